"""Shared synthetic records of the identification tests."""

import numpy as np
import pytest

from rcm_kin.dynamics.stick_slip import AxisFriction, AxisPlant
from rcm_kin.identification.drive_train import AxisLog, predict_log

GAIN, MASS = 0.1, 0.5     # N m per count, kg m^2


def three_steps(truth: AxisFriction) -> tuple[AxisPlant, list[AxisLog]]:
    """Three noiseless steps of a presliding-spring axis with viscous friction on a sine gravity."""
    grid = np.linspace(-1.0, 1.0, 201)
    plant = AxisPlant(GAIN, 0.6, 3e-3, grid, 3.0 * np.sin(grid), np.full(grid.size, MASS))
    logs = []
    for k, start in enumerate((-0.2, 0.0, 0.2)):
        hold = 3.0 * np.sin(start) / GAIN
        pwm = np.r_[hold, np.full(1500, hold + 8.0 + 3.0 * k)]
        blank = AxisLog(f"step {k}", "roll", 1e-3, pwm, np.full(pwm.size, start), np.array([start, 0, 0.08]))
        logs.append(AxisLog(blank.name, "roll", 1e-3, pwm, predict_log(truth, plant, blank), blank.pose))
    return plant, logs


@pytest.fixture
def steps():
    """:func:`three_steps`: ``steps(truth)`` gives the plant and the three step logs."""
    return three_steps

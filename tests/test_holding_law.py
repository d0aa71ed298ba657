"""The firmware's pitch hold read back from the measured roll-step logs
(``analysis/holding_law.py``): the evidence that the simulated runs start with the pitch
integral charged (:class:`rcm_kin.simulation.controllers.Hold`)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "analysis" / "holding_law.py"


@pytest.fixture(scope="module")
def holding_law():
    spec = importlib.util.spec_from_file_location("holding_law", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.holding_law


def test_the_pitch_hold_at_home_carries_its_holding_pwm_in_the_integral(shared_data, holding_law):
    """At (0, 0), where the sinusoid starts, the law u = -(Kp e + Kd v + Ki E) reproduces the
    logged float PWM to 0.05 counts RMS with the thesis's structure (Kp about 220 PWM/deg, the
    positive Kd of the tables on the measured velocity, Ki of the tables' order), and the integral
    carries at least 90 % of the mean PWM."""
    h = holding_law(shared_data / "psm-sysid" / "roll-step" / "roll_step_response_roll_0_pitch_0.csv")
    assert h["residual_rms"] < 0.05
    assert h["Kp"] == pytest.approx(220.7, abs=1.0)
    assert h["Kd"] == pytest.approx(0.32, abs=0.02)
    assert 0.01 < h["Ki"] < 1.0
    assert h["mean_pwm"] < -50
    assert h["integral"] / h["mean_pwm"] > 0.9

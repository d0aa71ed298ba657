"""The drive-train identification's view of the Maxwell-slip spring: the element count is a model
choice the search carries but never frees, and a log's rest may carry a presliding preload."""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest

from rcm_kin.dynamics.stick_slip import AxisFriction, AxisPlant
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.drive_train import (
    NAMES,
    AxisLog,
    at_rest,
    predict_log,
    predicted_standard_errors,
    search_for,
)

GRID = np.linspace(-1.0, 1.0, 201)
PLANT = AxisPlant(0.1, 0.6, 3e-3, GRID, 3.0 * np.sin(GRID), np.full(GRID.size, 0.5))
FRICTION = AxisFriction(viscous=4.0, coulomb=0.2, presliding_stiffness=25.0, presliding_slope=1.0,
                        presliding_force=1.0, presliding_elements=3.0)


def step_log(start=0.1, push=12.0) -> AxisLog:
    hold = 3.0 * np.sin(start) / 0.1
    pwm = np.r_[hold, np.full(800, hold + push)]
    return AxisLog("synthetic", "roll", 1e-3, pwm, np.full(pwm.size, start), np.array([start, 0.0, 0.08]))


def test_the_element_count_is_carried_never_searched():
    """Every search leaves presliding_elements out of its free parameters (the names it had before
    the field existed) and sets it from ``elements`` whatever the search point."""
    for terms in ((), ("presliding",), ("presliding", "stiction", "two_mass")):
        search = search_for(terms, elements=3)
        assert "presliding_elements" in NAMES and "presliding_elements" not in search.free
        assert search.friction(search.start(FRICTION)).presliding_elements == 3.0
    assert search_for(("presliding",)).base.presliding_elements == 1.0
    assert search_for(("viscous", "presliding")).free == ("extra_inertia", "viscous", "coulomb",
                                                          "presliding_stiffness", "presliding_slope",
                                                          "presliding_force")
    assert "viscous" not in search_for(("presliding",)).free


def test_predicted_errors_keep_the_models_element_count():
    """The Gauss-Newton errors are those of the model given (3 elements), not of a 1-element one."""
    log = step_log()
    log = AxisLog(log.name, log.joint, log.period, log.pwm, predict_log(FRICTION, PLANT, log), log.pose)
    three = predicted_standard_errors(FRICTION, [PLANT], [log], np.radians(0.01))
    one = predicted_standard_errors(AxisFriction(**{**FRICTION.as_dict(), "presliding_elements": 1.0}), [PLANT],
                                    [log], np.radians(0.01))
    assert "presliding_elements" not in three and three != one


@pytest.mark.parametrize("preload", [-1.0, -0.4, 0.5, 1.0])
def test_a_logs_rest_carries_the_preload(preload):
    """``at_rest`` shifts gravity so the first PWM holds the axis (no load left), so the spring's
    force at rest is the preload alone: ``preload F_p``; ``predict_log`` starts from it (the
    default, 0, is the relaxed rest, and a preload moves the prediction)."""
    log = step_log()
    _, state = at_rest(FRICTION, PLANT, log.measured[0], log.pwm[0], preload=preload)
    q, n = state[2], 3
    k = 25.0 * np.exp(q) / n
    assert np.sum(k * (q - state[4:4 + n])) == pytest.approx(preload * 1.0, abs=1e-9)
    relaxed = predict_log(FRICTION, PLANT, log)
    np.testing.assert_array_equal(relaxed, predict_log(FRICTION, PLANT, log, preload=0.0))
    assert np.max(np.abs(predict_log(FRICTION, PLANT, log, preload=preload) - relaxed)) > 1e-4


@pytest.mark.parametrize("preload", [-0.8, 0.5])
def test_a_preloaded_rest_is_a_static_equilibrium(preload):
    """Under its first PWM held, a preloaded rest stays where it is: the spring's force plus the
    shifted gravity balance the motor torque (a preload on top of a fully balanced gravity would
    leave the link pushed by the spring alone, and it would creep off the rest)."""
    log = step_log()
    held = AxisLog(log.name, log.joint, log.period, np.full(log.pwm.size, log.pwm[0]), log.measured, log.pose)
    moved = predict_log(FRICTION, PLANT, held, preload=preload) - held.measured[0]
    assert np.max(np.abs(moved)) < 1e-9
    shifted, state = at_rest(FRICTION, PLANT, log.measured[0], log.pwm[0], preload=preload)
    torque = PLANT.input_gain * log.pwm[0]
    gravity = np.interp(state[2], shifted.grid, shifted.gravity)
    assert torque - gravity == pytest.approx(preload * FRICTION.presliding_force, abs=1e-9)


@pytest.mark.parametrize("preload", [1.5, -1.01, float("nan")])
def test_a_preload_outside_its_range_is_refused(preload):
    log = step_log()
    with pytest.raises(RcmKinError, match=r"fraction of the slip force in \[-1, 1\]"):
        at_rest(FRICTION, PLANT, log.measured[0], log.pwm[0], preload=preload)

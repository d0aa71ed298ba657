"""The fast experiments as constraints: the speed bounds and the constrained fit."""

import numpy as np
import pytest

from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.identification.drive_train import fit_friction, search_for
from rcm_kin.identification.speed_bounds import SpeedBound, sliding_friction, speed_bounds


def test_the_sinusoid_bounds_match_the_issues_hand_arithmetic(params):
    """The issue's sums, by hand from the thesis numbers: roll 35 x 1.17 - 17 = 24 PWM for friction
    plus back-EMF at 42 deg/s (2.9 N m), pitch 60 x 2.31 - 80 = 59 PWM at 31 deg/s; a bound
    carries the friction alone (back-EMF taken off at its speed)."""
    from rcm_kin.identification.identify import base_model

    model = base_model(params)
    roll, = speed_bounds(model, params, "roll")
    pitch, = speed_bounds(model, params, "pitch")
    assert np.degrees(roll.speed) == pytest.approx(20 * 2 * np.pi / 3, rel=1e-9)
    assert np.degrees(pitch.speed) == pytest.approx(15 * 2 * np.pi / 3, rel=1e-9)
    emf = {j: params[j].torque_constant**2 * params[j].gear_ratio**2 / params[j].resistance for j in ("roll", "pitch")}
    for bound, pwm, joint in ((roll, 35 * 1.17 - 17, "roll"), (pitch, 60 * 2.31 - 80, "pitch")):
        total = bound.max_force + emf[joint] * bound.speed         # friction plus back-EMF, N m
        assert total == pytest.approx(pwm / abs(params[joint].pwm_per_torque), rel=0.05), joint
    assert roll.max_force + emf["roll"] * roll.speed == pytest.approx(2.9, abs=0.1)


def test_the_runaway_bound_is_the_analysis_figure(shared_data, params):
    """With the ramp log among the logs the pitch gains the runaway bound: viscous friction
    beyond back-EMF <= 4.1 N m s/rad (analysis/pitch_runaway.py's published figure), 133 deg/s."""
    from rcm_kin.identification.identify import base_model
    from rcm_kin.identification.telemetry import load_telemetry

    ramp = load_telemetry(shared_data / "psm-sysid" / "single-axis" / "pitch_speed_ramp_down_response.csv")
    other = load_telemetry(shared_data / "psm-sysid" / "single-axis" / "pitch_step_response.csv")
    bounds = speed_bounds(base_model(params), params, "pitch", [other, ramp])
    assert [b.name for b in bounds] == ["pitch_p_sinusoid", "pitch_runaway"]
    runaway = bounds[1]
    assert np.degrees(runaway.speed) == pytest.approx(133, abs=1)
    assert runaway.max_force / runaway.speed == pytest.approx(4.1, abs=0.05)   # viscous alone at the limit


def test_sliding_friction_adds_every_sliding_term():
    f = AxisFriction(viscous=2.0, coulomb=0.3, static=0.5, stribeck_velocity=0.1, presliding_stiffness=10.0,
                     presliding_force=0.4, motor_coulomb=0.1, motor_viscous=1.0)
    assert sliding_friction(f, 0.2) == pytest.approx(0.3 + 0.1 + 0.2 * np.exp(-4.0) + 0.4 + 3.0 * 0.2)


def test_a_fit_that_violates_a_bound_is_pulled_onto_it(steps):
    """The steps' own optimum (the truth: 5.5 N m of friction at 0.7 rad/s) breaks a bound set at
    80 % of it: unconstrained the fit finds the truth's friction at speed, constrained it ends
    on the bound (active, within 1 %) and satisfies it."""
    truth = AxisFriction(extra_inertia=0.4, viscous=6.0, coulomb=0.3, presliding_stiffness=20.0,
                         presliding_slope=2.0, presliding_force=1.5)
    plant, logs = steps(truth)
    bound = SpeedBound("test", "roll", 0.7, 0.8 * sliding_friction(truth, 0.7), "synthetic")
    search = search_for(("viscous", "presliding"))
    free, _ = fit_friction(search, [plant] * 3, logs, seed=3, generations=30)
    assert bound.value(free) > 1.1 * bound.max_force                 # the unconstrained fit violates it
    held, _ = fit_friction(search, [plant] * 3, logs, seed=3, generations=30, speed_bounds=(bound,))
    assert bound.value(held) <= bound.max_force * (1 + 1e-9)
    assert bound.active(held) and bound.as_dict(held)["active"]


def test_identify_on_the_shared_logs_satisfies_the_roll_bound(shared_data, params, monkeypatch):
    """A short identification on every shared roll log (5 generations) ends inside the roll's
    P-sinusoid bound, reports it, and takes the two single-axis logs with their pose noted."""
    from rcm_kin.identification import identify as module

    monkeypatch.setattr(module, "GENERATIONS", (5, 5))
    result = module.identify([shared_data / "psm-sysid"], params, ("roll",))
    roll = result.joints["roll"]
    bound, = roll.bounds
    assert bound.value(roll.friction) <= bound.max_force * (1 + 1e-9)
    assert result.as_dict()["constraints"]["roll"]["roll_p_sinusoid"]["satisfied"]
    assert {"roll_step.csv", "step_response.csv"} <= set(roll.logs)
    assert {e.path.name for e in result.notes} == {"roll_step.csv", "step_response.csv"}


def test_the_shipped_set_satisfies_the_speed_bounds(params):
    """The shipped drive file's roll drive train and its pitch's smooth constants (Coulomb and
    viscous; the pitch has no drive train) are within the P-sinusoid bounds of both axes, computed
    from the thesis's numbers and the file's own drive (the shipped set before these bounds, viscous
    7.59 N m s/rad on the roll, had 6.8 N m at 42 deg/s against 2.4)."""
    from rcm_kin.identification.identify import base_model

    model = base_model(params)
    roll, = speed_bounds(model, params, "roll")
    pitch, = speed_bounds(model, params, "pitch")
    assert roll.value(params.drive_train["roll"]) <= roll.max_force * (1 + 1e-9)
    smooth = AxisFriction(coulomb=params["pitch"].coulomb, viscous=params["pitch"].viscous)
    assert pitch.value(params.drive_train.get("pitch", smooth)) <= pitch.max_force

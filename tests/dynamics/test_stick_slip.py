"""The stick-slip axis model against closed-form cases, and identification on synthetic logs."""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest

from rcm_kin.dynamics.axis_friction import SUBSTEP
from rcm_kin.dynamics.stick_slip import STATE_SIZE, AxisFriction, AxisPlant, rest_state, simulate_axis

MASS = 0.5        # kg m^2
COULOMB = 0.8     # N m
GAIN = 0.1        # N m per PWM count


def flat_plant(inertia=MASS, gain=GAIN) -> AxisPlant:
    """No gravity, constant inertia, no back-EMF, no rotor: a block on a rough floor."""
    grid = np.linspace(-10.0, 10.0, 5)
    return AxisPlant(gain, 0.0, 0.0, grid, np.zeros(5), np.full(5, inertia))


def test_sliding_block_stops_where_and_when_coulomb_says():
    """From v0 under Coulomb friction alone: stops at t = J v0 / F_c, x = J v0^2 / (2 F_c), then
    stays. Time stepping finds the stop within one step h: |dt| <= h, |dx| <= v0 h."""
    v0 = 2.0
    friction = AxisFriction(coulomb=COULOMB)
    state = np.zeros(STATE_SIZE)
    state[1] = state[3] = v0
    period = 1e-3
    angle = simulate_axis(friction, flat_plant(), np.zeros(3000), period, state)
    t_stop, x_stop = MASS * v0 / COULOMB, MASS * v0**2 / (2 * COULOMB)
    moving = np.flatnonzero(np.diff(angle) != 0.0)
    t_sim = (moving[-1] + 2) * period
    assert abs(t_sim - t_stop) <= period + SUBSTEP
    assert abs(angle[-1] - x_stop) <= v0 * SUBSTEP
    assert state[3] == 0.0 and np.all(angle[int(1.1 * t_stop / period):] == angle[-1])


def test_block_sticks_below_breakaway_and_accelerates_above_it():
    """At rest with static friction F_s: a push below F_s leaves it exactly still; above, it
    accelerates at (F - F_c) / J: x(t) = (F - F_c) t^2 / (2 J) (to O(h))."""
    friction = AxisFriction(coulomb=COULOMB, static=1.2, stribeck_velocity=1e-6)
    below = simulate_axis(friction, flat_plant(), np.full(500, 1.19 / GAIN), 1e-3, np.zeros(STATE_SIZE))
    assert np.all(below == 0.0)
    push = 1.5
    above = simulate_axis(friction, flat_plant(), np.full(500, push / GAIN), 1e-3, np.zeros(STATE_SIZE))
    t = np.arange(1, 501) * 1e-3
    exact = (push - COULOMB) * t**2 / (2 * MASS)
    assert np.max(np.abs(above - exact)) <= (push - COULOMB) / MASS * t[-1] * SUBSTEP * 1.01


def test_presliding_spring_is_anchored_where_the_axis_came_to_rest():
    """A push below the spring's slip force F_p (and no floor friction) settles at F / k_p from
    the start, wherever that start is; above F_p the spring slips and the travel is larger."""
    k, slip = 40.0, 1.0
    friction = AxisFriction(viscous=5.0, presliding_stiffness=k, presliding_force=slip)
    for start in (-0.2, 0.3):
        state = rest_state(friction, flat_plant(), start, 0.0)
        angle = simulate_axis(friction, flat_plant(), np.full(4000, 0.5 / GAIN), 1e-3, state)
        assert abs(angle[-1] - start - 0.5 / k) < 1e-9
    state = rest_state(friction, flat_plant(), 0.0, 0.0)
    angle = simulate_axis(friction, flat_plant(), np.full(4000, 1.5 / GAIN), 1e-3, state)
    assert angle[-1] > 2 * slip / k


def test_two_mass_drive_carries_the_static_load_through_the_cable():
    """With the link stuck (large static friction), the motor (encoder side) winds the cable to
    k_u u / k_c exactly, and the link does not move."""
    friction = AxisFriction(coulomb=5.0, static=5.0, cable_stiffness=200.0, cable_damping=1.0)
    plant = AxisPlant(GAIN, 0.5, 3e-3, np.linspace(-1, 1, 5), np.zeros(5), np.full(5, MASS))
    state = rest_state(friction, plant, 0.0, 0.0)
    angle = simulate_axis(friction, plant, np.full(3000, 20.0), 1e-3, state)
    assert abs(angle[-1] - GAIN * 20.0 / 200.0) < 1e-9
    assert state[2] == 0.0 and state[3] == 0.0


def synthetic_logs(truth, count=4, seed=1):
    """Step logs of a pendulum-like axis (gravity 3 sin q N m) simulated with ``truth``, the
    angle quantised to the roll encoder's 0.009 deg and with 0.005 deg noise."""
    from rcm_kin.identification.drive_train import AxisLog, predict_log

    rng = np.random.default_rng(seed)
    grid = np.linspace(-1.0, 1.0, 201)
    plant = AxisPlant(GAIN, 0.6, 3e-3, grid, 3.0 * np.sin(grid), np.full(grid.size, MASS))
    logs = []
    for k, start in enumerate(np.linspace(-0.3, 0.3, count)):
        hold = 3.0 * np.sin(start) / GAIN
        pwm = np.r_[hold, np.full(2500, hold + 8.0 + 2.0 * k)]
        blank = AxisLog(f"synthetic {k}", "roll", 1e-3, pwm, np.full(pwm.size, start), np.array([start, 0, 0.08]))
        clean = predict_log(truth, plant, blank)
        count_ = np.radians(0.009)
        noisy = np.round((clean + rng.normal(0, np.radians(0.005), clean.size)) / count_) * count_
        logs.append(AxisLog(blank.name, "roll", 1e-3, pwm, noisy, blank.pose))
    return plant, logs


def test_identification_recovers_a_stick_slip_axis_from_noisy_steps():
    """The fit (evolution + least squares) finds the parameters that made the data: each within
    10 % (the inertia 20 %: the steps excite it least), and fits every log above 97 %."""
    from rcm_kin.identification.drive_train import fit_friction, fit_percent, predict_log, search_for

    truth = AxisFriction(extra_inertia=0.4, viscous=6.0, coulomb=0.3, presliding_stiffness=20.0,
                         presliding_slope=2.0, presliding_force=1.5)
    plant, logs = synthetic_logs(truth)
    found, sigma = fit_friction(search_for(("viscous", "presliding")), [plant] * len(logs), logs, seed=3,
                                generations=60)
    for name, tolerance in (("viscous", 0.1), ("coulomb", 0.1), ("presliding_stiffness", 0.1),
                            ("presliding_slope", 0.1), ("extra_inertia", 0.2)):
        assert getattr(found, name) == pytest.approx(getattr(truth, name), rel=tolerance), name
    assert all(fit_percent(g.measured, predict_log(found, plant, g)) > 97.0 for g in logs)
    assert np.all(np.isfinite(sigma[:5]))


def test_leave_one_out_predicts_each_log_from_the_others():
    """Cross-validation on synthetic logs from one model: every left-out log is predicted above
    95 % by the model fitted without it, each fold searched from scratch, and a fold is fitted
    without its log (a log made inconsistent with the others, twice the travel, is predicted
    badly when left out)."""
    from rcm_kin.identification.drive_train import AxisLog, leave_one_out, search_for

    truth = AxisFriction(extra_inertia=0.4, viscous=6.0, coulomb=0.3, presliding_stiffness=20.0,
                         presliding_slope=2.0, presliding_force=1.5)
    plant, logs = synthetic_logs(truth, count=3)
    checks, folds = leave_one_out(search_for(("viscous", "presliding")), [plant] * 3, logs, generations=30)
    assert len(folds) == 3 and all(c.fit_percent > 95.0 for c in checks)
    odd = AxisLog("inconsistent", "roll", logs[0].period, logs[0].pwm, logs[0].measured[0] + 2.0 * (
        logs[0].measured - logs[0].measured[0]), logs[0].pose)
    checks, _ = leave_one_out(search_for(("viscous", "presliding")), [plant] * 3, [odd] + logs[1:], generations=30)
    assert checks[0].fit_percent < 60.0


def test_a_stiff_cable_tends_to_the_rigid_drive():
    """Two masses joined by a cable of growing stiffness move like the one rigid body they
    become: the coupling is implicit in both velocities, so no false damping grows with k_c
    (0.2 s of a constant push, no friction: within 1 % at 1e4 N m/rad, the search's bound, and 0.1 %
    at 1e6)."""
    plant = AxisPlant(-GAIN, 0.5, 3e-3, np.linspace(-1, 1, 5), np.zeros(5), np.full(5, MASS))
    push = np.full(200, -10.0)                 # negative PWM raises the angle (hardware sign)
    rigid = simulate_axis(AxisFriction(viscous=1.0), plant, push, 1e-3, np.zeros(STATE_SIZE))[-1]
    assert rigid > 0.01
    for stiffness, tolerance in ((1e4, 1e-2), (1e6, 1e-3)):
        two_mass = simulate_axis(AxisFriction(viscous=1.0, cable_stiffness=stiffness, cable_damping=1.0), plant,
                                 push, 1e-3, np.zeros(STATE_SIZE))[-1]
        assert two_mass == pytest.approx(rigid, rel=tolerance), stiffness


def test_the_rest_a_log_starts_from_is_an_equilibrium():
    """With the hardware's negative gain, gravity and a compliant cable, the state ``at_rest``
    builds for a measured angle and PWM stays exactly still under that PWM: the cable carries
    the motor torque, the link is where gravity (shifted) balances it, the spring is unloaded."""
    from rcm_kin.identification.drive_train import at_rest

    grid = np.linspace(-1.0, 1.0, 201)
    plant = AxisPlant(-GAIN, 0.6, 3e-3, grid, 3.0 * np.sin(grid), np.full(grid.size, MASS))
    friction = AxisFriction(viscous=2.0, coulomb=0.05, presliding_stiffness=30.0, presliding_slope=3.0,
                            presliding_force=2.0, cable_stiffness=120.0, cable_damping=5.0)
    shifted, state = at_rest(friction, plant, 0.3, -20.0)
    assert state[2] == pytest.approx(0.3 - (-GAIN * -20.0) / 120.0, abs=1e-12)    # link behind the stretch
    assert state[4] == state[2]                                                    # spring unloaded
    angle = simulate_axis(friction, shifted, np.full(1000, -20.0), 1e-3, state.copy())
    assert np.max(np.abs(angle - 0.3)) < 1e-12


def test_a_progress_bar_does_not_stop_the_search():
    """The fit's progress hook is called once per generation and cannot end the search: a hook that
    returns True (as ``tqdm.update`` does when it redraws; scipy halts on a true callback) gives
    the same estimate as no hook, after the same number of generations."""
    from rcm_kin.identification.drive_train import fit_friction, search_for

    truth = AxisFriction(extra_inertia=0.4, viscous=6.0, coulomb=0.3, presliding_stiffness=20.0,
                         presliding_slope=2.0, presliding_force=1.5)
    plant, logs = synthetic_logs(truth, count=2)
    calls = []
    quiet, _ = fit_friction(search_for(("viscous", "presliding")), [plant] * 2, logs, seed=2, generations=8)
    hooked, _ = fit_friction(search_for(("viscous", "presliding")), [plant] * 2, logs, seed=2, generations=8,
                             progress=lambda: calls.append(1) or True)
    assert hooked == quiet
    assert len(calls) >= 2


@pytest.mark.parametrize("pwm, period, says", [
    (np.full(10, 1e6), 1e-3, "within \\+-255"),          # the case: a PWM of 1e6 was simulated
    (np.array([0.0, np.nan]), 1e-3, "finite counts"),
    (np.zeros((2, 2)), 1e-3, "1-D series"),
    ("abc", 1e-3, "PWM counts"),
    (np.zeros(3), 0.0, "0 to 1 s"),
    (np.zeros(3), float("nan"), "0 to 1 s"),
])
def test_simulate_axis_refuses_what_no_driver_sends(pwm, period, says):
    from rcm_kin.errors import RcmKinError

    friction = AxisFriction(coulomb=COULOMB)
    with pytest.raises(RcmKinError, match=says) as caught:
        simulate_axis(friction, flat_plant(), pwm, period, np.zeros(STATE_SIZE))
    assert caught.value.parameter in ("pwm", "period")

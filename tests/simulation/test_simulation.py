"""Closed-loop simulation: plant integration, firmware I/O, controllers, experiments (issue 5)."""

from __future__ import annotations

import json
import re

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.dynamics.drive import DRIVEN, with_joint
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.teleop import default_teleop_map, psm_targets
from rcm_kin.simulation.controllers import PController, PIDController, make_controller
from rcm_kin.simulation.experiments import run_experiment
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import simulate, tracking_metrics
from rcm_kin.simulation.plant import period_map
from rcm_kin.simulation.references import load_mtm_trajectory, sine_reference, step_reference, target_reference

T = 1.0 / 400.0
EXACT = FirmwareSettings(encoder_count=np.zeros(3), quantise_pwm=False, pwm_limit=np.full(3, 255.0))


def linear_forward(b: np.ndarray) -> ca.Function:
    """Three decoupled integrators qdot = b u (the v states stay 0)."""
    x, u = ca.SX.sym("x", 6), ca.SX.sym("u", 3)
    return ca.Function("f", [x, u], [ca.vertcat(ca.DM(b) * u, ca.DM.zeros(3))])


def as_step(F: ca.Function):
    return lambda x, u: np.array(F(x, u)).ravel()


def test_sampled_p_loop_on_integrators_is_the_geometric_sequence():
    """y' = b u under u = -Kp (r - y) every T with the input held: the error after the step is
    e_k = e_0 (1 - |b| T Kp 180/pi)^k exactly, with the step seen at the first tick at or after 0.5 s."""
    b = np.array([-0.05, -0.02, 1e-4])                   # rad (m) per s per count, hardware signs
    F = period_map(linear_forward(b), T)
    ref = step_reference(1.0, T, step_deg=(2.0, -3.0), at=0.5)
    result = simulate(as_step(F), PController(), ref, EXACT, settle=0.0)
    k0 = int(np.argmax(ref.time >= 0.5))
    k = np.arange(ref.time.size - k0)
    for i, (kp, step) in enumerate(zip((35.0, 60.0), (2.0, -3.0))):
        factor = 1.0 - abs(b[i]) * T * kp * np.degrees(1.0)
        np.testing.assert_allclose(result.error[k0:, i], step * factor**k, rtol=0, atol=1e-12)
        np.testing.assert_allclose(result.error[:k0, i], 0.0, atol=1e-15)


def test_rk4_period_map_matches_the_closed_form_second_order_response():
    """Open loop, constant PWM, on q'' = -w^2 q - 2 z w q' + k u: the closed-form step response."""
    w, z, k, u0 = 12.0, 0.2, 3.0, 7.0
    x, u = ca.SX.sym("x", 6), ca.SX.sym("u", 3)
    F = period_map(ca.Function("f", [x, u], [ca.vertcat(x[3:], -w**2 * x[:3] - 2 * z * w * x[3:] + k * u)]), T)
    xk = np.zeros(6)
    for _ in range(400):
        xk = np.array(F(xk, np.full(3, u0))).ravel()
    wd = w * np.sqrt(1 - z**2)
    exact = k * u0 / w**2 * (1 - np.exp(-z * w) * (np.cos(wd) + z / np.sqrt(1 - z**2) * np.sin(wd)))
    np.testing.assert_allclose(xk[:3], exact, rtol=0, atol=1e-9)


def test_period_map_on_the_psm_matches_an_adaptive_solver(model):
    """RK4 with 4 substeps at 400 Hz against scipy's DOP853 at rtol 1e-11 over 0.25 s, PWM
    switching every period (the nonlinear model with Coulomb friction). The error per period is
    largest where a velocity crosses the steep tanh of the smoothed Coulomb friction (pitch: slope
    F_c / v_c = 54 N m s/rad on 0.31 kg m^2, |lambda h| = 0.11 at h = 0.625 ms)."""
    F = as_step(period_map(model.forward, T))
    rng = np.random.default_rng(3)
    x = np.array([0.2, -0.3, 0.07, 0.5, -0.4, 0.01])
    for _ in range(100):
        u = rng.uniform(-100, 100, 3)
        ivp = solve_ivp(lambda t, s: np.array(model.forward(s, u)).ravel(), (0, T), x, method="DOP853",
                        rtol=1e-11, atol=1e-13)
        x_rk4 = F(x, u)
        np.testing.assert_allclose(x_rk4[:3], ivp.y[:3, -1], rtol=0, atol=1e-7)     # rad, m
        np.testing.assert_allclose(x_rk4[3:], ivp.y[3:, -1], rtol=0, atol=2e-4)     # rad/s, m/s
        x = ivp.y[:, -1]


def test_holding_pwm_keeps_the_psm_at_rest(model):
    F = as_step(period_map(model.forward, T))
    for q in ([0.0, 0.0, 0.08], [0.3, -0.4, 0.12], [-0.5, 0.5, 0.05]):
        x0 = np.r_[q, 0.0, 0.0, 0.0]
        x = x0.copy()
        for _ in range(400):
            x = F(x, holding_pwm(model, q))
        np.testing.assert_allclose(x, x0, rtol=0, atol=1e-9)


def test_undamped_psm_conserves_energy(psm, params):
    """Without damping, friction or input, kinetic + potential energy is constant. The
    potential is the line integral of the model's generalised gravity (Gauss-Legendre, 30 nodes)."""
    lossless = params
    for j in DRIVEN:
        lossless = with_joint(lossless, j, torque_constant=1e-12, viscous=0.0, coulomb=0.0)
    m = driven_dynamics(psm, lossless)
    F = as_step(period_map(m.forward, T, substeps=8))
    q_ref = np.array([0.0, 0.0, 0.08])
    nodes, weights = np.polynomial.legendre.leggauss(30)

    def energy(x):
        q, v = x[:3], x[3:]
        dq = q - q_ref
        potential = sum(wt / 2 * np.array(m.gravity(q_ref + (s + 1) / 2 * dq)).ravel() @ dq
                        for s, wt in zip(nodes, weights))
        return 0.5 * v @ np.array(m.mass_matrix(q)) @ v + potential

    x = np.array([0.3, -0.2, 0.1, 0.0, 0.5, 0.0])
    e0 = energy(x)
    for _ in range(400):
        x = F(x, np.zeros(3))
    assert np.ptp(x[:2]) > 0.1                            # it moved
    assert abs(energy(x) - e0) < 1e-7 * max(1.0, abs(e0))


def test_firmware_io_quantises_saturates_and_truncates():
    F = as_step(period_map(linear_forward(np.array([-0.5, -0.3, 1e-4])), T))
    ref = step_reference(0.5, T, step_deg=(25.0, -25.0), at=0.01)
    result = simulate(F, PController(), ref, FirmwareSettings(), settle=0.0)
    counts = result.measured[:, :2] / np.array([0.009, 0.0135])
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)
    assert np.all(result.pwm == np.trunc(result.pwm))
    assert np.abs(result.pwm[:, 0]).max() == 100 and np.abs(result.pwm[:, 1]).max() == 150
    metrics = tracking_metrics(result)
    assert metrics["roll"].saturation_s > 0 and metrics["pitch"].saturation_s > 0


def test_runs_are_deterministic_given_the_seed():
    F = as_step(period_map(linear_forward(np.array([-0.5, -0.3, 1e-4])), T))
    ref = sine_reference(0.5, T)
    noisy = FirmwareSettings(noise_counts=2.0)
    a, b, c = (simulate(F, PIDController(), ref, noisy, seed=s) for s in (1, 1, 2))
    np.testing.assert_array_equal(a.pwm, b.pwm)
    assert not np.array_equal(a.pwm, c.pwm)


def test_pitch_integral_does_not_wind_up_in_saturation():
    """A pitch integrator that cannot move (b = 0): the PWM saturates and the integral stays put."""
    F = as_step(period_map(linear_forward(np.array([-0.5, 0.0, 1e-4])), T))
    ref = step_reference(0.5, T, step_deg=(0.0, 20.0), at=0.01)
    controller = PIDController()
    memory = controller.initial_memory()
    result = simulate(F, controller, ref, FirmwareSettings(), settle=0.0)
    assert np.all(result.pwm[4:, 1] == -150)
    from rcm_kin.simulation.controllers import Sample
    s = Sample(np.zeros(3), np.zeros(3), np.array([0.0, 20.0, 0.0]), np.zeros(3), np.zeros(3), T,
               np.array([100.0, 150.0, 100.0]))
    for _ in range(50):
        _, memory = controller.command(memory, s)
    assert memory[1] == 0.0


def test_target_reference_reaches_the_teleoperated_shaft_tip(psm):
    """The joint reference, through FK, puts the shaft tip on the teleoperation targets."""
    ref = target_reference(psm, None, T)
    t_raw, displacement = load_mtm_trajectory()
    targets = psm_targets(default_teleop_map(psm), displacement)
    for k in range(0, len(t_raw), 40):
        i = int(round(t_raw[k] / T))
        q = np.zeros(psm.nq)
        q[[psm.actuated.index(j) for j in DRIVEN]] = ref.position[i]
        tip = frame_placement(psm, q, "shaft_tip").translation
        # spline between 100 Hz samples, evaluated within half a controller period of the sample
        np.testing.assert_allclose(tip, targets[k], atol=2e-6)


def test_model_based_control_tracks_the_sinusoid_better_than_p():
    """The thesis's finding, reproduced on the model: the scheduled LQR/LQI with feedforward has
    smaller mean and largest errors than the P baseline on both axes."""
    p = tracking_metrics(run_experiment("sine", "p", duration=3.0))
    s = tracking_metrics(run_experiment("sine", "scheduled-gravity", duration=3.0))
    for axis in ("roll", "pitch"):
        assert s[axis].mean_error_deg < p[axis].mean_error_deg
        assert s[axis].max_error_deg < p[axis].max_error_deg


def test_statistics_can_leave_out_the_start():
    F = as_step(period_map(linear_forward(np.array([-0.05, -0.02, 1e-4])), T))
    result = simulate(F, PController(), step_reference(1.0, T, step_deg=(2.0, -3.0), at=0.5), EXACT, settle=0.0)
    after = tracking_metrics(result, skip=0.75)
    keep = result.time >= 0.75
    assert after["pitch"].max_error_deg == np.max(np.abs(result.error[keep, 1]))
    assert after["roll"].max_error_deg < tracking_metrics(result)["roll"].max_error_deg


def test_unknown_controller_is_refused():
    with pytest.raises(RcmKinError, match="unknown controller"):
        make_controller("mpc")
    with pytest.raises(RcmKinError, match="needs a gain schedule"):
        make_controller("scheduled")


def test_simulate_cli_contract(capsys):
    assert main(["simulate", "psm", "--experiment", "step", "--controller", "lqr-fixed", "--duration", "1",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out) == {"roll", "pitch"}
    for axis in out.values():
        assert {"max_error_deg", "mean_error_deg", "rms_error_deg"} <= set(axis)
        assert axis["max_error_deg"] >= axis["rms_error_deg"] >= axis["mean_error_deg"] >= 0


@pytest.mark.parametrize("argv, message", [
    (["--experiment", "sine", "--controller", "p", "--rate", "-5"], "--rate"),
    (["--experiment", "sine", "--controller", "p", "--duration", "0"], "duration"),
    (["--experiment", "target", "--controller", "p", "--trajectory", "nowhere.csv"], "cannot read"),
    (["--experiment", "step", "--controller", "p", "--skip", "5"], "--skip is a number in [0, 3] s, got 5"),
])
def test_simulate_cli_errors_are_one_line(capsys, argv, message):
    assert main(["simulate", "psm", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err and err.count("\n") == 1


def test_every_controller_is_a_controller(psm):
    from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG, schedule_gains
    from rcm_kin.simulation.controllers import CONTROLLERS, Controller

    schedule = schedule_gains(driven_dynamics(psm, coulomb=False), THESIS_ROLL_DEG, THESIS_PITCH_DEG)
    for name in CONTROLLERS:
        assert isinstance(make_controller(name, schedule), Controller)


def test_thesis_controller_applies_the_flashed_law_and_signs():
    """The thesis's tables as flashed (Tables 4.4-4.8, bilinear at the measured pose): at the grid
    point (roll 0, pitch 0) the command is exactly u = -(Kp e + Kd v) with the table's positive Kd
    on the measured velocity itself (under the -1 hardware sign, positive feedback of velocity:
    the firmware's law, kept on purpose), and the pitch integral grows by e T."""
    from rcm_kin import thesis as thesis_reference
    from rcm_kin.simulation.controllers import Sample, ThesisController

    c = ThesisController()
    e, v = np.array([0.5, -0.2]), np.array([3.0, -4.0])
    sample = Sample(np.array([0.0, 0.0, 0.08]), np.r_[v, 0.0], np.array([e[0], e[1], 0.08]), np.zeros(3),
                    np.zeros(3), T, np.array([100.0, 150.0, 100.0]))
    u, memory = c.command(c.initial_memory(), sample)
    kr, kp = thesis_reference.K_ROLL[1, 1], thesis_reference.K_PITCH[1, 1]
    assert u[0] == pytest.approx(-(kr[0] * e[0] + kr[1] * v[0]), abs=1e-12)
    assert memory[0] == pytest.approx(e[1] * T, abs=1e-15)
    assert u[1] == pytest.approx(-(kp[0] * e[1] + kp[1] * v[1] + kp[2] * e[1] * T), abs=1e-12)


@pytest.mark.parametrize("varying_ki", [False, True])
def test_integrals_start_charged_with_the_holding_pwm(varying_ki):
    """At the hold pose (off the gain grids) with zero error, velocity and reference motion, every
    controller with an integral sends exactly the holding PWM from its initial memory and keeps
    that memory (nothing to integrate); the P controller, which has none, sends nothing. Without
    a hold the integrals start at zero. With a pitch Ki that varies over the grid (the designed
    one is uniform), the Ki at the pose (scheduled) and at (0, 0) (lqr-fixed) differ."""
    from dataclasses import replace

    from rcm_kin.simulation.controllers import CONTROLLERS, Hold, Sample
    from rcm_kin.simulation.experiments import psm_plant_and_schedule

    _, schedule = psm_plant_and_schedule(period=T)
    if varying_ki:
        k_pitch = np.array(schedule.k_pitch, dtype=float)
        k_pitch[..., 2] *= 1.0 + 0.3 * np.arange(k_pitch[..., 2].size).reshape(k_pitch.shape[:2])
        schedule = replace(schedule, k_pitch=k_pitch)
    pose = np.array([10.0, -7.0, 0.08])
    hold = Hold(pose, np.array([12.5, -83.0, 0.0]))
    sample = Sample(pose, np.zeros(3), pose, np.zeros(3), np.zeros(3), T, np.array([100.0, 150.0, 100.0]))
    for name in CONTROLLERS:
        c = make_controller(name, schedule)
        memory = c.initial_memory(hold)
        u, after = c.command(memory, sample)
        if name == "p":
            np.testing.assert_array_equal(u[:2], 0.0)
            continue
        np.testing.assert_allclose(u[:2] if name == "pid" else u[1], hold.pwm[:2] if name == "pid" else hold.pwm[1],
                                   rtol=0, atol=1e-9, err_msg=name)
        integrals = slice(0, 2) if name == "pid" else slice(0, 1)
        np.testing.assert_allclose(after[integrals], memory[integrals], rtol=0, atol=1e-12, err_msg=name)
        assert np.all(c.initial_memory()[integrals] == 0.0), name


def test_a_hold_beyond_the_pwm_limit_charges_the_integral_to_the_limit(params):
    """Conditional integration never carries more than the PWM limit: with the pitch limited below
    its holding PWM, the thesis law's first command (at the pose, zero error and velocity) is the
    limit itself, in the readable loop and in the one runner (compiled where it can be)."""
    from rcm_kin.simulation.controllers import Hold, ThesisController
    from rcm_kin.simulation.experiments import closed_loop, psm_plant_and_schedule
    from rcm_kin.simulation.references import Reference

    n = 4
    ref = Reference(np.arange(n) * T, np.tile([0.0, 0.0, 0.08], (n, 1)), np.zeros((n, 3)), np.zeros((n, 3)))
    hold = Hold(np.array([0.0, 0.0, 0.08]), np.array([0.0, -79.0, 0.0]))
    settings = FirmwareSettings(pwm_limit=np.array([100.0, 60.0, 100.0]))
    assert hold.within(settings.pwm_limit).pwm.tolist() == [0.0, -60.0, 0.0]
    plant, _ = psm_plant_and_schedule(params, T)
    first = simulate(plant.step, ThesisController(), ref, settings, settle=0.0, initial=plant.initial, hold=hold)
    assert first.command[0, 1] == pytest.approx(-60.0, abs=1e-9)
    slow = simulate(plant.step, ThesisController(), ref, settings, initial=plant.initial, hold=hold)
    fast_plant, _ = psm_plant_and_schedule(params, T, fast=True)
    fast = closed_loop(fast_plant, ThesisController(), ref, settings, hold=hold)
    np.testing.assert_allclose(fast.command, slow.command, rtol=0, atol=1e-9)


def test_the_sinusoid_starts_from_the_steady_hold_of_its_first_pose(psm, params):
    """run_experiment charges the thesis law's pitch integral with the model's holding PWM at the
    first pose (roll = pitch = 0): standing at that pose, the pitch stays within two encoder counts
    of it; with an empty integral (the loop from the same start) it sags by the holding PWM over
    Kp, whole counts away."""
    from rcm_kin.simulation.controllers import ThesisController
    from rcm_kin.simulation.experiments import psm_plant_and_schedule, start_hold
    from rcm_kin.simulation.references import Reference

    n = 400
    ref = Reference(np.arange(n) * T, np.tile([0.0, 0.0, 0.08], (n, 1)), np.zeros((n, 3)), np.zeros((n, 3)))
    hold = start_hold(ref, params)
    model = driven_dynamics(psm, params)
    np.testing.assert_allclose(hold.pwm, holding_pwm(model, ref.position[0]), rtol=0, atol=1e-12)
    plant, _ = psm_plant_and_schedule(params, T)
    count = FirmwareSettings().encoder_count[1]
    charged = simulate(plant.step, ThesisController(), ref, initial=plant.initial, hold=hold)
    empty = simulate(plant.step, ThesisController(), ref, initial=plant.initial)
    assert np.max(np.abs(charged.measured[:, 1])) <= 2 * count
    assert np.max(np.abs(empty.measured[:, 1])) > 0.5 * abs(hold.pwm[1]) / 200.0 > 10 * count


@pytest.mark.parametrize("plant", ["drive-train", "smooth"])
def test_the_compiled_engine_equals_the_readable_classes_tick_for_tick(plant, params):
    """Every controller on both plants: ``run_experiment`` in the compiled engine (no fallback)
    against the readable reference classes, with encoder noise so that every branch sees varied
    samples."""
    import os
    import shutil
    import warnings

    from rcm_kin.errors import EngineFallbackWarning
    compiler = shutil.which(os.environ.get("CC") or "cc") is not None     # hidden in CI's fallback run
    from dataclasses import replace

    from rcm_kin.simulation.controllers import CONTROLLERS
    p = params if plant == "drive-train" else replace(params, drive_train={})
    assert bool(p.drive_train) == (plant == "drive-train")
    settings = FirmwareSettings(noise_counts=1.0)
    for name in CONTROLLERS:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            fast = run_experiment("step", name, duration=0.6, params=p, settings=settings, seed=3)
        slow = run_experiment("step", name, duration=0.6, params=p, settings=settings, seed=3, fast=False)
        fallbacks = [w for w in caught if issubclass(w.category, EngineFallbackWarning)]
        assert fast.engine == ("compiled" if compiler else "readable") and slow.engine == "readable"
        assert len(fallbacks) == (0 if compiler else 1), name              # never silently slower
        np.testing.assert_allclose(fast.position[:, :2], slow.position[:, :2], rtol=0, atol=np.degrees(1e-9))
        np.testing.assert_allclose(fast.position[:, 2], slow.position[:, 2], rtol=0, atol=1e-9)
        np.testing.assert_array_equal(fast.pwm, slow.pwm)
        assert np.ptp(fast.pwm[:, 1]) > 10            # the controller acted


def test_cached_schedules_and_models_tell_apart_the_9th_significant_digit(params):
    """Two parameter sets that differ only in the 9th significant digit of one gravity offset (their
    reprs are the same: NumPy prints 8 digits) get schedules, models and plants of their own; the
    same values, in another object, share them."""
    from dataclasses import replace

    from rcm_kin.simulation import experiments

    for link, offset in params.gravity_offsets.items():
        i = int(np.argmax(np.abs(offset)))
        nudged = np.array(offset, dtype=float)
        nudged[i] += 3 * 10.0 ** (np.floor(np.log10(abs(offset[i]))) - 8)
        other = replace(params, gravity_offsets={**params.gravity_offsets, link: nudged})
        if repr(other) == repr(params):
            break
    else:
        pytest.fail("no gravity offset whose 9th digit hides from repr")
    assert f"{nudged[i]:.8e}" != f"{offset[i]:.8e}"                     # the 9th significant digit differs
    same = replace(params, gravity_offsets={k: np.array(v) for k, v in params.gravity_offsets.items()})
    assert experiments.exact_key(params) != experiments.exact_key(other)
    assert experiments.exact_key(params) == experiments.exact_key(same)
    assert experiments.psm_schedule(other) is not experiments.psm_schedule(params)
    assert experiments.psm_schedule(same) is experiments.psm_schedule(params)
    assert experiments._smooth_model(other) is not experiments._smooth_model(params)
    assert experiments.psm_plant_and_schedule(other)[0] is not experiments.psm_plant_and_schedule(params)[0]
    q = np.array([0.2, -0.3, 0.1])
    gravity = [np.array(experiments._smooth_model(p).gravity(q)).ravel() for p in (params, other)]
    assert not np.array_equal(*gravity)                                  # and the models differ


def test_the_caches_follow_the_robot_loaded_now(tmp_path, monkeypatch, params):
    """After the robot's files change, load_robot gives a new robot: the model, schedule and plant
    caches keyed by the parameters alone would return the old robot's; they are keyed by both."""
    import shutil

    from rcm_kin.model import load_robot
    from rcm_kin.model.loading import urdf_dir
    from rcm_kin.simulation import experiments

    for suffix in (".toml", ".urdf", "_drive.toml"):
        shutil.copy(urdf_dir() / f"psm{suffix}", tmp_path / f"psm{suffix}")
    urdf = tmp_path / "psm.urdf"
    heavier = re.sub(r'<mass value="([^"]+)"', lambda m: f'<mass value="{2 * float(m.group(1))!r}"', urdf.read_text())
    urdf.write_text(heavier)                                               # every body twice as heavy
    before = experiments._smooth_model(params)
    edited = load_robot(str(tmp_path / "psm.toml"))
    monkeypatch.setattr(experiments, "load_robot", lambda name, **kw: edited)
    after = experiments._smooth_model(params)
    assert after is not before
    q = np.array([0.2, -0.3, 0.1])
    fresh = experiments.driven_dynamics(edited, params, coulomb=False)
    np.testing.assert_allclose(np.asarray(after.gravity(q)), np.asarray(fresh.gravity(q)), atol=1e-12)
    assert not np.allclose(np.asarray(after.gravity(q)), np.asarray(before.gravity(q)))

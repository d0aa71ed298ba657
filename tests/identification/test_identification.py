"""System identification: transfer-function fits, records from logs, physics comparison (issue 5)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import signal

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.identification.pose_models import identify_folder, identify_log, physics_axis
from rcm_kin.identification.records import operating_point, prbs, step_record
from rcm_kin.identification.telemetry import load_telemetry
from rcm_kin.identification.transfer_function import fit_percent, fit_transfer_function

T = 0.0025
THESIS_ROLL = ([4.0426, -8.3312], [1.0, 6.1202, 16.288])     # thesis roll model at (0, 0), PWM -> deg


def discrete_simulation(num, den, u, period, feedback=0.0, dither=None):
    """Independent reference: ZOH state-space recursion, optionally in a loop u = dither - k y."""
    A, B, C, D = signal.tf2ss(num, den)
    Ad, Bd, Cd, _, _ = signal.cont2discrete((A, B, C, D), period, method="zoh")
    x, us, ys = np.zeros(A.shape[0]), [], []
    for k in range(len(u) if dither is None else len(dither)):
        y = (Cd @ x).item()
        uk = u[k] if dither is None else dither[k] - feedback * y
        us.append(uk)
        ys.append(y)
        x = Ad @ x + Bd[:, 0] * uk
    return np.array(us), np.array(ys)


def test_fit_percent_is_matlabs_nrmse():
    y = np.array([1.0, 2.0, 3.0, 4.0])
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full(4, 2.5)) == pytest.approx(0.0, abs=1e-12)
    assert fit_percent(y, y + [1.0, -1.0, 1.0, -1.0]) == pytest.approx(100 * (1 - 2 / np.sqrt(5)), abs=1e-12)


def test_noise_free_step_recovers_the_thesis_model_exactly():
    u = np.r_[np.zeros(20), np.full(780, -5.0)]
    _, y = discrete_simulation(*THESIS_ROLL, u, T)
    fit = fit_transfer_function(u, y, T, poles=2)
    np.testing.assert_allclose(fit.num, THESIS_ROLL[0], rtol=1e-6)
    np.testing.assert_allclose(fit.den, THESIS_ROLL[1], rtol=1e-6)
    assert fit.fit_percent > 99.999


def test_noisy_prbs_recovers_a_second_order_model():
    rng = np.random.default_rng(7)
    u = prbs(4.0, T, amplitude=10.0, min_hold=0.02, max_hold=0.3, seed=1)
    _, y = discrete_simulation(*THESIS_ROLL, u, T)
    noisy = y + rng.normal(0.0, 0.02 * np.std(y), y.size)      # 2 % output noise
    fit = fit_transfer_function(u, noisy, T, poles=2)
    np.testing.assert_allclose(fit.den, THESIS_ROLL[1], rtol=0.03)
    np.testing.assert_allclose(fit.dc_gain, -8.3312 / 16.288, rtol=0.02)
    assert fit.fit_percent > 95.0


def test_closed_loop_prbs_of_an_unstable_third_order_plant():
    """The pitch experiment in miniature: an open-loop unstable plant held by a P loop with a
    PRBS dither; the segmented (multiple-shooting) fit recovers the plant from u -> y."""
    num, den = [-3.0, -6.0], np.poly([1.2, -4.0, -9.0])          # one unstable pole at +1.2 1/s
    dither = prbs(20.0, T, amplitude=15.0, min_hold=0.005, max_hold=0.5, seed=3)
    u, y = discrete_simulation(num, den, None, T, feedback=-8.0, dither=dither)
    assert np.max(np.abs(y)) < 50                                  # the loop held it
    rng = np.random.default_rng(0)
    fit = fit_transfer_function(u, y + rng.normal(0, 0.01, y.size), T, poles=3, zeros=1, segment=400)
    np.testing.assert_allclose(np.sort(fit.poles.real), [-9.0, -4.0, 1.2], rtol=0.05)
    assert fit.fit_percent > 95.0


def test_bad_orders_and_records_are_refused():
    u = np.r_[np.zeros(10), np.ones(90)]
    with pytest.raises(RcmKinError, match="poles"):
        fit_transfer_function(u, u, T, poles=0)
    with pytest.raises(RcmKinError, match="input must vary"):
        fit_transfer_function(np.ones(100), u, T, poles=1)
    with pytest.raises(RcmKinError, match="samples"):
        fit_transfer_function(u[:5], u[:5], T, poles=2)


def test_prbs_levels_and_switching_intervals():
    seq = prbs(10.0, T, amplitude=15.0, min_hold=0.005, max_hold=1.0, seed=4)
    assert set(np.unique(seq)) == {-15.0, 15.0}
    switches = np.flatnonzero(np.diff(seq)) + 1
    holds = np.diff(np.r_[0, switches]) * T
    assert holds.min() >= 0.005 - 1e-12 and holds.max() <= 1.0 + 1e-12
    np.testing.assert_array_equal(seq, prbs(10.0, T, amplitude=15.0, min_hold=0.005, max_hold=1.0, seed=4))


def test_operating_points_from_file_names():
    assert operating_point("prbs_roll_0_pitch_m15_earlier.csv") == (0.0, -15.0)
    assert operating_point("roll_step_response_roll_-15_pitch_15.csv") == (-15.0, 15.0)
    assert operating_point("PRBS_Pitch.csv") is None


def write_log(path, rows, header):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(f"{v:.6f}" for v in r) for r in rows) + "\n")
    return path


def test_step_trimming_starts_at_rest_before_the_step(tmp_path):
    t = np.arange(300) * 0.002
    u = np.where(np.arange(300) >= 100, -15.0, -10.0)
    y = np.where(np.arange(300) >= 100, 0.01 * (np.arange(300) - 99), 0.0) - 3.0
    log = load_telemetry(write_log(tmp_path / "step.csv", zip(t, y, u), ["time", "roll_position", "roll_velocity"]))
    record = step_record(log, "roll", samples=150)
    assert record.u0 == -10.0 and record.y0 == pytest.approx(-3.0, abs=1e-9)
    assert record.u[0] == 0.0 and record.y[0] == 0.0 and np.all(record.u[1:] == -5.0)
    assert record.u.size == 150


def test_missing_joint_columns_are_a_one_line_error(tmp_path, capsys):
    t = np.arange(300) * 0.002
    path = write_log(tmp_path / "roll_only.csv", zip(t, np.sin(t), np.cos(t)),
                     ["time", "roll_position", "roll_velocity"])
    assert main(["sysid", str(path), "--joint", "pitch", "--json"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "pitch/position" in err and err.count("\n") == 1


def test_physics_dc_gain_is_input_gain_over_gravity_stiffness(psm):
    """The linearised PWM -> angle DC gain equals k_u / (dg/dq) with the gravity slope taken by
    central differences of the model's gravity (a second route, not the AD linearisation)."""
    model = driven_dynamics(psm, coulomb=False)
    for roll, pitch in ((0.0, 0.0), (-15.0, 10.0)):
        q = np.array([np.radians(roll), np.radians(pitch), 0.08])
        h = 1e-6
        for axis, joint in ((0, "roll"), (1, "pitch")):
            dq = np.zeros(3)
            dq[axis] = h
            # other joints held: the single-axis slope of g along this joint
            slope = (np.array(model.gravity(q + dq)) - np.array(model.gravity(q - dq))).ravel()[axis] / (2 * h)
            expected = np.degrees(model.drive.input_gain[axis] / slope)
            assert physics_axis(model, joint, roll, pitch).dc_gain == pytest.approx(expected, rel=1e-6)


def test_thesis_roll_model_from_the_shared_step(shared_data):
    """The thesis's (0, 0) roll model (4.04 s - 8.33) / (s^2 + 6.12 s + 16.29) from the
    single-axis roll step: the DC gain and the poles are reproduced; the thesis's numerator
    zero (+2.06 1/s, non-minimum phase) is not, the log starts without an inverse response."""
    result = identify_log(shared_data / "psm-sysid/single-axis/roll_step.csv", "roll")
    fit = result.fit
    assert fit.fit_percent > 94.0
    assert fit.dc_gain == pytest.approx(-8.3312 / 16.288, rel=0.01)
    np.testing.assert_allclose(fit.den, THESIS_ROLL[1], rtol=0.1)
    np.testing.assert_allclose(np.abs(fit.poles), np.sqrt(16.288), rtol=0.05)


def test_roll_steps_over_the_grid_fit_about_95_percent(shared_data, psm):
    models = identify_folder(shared_data / "psm-sysid/roll-step", "roll", driven_dynamics(psm, coulomb=False))
    fits = np.array([m.fit.fit_percent for m in models])
    assert len(models) == 6 and fits.min() > 88.0 and fits.mean() > 92.0
    assert all(m.physics is not None and m.fit.dc_gain < 0 and m.physics.dc_gain < 0 for m in models)


def test_sysid_cli_contract(shared_data, capsys):
    assert main(["sysid", str(shared_data / "psm-sysid/single-axis/roll_step.csv"), "--joint", "roll",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"num", "den", "fit_percent", "A", "B", "C", "D"} <= set(out)
    A, B, C, D = (np.array(out[k]) for k in "ABCD")
    # the state space realises the transfer function: same poles and DC gain
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(A)), np.sort_complex(np.roots(out["den"])),
                               atol=1e-9)
    assert (-C @ np.linalg.solve(A, B) + D).item() == pytest.approx(out["num"][-1] / out["den"][-1], rel=1e-9)


@pytest.mark.parametrize("extra, message", [
    (["--order", "0"], "poles"),
    (["--pose", "40", "0"], "roll 40 deg not in [-30 deg, 30 deg]"),
    (["--samples", "10"], "--samples"),
])
def test_sysid_cli_user_errors_are_one_line(tmp_path, capsys, extra, message):
    t = np.arange(400) * 0.002
    u = np.where(t > 0.2, -15.0, -10.0)
    path = write_log(tmp_path / "step.csv", zip(t, np.where(t > 0.2, 1 - np.exp(-(t - 0.2) * 5), 0), u),
                     ["time", "roll_position", "roll_velocity"])
    assert main(["sysid", str(path), "--joint", "roll", *extra]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err and err.count("\n") == 1


def test_a_cut_off_row_is_left_out_with_a_warning(tmp_path, capsys):
    """A recording cut off mid-row (its last line short) reads as the rows before it, and says so:
    one ``warning:`` line on stderr after a successful run, never a silent drop."""
    t = np.arange(300) * 0.002
    u = np.where(np.arange(300) >= 100, -15.0, -10.0)
    y = np.where(np.arange(300) >= 100, 0.01 * (np.arange(300) - 99), 0.0) - 3.0
    whole = write_log(tmp_path / "whole.csv", zip(t, y, u), ["time", "roll_position", "roll_velocity"])
    cut = tmp_path / "cut.csv"
    cut.write_text(whole.read_text() + "0.600000,-1.0\n")
    with pytest.warns(UserWarning, match="1 rows with a wrong number of fields"):
        log = load_telemetry(cut)
    np.testing.assert_array_equal(log.position["roll"], load_telemetry(whole).position["roll"])
    assert main(["sysid", str(cut), "--joint", "roll", "--json"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning:") and "wrong number of fields" in err and err.count("\n") == 1

"""Excitation design (``rcm-kin excite``): the Fourier trajectories, the replay file, the CLI."""

import json

import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.hardware import FIRMWARE_PERIOD, PWM_LIMIT
from rcm_kin.identification.excitation_axis import JOINT_MARGIN, PWM_FRACTION, VELOCITY_LIMIT, regressor
from rcm_kin.identification.fourier import Fourier, frequencies


def run(capsys, *argv):
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture(scope="module")
def excited(tmp_path_factory):
    """One short design of both joints through the CLI: its JSON and the file it wrote."""
    out = tmp_path_factory.mktemp("excite") / "excitation.csv"
    code = main(["excite", "psm", "--duration", "4", "--harmonics", "3", "--out", str(out), "--json"])
    return code, out


def test_fourier_is_periodic_starts_at_rest_and_its_derivatives_are_exact():
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=4), rng.normal(size=4)
    a[-1] -= a.sum()                                   # qd(0) = 0
    b[-1] -= np.arange(1, 5) @ b / 4                   # qdd(0) = 0
    f = Fourier(7.3, a, b)
    q, qd, qdd = f.evaluate([0.0, f.period])
    assert q[0] == pytest.approx(q[1], abs=1e-9) and qd[0] == pytest.approx(qd[1], abs=1e-9)
    assert q[0] == pytest.approx(0.0, abs=1e-12) and qd[0] == pytest.approx(0.0, abs=1e-12)
    assert qdd[0] == pytest.approx(0.0, abs=1e-12)
    # the series as the module states it, with q0 = sum b / (w k)
    t = np.linspace(0.0, 2 * f.period, 301)
    w = frequencies(f.period, 4)
    direct = f.offset + np.sin(np.outer(t, w)) @ (a / w) - np.cos(np.outer(t, w)) @ (b / w)
    np.testing.assert_allclose(f.evaluate(t)[0], direct, atol=1e-12)
    h = 1e-5
    (qm, qdm, _), (qp, qdp, _) = f.evaluate(t - h), f.evaluate(t + h)
    _, qd, qdd = f.evaluate(t)
    np.testing.assert_allclose((qp - qm) / (2 * h), qd, atol=1e-7)
    np.testing.assert_allclose((qdp - qdm) / (2 * h), qdd, atol=1e-7)


def test_single_sine_regressor_is_ill_conditioned():
    """The baseline's weakness, by construction: one frequency ties qdd to q (and sin q ~ q)."""
    t = np.linspace(0, 10, 2001)
    w = 2 * np.pi / 10
    Y = regressor(0.4 * np.sin(w * t), 0.4 * w * np.cos(w * t), -0.4 * w**2 * np.sin(w * t), 0.02)
    assert np.linalg.cond(Y / np.linalg.norm(Y, axis=0)) > 100


def test_excite_writes_a_replayable_file_within_the_limits(excited):
    from rcm_kin.identification.telemetry import load_telemetry

    code, out = excited
    assert code == 0
    log = load_telemetry(out)
    n = int(round(4 / FIRMWARE_PERIOD))
    assert log.time.size == 2 * n + 1
    np.testing.assert_allclose(np.diff(log.time), FIRMWARE_PERIOD, atol=1e-9)
    for k, joint in enumerate(("roll", "pitch")):
        position, pwm, setpoint = log.position[joint], log.pwm[joint], log.setpoint[joint]
        np.testing.assert_array_equal(position, setpoint)
        assert np.max(np.abs(position)) <= 30.0 - np.degrees(JOINT_MARGIN) + 1e-6
        assert np.max(np.abs(np.diff(position))) / FIRMWARE_PERIOD <= np.degrees(VELOCITY_LIMIT) + 1e-3
        assert np.max(np.abs(pwm)) <= PWM_LIMIT[k]
        moving = slice(k * n, (k + 1) * n)
        assert np.max(np.abs(pwm[moving])) <= PWM_FRACTION * PWM_LIMIT[k] + 1e-3
        assert np.ptp(position[moving]) > 10.0                 # it does move (deg)
        held = np.delete(np.arange(2 * n + 1), np.arange(k * n, (k + 1) * n))
        assert np.all(position[held] == 0.0)                   # and holds at 0 while the other moves
        assert position[k * n] == position[(k + 1) * n] == 0.0  # a whole number of periods, from rest to rest


def test_excite_contract(excited, capsys, tmp_path):
    code, out = excited
    result_file = tmp_path / "again.csv"
    code, text, err = run(capsys, "excite", "psm", "--duration", "4", "--harmonics", "3", "--joint", "roll",
                          "--out", str(result_file), "--json")
    assert code == 0, err
    result = json.loads(text)
    assert {"written", "condition_number", "baseline_condition_number", "standard_errors", "period_s"} <= set(result)
    assert result["written"] == str(result_file) and result["period_s"] == pytest.approx(4.0)
    assert set(result["condition_number"]) == {"roll"}
    assert result["condition_number"]["roll"] < result["baseline_condition_number"]["roll"] / 10
    errors = result["standard_errors"]["roll"]
    assert set(errors["regressor"]) == {"inertia", "damping", "coulomb", "gravity_sin", "gravity_cos"}
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.identification.drive_train import search_for, terms_of
    shipped = search_for(terms_of(load_drive_parameters().drive_train["roll"])).free
    assert set(errors["stick_slip"]) == set(shipped)   # the shipped roll drive train's free parameters
    assert all(0 < v < np.inf for v in errors["regressor"].values())
    # the same design (same seed) as the first joint of the two-joint file
    from rcm_kin.identification.telemetry import load_telemetry
    n = int(round(4 / FIRMWARE_PERIOD))
    np.testing.assert_array_equal(load_telemetry(result_file).pwm["roll"][:n], load_telemetry(out).pwm["roll"][:n])


def test_excite_pitch_has_no_drive_train_errors_yet(capsys, tmp_path):
    code, text, err = run(capsys, "excite", "psm", "--duration", "2", "--harmonics", "2", "--joint", "pitch",
                          "--out", str(tmp_path / "p.csv"), "--json")
    assert code == 0, err
    result = json.loads(text)
    assert result["standard_errors"]["pitch"]["stick_slip"] is None
    assert result["condition_number"]["pitch"] < result["baseline_condition_number"]["pitch"]


def test_replay_record_is_what_identification_would_predict(params):
    """The stick-slip errors are taken on the log the replay would record (feedforward plus the
    firmware's P loop): the model driven open loop by that log's PWM gives back its angle."""
    from rcm_kin.dynamics.stick_slip import axis_plant
    from rcm_kin.identification.drive_train import AxisLog, predict_log
    from rcm_kin.identification.excitation_axis import axis_model, optimise_axis
    from rcm_kin.identification.identify import base_model
    from rcm_kin.identification.replay import HOLD_POSE, closed_loop_record

    model = base_model(params)
    axis = axis_model(model, params, "roll")
    fourier = optimise_axis(axis, 2.0, 2, np.random.default_rng(0), starts=1)
    q, qd, qdd = fourier.evaluate(np.arange(800) * FIRMWARE_PERIOD)
    plant = axis_plant(model, "roll", HOLD_POSE)
    angle, pwm = closed_loop_record(params.drive_train["roll"], plant, "roll", q, axis.pwm(q, qd, qdd))
    assert np.max(np.abs(np.degrees(angle - q))) < 3.0 and np.max(np.abs(pwm)) <= PWM_LIMIT[0]
    log = AxisLog("replay", "roll", FIRMWARE_PERIOD, pwm, angle, HOLD_POSE.copy())
    np.testing.assert_allclose(predict_log(params.drive_train["roll"], plant, log), angle, atol=1e-12)


@pytest.mark.parametrize("argv, message", [
    (["--duration", "0"], "duration"),
    (["--duration", "-3"], "duration"),
    (["--duration", "1e6"], "duration"),
    (["--duration", "nan"], "duration"),
    (["--duration", "10", "--joint", "insertion"], "insertion"),
    (["--duration", "10", "--joint", "wrist"], "wrist"),
    (["--duration", "10", "--harmonics", "1"], "harmonics"),
])
def test_excite_user_errors(capsys, tmp_path, argv, message):
    code, out, err = run(capsys, "excite", "psm", *argv, "--out", str(tmp_path / "x.csv"))
    assert code == 2 and out == "" and err.startswith("error: ") and err.count("\n") == 1 and message in err
    assert not (tmp_path / "x.csv").exists()


def test_excite_refuses_to_overwrite(capsys, tmp_path):
    existing = tmp_path / "x.csv"
    existing.write_text("keep me")
    code, _, err = run(capsys, "excite", "psm", "--duration", "10", "--out", str(existing))
    assert code == 2 and "--force" in err and err.count("\n") == 1
    assert existing.read_text() == "keep me"
    code, _, err = run(capsys, "excite", "mtm", "--duration", "10", "--out", str(tmp_path / "y.csv"))
    assert code == 2 and "PSM" in err

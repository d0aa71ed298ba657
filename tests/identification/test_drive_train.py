"""The identified drive trains on the measured logs: identify, predict, validation, the closed loop."""

import json

import numpy as np
import pytest

from rcm_kin.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_shipped_roll_drive_train_predicts_every_roll_step_it_was_fitted_on(shared_data, params):
    """In-sample, the shipped roll model fits each roll-step log above 40 % and ends within 25 %
    of each measured travel (measured 41.0-80.7 % and 1-20 %; the left-out figures are in the
    shipped file's header). The set before, fitted without the thesis's P-sinusoid bound, was held
    to 45 % and 20 %: the bound costs the slow steps (docs/findings.md)."""
    from rcm_kin.dynamics.stick_slip import axis_plant
    from rcm_kin.identification.drive_train import axis_log, check_log, predict_log
    from rcm_kin.identification.identify import base_model

    model = base_model(params)
    for path in sorted((shared_data / "psm-sysid" / "roll-step").glob("*.csv")):
        log = axis_log(path, "roll")
        check = check_log(log.name, log.measured, predict_log(params.drive_train["roll"],
                                                             axis_plant(model, "roll", log.pose), log), log.period)
        assert check.fit_percent > 40.0, check
        assert check.travel_error < 0.25, check


def test_predict_contract(shared_data, capsys, tmp_path):
    log = shared_data / "psm-sysid" / "roll-step" / "roll_step_response_roll_15_pitch_0.csv"
    code, out, err = run(capsys, "predict", "psm", str(log), "--joint", "roll", "--plot", str(tmp_path / "p.png"),
                         "--json")
    assert code == 0, err
    result = json.loads(out)
    assert {"fit_percent", "final_error_deg", "time", "measured", "predicted"} <= set(result)
    assert len(result["time"]) == len(result["measured"]) == len(result["predicted"])
    assert result["measured"][0] == pytest.approx(14.883, abs=0.01)          # the log's own first angle, deg
    assert abs(result["final_error_deg"]) < 0.1 and result["fit_percent"] > 80.0    # the whole log, mostly at rest
    assert (tmp_path / "p.png").stat().st_size > 10_000


def test_a_roll_log_with_the_pitch_on_its_stop_is_predicted(shared_data, capsys):
    """roll_step.csv (the pitch resting on its lower stop) and step_response.csv (no pitch column,
    the pitch taken at its resting value) are predicted: finite fits, one per logged sample."""
    single = shared_data / "psm-sysid" / "single-axis"
    for name in ("roll_step.csv", "step_response.csv"):
        code, out, err = run(capsys, "predict", "psm", str(single / name), "--joint", "roll", "--json")
        assert code == 0, err
        result = json.loads(out)
        assert np.isfinite(result["fit_percent"]) and len(result["predicted"]) == len(result["measured"])


def test_predict_refuses_logs_the_model_cannot_speak_for(shared_data, capsys):
    """A log in raw encoder counts, or without the joint's columns, is a one-line error, not a
    number; --json output is strict JSON. (A roll log with the pitch on its stop is a roll record:
    test_a_roll_log_with_the_pitch_on_its_stop_is_predicted.)"""
    single = shared_data / "psm-sysid" / "single-axis"
    for name, joint, reason in (("pitch_speed_ramp_down_response.csv", "roll", "not in degrees"),
                                ("pitch_step_response.csv", "roll", "no roll columns")):
        code, out, err = run(capsys, "predict", "psm", str(single / name), "--joint", joint, "--json")
        assert code == 2 and out == "" and err.count("\n") == 1 and reason in err, err


def test_predict_user_errors(shared_data, capsys, tmp_path):
    pitch_only = shared_data / "psm-sysid" / "single-axis" / "PRBS_Pitch.csv"
    code, _, err = run(capsys, "predict", "psm", str(pitch_only), "--joint", "roll")
    assert code == 2 and err.count("\n") == 1 and "roll" in err
    bare = tmp_path / "bare.toml"
    from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
    text = DEFAULT_PARAMETERS.read_text()
    bare.write_text(text[:text.index("\n[drive_train.")])
    code, _, err = run(capsys, "predict", "psm", str(pitch_only), "--joint", "roll", "--params", str(bare))
    assert code == 2 and "drive_train.roll" in err and err.count("\n") == 1


def test_identify_contract(shared_data, capsys, tmp_path):
    """identify on three of the roll steps (the full run's cross-validated numbers are in the
    shipped file's header; the mechanism is tested on synthetic logs): the written file loads and
    carries the identified set, and refuses to overwrite without --force."""
    out = tmp_path / "identified.toml"
    steps = sorted((shared_data / "psm-sysid" / "roll-step").glob("*pitch_0.csv"))
    assert len(steps) == 3
    code, text, err = run(capsys, "identify", "psm", *map(str, steps), "--out", str(out), "--json")
    assert code == 0, err
    result = json.loads(text)
    assert set(result["parameters"]) == {"roll"} and len(result["fits"]["roll"]) == 3
    from rcm_kin.dynamics.drive import load_drive_parameters
    loaded = load_drive_parameters(out)
    assert loaded.drive_train["roll"].viscous == pytest.approx(result["parameters"]["roll"]["viscous"], rel=1e-12)
    assert loaded["roll"].extra_inertia == pytest.approx(result["parameters"]["roll"]["extra_inertia"], rel=1e-12)
    assert np.mean([c["fit_percent"] for c in result["fits"]["roll"].values()]) > 65.0
    free = set(result["standard_errors"]["roll"]) | set(result["undetermined"]["roll"])
    assert free == {"extra_inertia", "coulomb", "presliding_stiffness", "presliding_slope", "presliding_force",
                    "cable_stiffness", "cable_damping", "motor_coulomb", "motor_viscous"}
    # every free parameter of the roll's terms (presliding, two-mass): a finite standard error, or undetermined
    code, _, err = run(capsys, "identify", "psm", *map(str, steps), "--out", str(out))
    assert code == 2 and "--force" in err and err.count("\n") == 1


def test_identify_pitch_in_its_recorded_loop(shared_data, capsys, tmp_path):
    """The pitch from a PRBS log, simulated with the controller read back from it: the whole
    command succeeds with strict JSON (its success path, which the fuzzer's bad-input guard never
    reaches), and the record is predicted well above the zero of a constant guess."""
    logs = [shared_data / "psm-sysid" / "pitch-prbs" / "prbs_roll_0_pitch_15.csv"]
    code, text, err = run(capsys, "identify", "psm", *map(str, logs), "--joint", "pitch",
                          "--out", str(tmp_path / "pitch.toml"), "--json")
    assert code == 0, err
    result = json.loads(text)
    fits = [c["fit_percent"] for c in result["fits"]["pitch"].values()]
    assert len(fits) == 1 and fits[0] > 40.0
    from rcm_kin.dynamics.drive import load_drive_parameters
    assert "pitch" in load_drive_parameters(tmp_path / "pitch.toml").drive_train

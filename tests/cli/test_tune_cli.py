"""``schedule psm --tune``: a small study end to end, its files, and its one-line refusals."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.control.schedule_file import read_schedule_file
from rcm_kin.simulation.experiments import run_experiment
from rcm_kin.simulation.loop import tracking_metrics


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    out = tmp_path_factory.mktemp("tuned")
    code = main(["schedule", "psm", "--tune", "--draws", "8", "--tune-draws", "2", "--budget", "3", "--workers", "1",
                 "--out", str(out), "--json"])
    assert code == 0
    return out


@pytest.mark.slow
def test_the_study_writes_the_chosen_design_and_its_evidence(study):
    names = {p.name for p in study.iterdir()}
    assert {"gains.json", "gains.csv", "gain_schedule.h", "tuning.json", "tuning.png", "tuning_gains.png"} <= names
    data = json.loads((study / "tuning.json").read_text())
    assert data["chosen"] in ("fixed", "scheduled") and data["samples"] == 8 and data["tune_samples"] == 2
    assert set(data["judged"]) == {"tuning", "held_out"}
    for sets in data["judged"].values():
        assert set(sets) == {"thesis", "lqr", "fixed", "scheduled"}
        assert sets["thesis"]["tracking_score"] == 2.0 and sets["thesis"]["score"] > 100   # its frozen loop: unstable
        assert np.array(sets["fixed"]["per_draw"]["max_error_deg"], dtype=float).shape == (8, 2, 2)
    # the file holds the chosen values' tables: at the grid's centre every slope is out of the gains
    loaded = read_schedule_file(study / "gains.json")
    v = data["values"]
    np.testing.assert_allclose(loaded.schedule.k_roll[1, 1], [v["roll_kp"], v["roll_kd"]], rtol=1e-12)
    np.testing.assert_allclose(loaded.schedule.k_pitch[1, 1], [v["pitch_kp"], v["pitch_kd"], v["pitch_ki"]],
                               rtol=1e-12)
    assert loaded.schedule.friction.pwm == pytest.approx((v["roll_friction_pwm"], v["pitch_friction_pwm"]))
    assert loaded.flags == {"scheduled": True, "gravity": True, "track_velocity": True, "friction": True}


@pytest.mark.slow
def test_the_written_design_runs_in_simulate(study):
    m = tracking_metrics(run_experiment("sine", "tuned", gains=study / "gains.json"), 1.0)
    assert all(np.isfinite(m[a].max_error_deg) for a in ("roll", "pitch"))


@pytest.mark.parametrize("words, text", [
    (["schedule", "mtm", "--tune"], "mtm"),
    (["schedule", "psm", "--tune", "--grid=-20,0,20:-10,0,10"], "thesis grid"),
    (["schedule", "psm", "--tune", "--insertion", "0.1"], "thesis grid"),
    (["schedule", "psm", "--tune", "--draws", "8", "--tune-draws", "9"], "--tune-draws"),
    (["schedule", "psm", "--tune", "--draws", "4"], "--draws"),
    (["schedule", "psm", "--tune", "--budget", "0"], "--budget"),
    (["schedule", "psm", "--budget", "5"], "--budget is an option of --tune"),
    (["schedule", "psm", "--draws", "9", "--generations", "3"], "--draws is an option of --tune"),
    (["schedule", "psm", "--tune", "--friction-ramp", "3"], "--friction-ramp is an option of the LQR/LQI"),
    (["schedule", "psm", "--tune", "--roll-error-deg", "1"], "--roll-error-deg is an option of the LQR/LQI"),
    (["schedule", "psm", "--tune", "--gravity-feedforward"], "--gravity-feedforward is an option of the LQR"),
    (["schedule", "psm", "--tune", "--seed", "1"], "--check-seed must differ from --seed"),
])
def test_bad_tune_requests_are_one_line_errors(tmp_path, capsys, words, text):
    assert main(words + ["--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and text in err and "Traceback" not in err and len(err.splitlines()) == 1
    assert not (tmp_path / "o").exists()          # refused before any output

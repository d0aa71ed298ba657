"""``gravity --band``, ``torque-map --band``, ``calibrate``'s holding band: text, JSON, tables, bad levels,
a drive file without holding residuals, the extrapolated flag. Expected half-widths are sorted by hand
from the shipped file's residuals (0.9 of 11: ceil(12 x 0.9) = 11, the largest)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from oracles.cli_calls import one_line_error, run

from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, load_drive_parameters

HULL_TEXT = "extrapolated (outside the calibrated poses roll [-15.1, 19.9] deg, pitch [-16.6, 14.9] deg)"


def shipped_half_width() -> dict:
    u = load_drive_parameters().uncertainty
    return {j: float(np.max(np.abs(u.holding_residuals[j]))) for j in ("roll", "pitch")}


@pytest.fixture
def bare(tmp_path):
    path = tmp_path / "bare.toml"
    path.write_text(DEFAULT_PARAMETERS.read_text().split("[uncertainty.")[0])
    return path


def test_gravity_band_json_and_text(capsys):
    half = shipped_half_width()
    code, out, err = run(capsys, "gravity", "psm", 5, -10, 0.08, "--deg", "--band", 0.9, "--json")
    assert code == 0, err
    payload = json.loads(out)
    band = payload["band"]
    assert band["level"] == 0.9 and band["joints"] == ["roll", "pitch"] and band["extrapolated"] is False
    for k, joint in enumerate(("roll", "pitch")):
        assert band["half_width_pwm"][joint] == pytest.approx(half[joint])
        assert band["lower_pwm"][joint] == pytest.approx(payload["pwm"][k] - half[joint])
        assert band["upper_pwm"][joint] == pytest.approx(payload["pwm"][k] + half[joint])
    assert set(payload) >= {"joints", "q", "tau", "pwm", "voltage", "driven", "model"}     # the old keys kept
    code, out, err = run(capsys, "gravity", "psm", 5, -10, 0.08, "--deg", "--band", 0.9)
    assert code == 0 and "holding band 0.9" in out and "extrapolated" not in out
    assert "insertion        no band: no holding residuals in psm_drive.toml" in out
    code, out, err = run(capsys, "gravity", "psm", 5, -10, 0.08, "--deg")
    assert code == 0 and "band" not in out                                          # no --band, no band


def test_gravity_band_outside_the_calibrated_poses_says_extrapolated(capsys):
    code, out, err = run(capsys, "gravity", "psm", 25, -10, 0.08, "--deg", "--band", 0.9)
    assert code == 0 and HULL_TEXT in out and ": roll outside" in out
    code, out, err = run(capsys, "gravity", "psm", 0, -20, 0.08, "--deg", "--band", 0.9, "--json")
    assert json.loads(out)["band"]["outside"] == ["pitch"] and json.loads(out)["band"]["extrapolated"] is True


@pytest.mark.parametrize("level", ["0", "1", "1.5", "-0.2", "x", "nan"])
def test_bad_levels_are_one_line(capsys, tmp_path, level):
    one_line_error(capsys, ["gravity", "psm", "0", "0", "0.08", f"--band={level}"], "--band")
    one_line_error(capsys, ["torque-map", "psm", "--roll", "0:10:2", "--pitch", "0:0:1", "--out", tmp_path / "m",
                            f"--band={level}"], "needs a level in (0, 1)")
    assert not (tmp_path / "m").exists()


def test_a_file_without_holding_residuals_is_one_line(capsys, tmp_path, bare):
    message = "no holding residuals in bare.toml: run rcm-kin calibrate"
    one_line_error(capsys, ["gravity", "psm", "0", "0", "0.08", "--params", bare, "--band", "0.9"], message)
    one_line_error(capsys, ["torque-map", "psm", "--roll", "0:10:2", "--pitch", "0:0:1", "--params", bare,
                            "--out", tmp_path / "m", "--band", "0.9"], message)
    assert not (tmp_path / "m").exists()
    code, out, err = run(capsys, "gravity", "psm", "0", "0", "0.08", "--params", bare)
    assert code == 0, err                                                            # no --band: as before


def test_torque_map_band_columns_and_json(capsys, tmp_path):
    half = shipped_half_width()
    code, out, err = run(capsys, "torque-map", "psm", "--roll=-20:10:4", "--pitch=0:0:1", "--out", tmp_path / "m",
                         "--band", 0.9, "--no-figures", "--json")
    assert code == 0, err
    band = json.loads(out)["band"]
    assert band["half_width_pwm"] == pytest.approx(half) and band["extrapolated_poses"] == 1     # roll -20 deg
    with open(tmp_path / "m" / "torque_map.csv") as fh:
        rows = list(csv.DictReader(fh))
    for row in rows:
        assert float(row["lower_pwm_roll"]) == pytest.approx(float(row["pwm_roll"]) - half["roll"], abs=1e-8)
        assert float(row["upper_pwm_pitch"]) == pytest.approx(float(row["pwm_pitch"]) + half["pitch"], abs=1e-8)
        assert float(row["extrapolated"]) == float(float(row["roll_deg"]) < -15.1)
    code, out, err = run(capsys, "torque-map", "psm", "--roll=-20:10:4", "--pitch=0:0:1", "--out", tmp_path / "n",
                         "--no-figures")
    assert code == 0 and "lower_pwm_roll" not in (tmp_path / "n" / "torque_map.csv").read_text().splitlines()[0]
    code, out, err = run(capsys, "torque-map", "psm", "--grid", "roll=-20:10:4", "pitch=0:0:1", "--out",
                         tmp_path / "g", "--band", 0.9, "--no-figures")
    assert code == 0 and HULL_TEXT in out and "1 of 4 poses" in out
    header = (tmp_path / "g" / "torque_map.csv").read_text().splitlines()[0].split(",")
    assert header[-5:] == ["lower_pwm_roll", "upper_pwm_roll", "lower_pwm_pitch", "upper_pwm_pitch", "extrapolated"]


def test_calibrate_reports_and_writes_the_holding_band(capsys, tmp_path, shared_data):
    code, out, err = run(capsys, "calibrate", shared_data, "--out", tmp_path / "c.toml", "--json")
    assert code == 0, err
    payload = json.loads(out)
    band = payload["holding_band"]
    assert band["level"] == 0.9 and band["holds"] == 11
    assert band["left_out_inside"]["roll"] >= 10 and max(band["left_out_half_width_pwm"]["roll"]) <= 5.0
    assert band["hull_deg"]["roll"] == pytest.approx([-15.06, 19.89], abs=0.01)
    assert {"parameters", "residual_rms_pwm", "friction_band_pwm", "points", "written"} <= set(payload)
    written, shipped = load_drive_parameters(tmp_path / "c.toml"), load_drive_parameters()
    np.testing.assert_allclose(written.uncertainty.holding_residuals["pitch"],
                               band["holding_residuals_pwm"]["pitch"], rtol=0, atol=1e-12)
    # the shipped file is this calibration: its values and its [uncertainty] tables
    assert written["roll"].volts_per_pwm == pytest.approx(shipped["roll"].volts_per_pwm, rel=1e-6)
    np.testing.assert_allclose(written.gravity_offsets["roll_link"], shipped.gravity_offsets["roll_link"], rtol=1e-6)
    np.testing.assert_allclose(written.uncertainty.holding_residuals["roll"],
                               shipped.uncertainty.holding_residuals["roll"], atol=1e-6)
    code, out, err = run(capsys, "calibrate", shared_data)
    assert code == 0 and "roll  10/11 holds inside" in out and "calibrated poses: roll [-15.1, 19.9] deg" in out

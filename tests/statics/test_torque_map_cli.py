"""``rcm-kin torque-map ROBOT --grid`` and ``rcm-kin gravity`` for any robot: the files and numbers are
the library's (itself held to Pinocchio in test_torque_map_any.py), a "model" line / key says which
model was used, and bad input is one line, status 2, nothing written."""

from __future__ import annotations

import csv
import json
import re

import numpy as np
import pinocchio as pin
import pytest
from oracles.cli_calls import run

import rcm_kin as rk
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
from rcm_kin.model.loading import urdf_dir


@pytest.fixture(scope="module")
def renamed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mypsm")
    (folder / "psm.urdf").write_bytes((urdf_dir() / "psm.urdf").read_bytes())
    text = re.sub(r'^robot = "psm"$', 'robot = "mypsm"', (urdf_dir() / "psm.toml").read_text(), flags=re.M)
    (folder / "mypsm.toml").write_text(re.sub(r"^drive = .*$", "", text, flags=re.M))
    return folder / "mypsm.toml"


def test_the_mtm_map_from_the_command_line(capsys, tmp_path):
    code, out, err = run(capsys, "torque-map", "mtm", "--grid", "j2=-40:60:6", "j3=-30:80:5", "--at", "j1=10",
                         "--out", tmp_path / "m", "--json")
    assert code == 0, err
    payload = json.loads(out)
    assert payload["poses"] == 30 and payload["joints"] == ["j2", "j3"] and payload["model"] == "CAD (URDF inertias)"
    assert [p.rsplit("/", 1)[1] for p in payload["files"]] == ["torque_map.csv", "torque_map.png"]
    mtm = rk.load_robot("mtm")
    data = mtm.tree.createData()
    with (tmp_path / "m" / "torque_map.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 30
    for row in rows[::7]:
        q = np.radians([10.0, float(row["j2_deg"]), float(row["j3_deg"]), 0, 0, 0, 0])
        tau = pin.computeGeneralizedGravity(mtm.tree, data, q)
        np.testing.assert_allclose([float(row[f"tau_{j}"]) for j in mtm.actuated], tau, rtol=0, atol=2e-9)


def test_a_psm_grid_map_has_its_drive_columns(capsys, tmp_path):
    code, out, err = run(capsys, "torque-map", "psm", "--grid", "roll=-10:10:3", "pitch=0:0:1", "--at", "insertion=0.1",
                         "--out", tmp_path, "--format", "npz", "--no-figures", "--json")
    assert code == 0, err
    assert json.loads(out)["model"] == "calibration psm_drive.toml"
    table = np.load(tmp_path / "torque_map.npz")
    psm = rk.load_robot("psm")
    one = rk.holding_effort(psm, [np.radians(10), 0, 0.1, 0, 0, 0, 0])
    assert table["pwm_roll"][-1] == pytest.approx(one.drive.pwm[0], abs=1e-9)
    assert list(table) == ["roll_deg", "pitch_deg"] + [f"tau_{j}" for j in psm.actuated] + [
        f"{x}_{j}" for x in ("voltage", "pwm") for j in ("roll", "pitch", "insertion")]


def test_gravity_says_which_model(capsys, renamed):
    code, out, _ = run(capsys, "gravity", "psm", "10", "-15", "0.08", "--deg")
    assert code == 0 and out.splitlines()[-1] == "model: calibration psm_drive.toml"
    assert "driven joints" in out
    code, out, _ = run(capsys, "gravity", renamed, "10", "-15", "0.08", "--deg", "--json")
    payload = json.loads(out)
    assert code == 0 and payload["model"] == "CAD (URDF inertias)" and payload["pwm"] == [] and payload["driven"] == []
    psm = rk.load_robot("psm")
    np.testing.assert_allclose(payload["tau"], rk.gravity_torque(psm, payload["q"], method="constrained"), atol=1e-9)
    code, out, _ = run(capsys, "gravity", "mtm", "10", "--deg", "--json")
    assert code == 0 and json.loads(out)["model"] == "CAD (URDF inertias)"


@pytest.mark.parametrize("argv, message", [
    (["torque-map", "{renamed}", "--grid", "roll=0:1:2", "pitch=0:1:2", "--params", "{drive}"],
     "describes robot 'psm', not 'mypsm'"),
    (["gravity", "{renamed}", "--params", "{drive}"], "describes robot 'psm', not 'mypsm'"),
    (["gravity", "mtm", "--params", "{drive}"], "describes robot 'psm', not 'mtm'"),
    (["torque-map", "psm", "--grid", "lower_fork_joint=0:1:2", "roll=0:1:2"], "is a passive joint of psm"),
    (["torque-map", "psm", "--grid", "elbow=0:1:2", "roll=0:1:2"], "psm has no joint 'elbow'"),
    (["torque-map", "psm", "--grid", "roll=0:1:2", "roll=0:2:2"], "names roll twice"),
    (["torque-map", "psm", "--grid", "roll=0:1:2"], "takes two joints"),
    (["torque-map", "psm", "--grid", "roll", "pitch=0:1:2"], "JOINT=VALUE"),
    (["torque-map", "psm", "--grid", "roll=nan:1:3", "pitch=0:1:2"], "need finite LO < HI"),
    (["torque-map", "psm", "--grid", "roll=-30:30:2000", "pitch=-30:30:2000"], "4,000,000 poses"),
    (["torque-map", "psm", "--grid", "roll=-60:30:3", "pitch=0:1:2"], "outside its joint limits"),
    (["torque-map", "psm", "--grid", "roll=0:1:2", "pitch=0:1:2", "--at", "roll=3"], "roll is a joint of the grid"),
    (["torque-map", "psm", "--grid", "roll=0:1:2", "pitch=0:1:2", "--roll=0:1:2"], "--grid replaces --roll"),
    (["torque-map", "mtm"], "a torque map of mtm is over two of its actuated joints"),
    (["torque-map", "mtm", "--roll=0:1:2"], "--roll/--pitch/--insertion are the bundled PSM's: for mtm give --grid"),
    (["torque-map", "psm", "--at", "roll=3"], "--at sets the other joints of a --grid map"),
])
def test_bad_input_is_one_line_and_writes_nothing(capsys, tmp_path, renamed, argv, message):
    argv = [a.format(renamed=renamed, drive=DEFAULT_PARAMETERS) for a in argv]
    code, out, err = run(capsys, *argv, "--out", tmp_path / "m") if argv[0] == "torque-map" else run(capsys, *argv)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("error: ") and message in err, err
    assert not (tmp_path / "m").exists()

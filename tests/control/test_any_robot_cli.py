"""``dynamics``, ``linearize`` and ``schedule`` for robots other than the bundled PSM: the MTM (no
drive: torque input), a renamed re-massed PSM copy with its own drive file, drive files of another
robot or naming a missing joint (one line, status 2, nothing written)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pinocchio as pin
import pytest
from oracles.cli_calls import one_line_error, run
from oracles.dyn_robots import DRIVE_KEYS, drive_text, write_mypsm, write_ur5

import rcm_kin as rk
from rcm_kin.control.joint_schedule import axis_gains, parse_joint_grid, schedule_joints
from rcm_kin.control.linearization import linearize
from rcm_kin.control.weights import Weights
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.errors import RcmKinError
from rcm_kin.model.loading import urdf_dir


def test_mtm_linearize_and_dynamics_have_torque_input(capsys, mtm):
    code, out, err = run(capsys, "linearize", "mtm", "--q", "10", "20", "-30", "0", "0", "0", "0", "--deg", "--json")
    assert code == 0, err
    lin = json.loads(out)
    assert lin["model"] == "CAD (URDF inertias)" and lin["input_unit"].startswith("torque")
    assert lin["input"][:3] == ["tau_j1", "tau_j2", "tau_j3"] and lin["state"][7] == "v_j1"
    q = np.radians([10, 20, -30, 0, 0, 0, 0])
    g = pin.computeGeneralizedGravity(mtm.tree, mtm.tree.createData(), q[np.argsort(mtm.tree_q_actuated)])
    np.testing.assert_allclose(lin["u0"], g[mtm.tree_q_actuated], rtol=0, atol=1e-9)   # holding torques, N m
    code, out, err = run(capsys, "dynamics", "mtm", "--joints", "j2", "j3", "--q", "0.3", "-0.5", "--u", "1", "0")
    assert code == 0 and "model: CAD (URDF inertias)" in out and "j3         qdd" in out, err


def test_psm_outputs_name_the_shipped_calibration(capsys):
    code, out, _ = run(capsys, "linearize", "psm", "--roll", "10", "--pitch=-5", "--json")
    lin = json.loads(out)
    assert lin["model"] == "calibration psm_drive.toml" and lin["input_unit"] == "PWM [counts]"
    assert lin["input"] == ["pwm_roll", "pwm_pitch", "pwm_insertion"]
    code, out, _ = run(capsys, "linearize", "psm", "--roll", "10", "--pitch=-5")
    assert code == 0 and out.endswith("\nmodel: calibration psm_drive.toml, PWM [counts] input\n")   # always said


def test_the_renamed_copy_runs_on_its_own_drive(capsys, tmp_path):
    sidecar, joints = write_mypsm(tmp_path)
    code, out, err = run(capsys, "linearize", sidecar, "--roll", "10", "--pitch=-5", "--json")
    assert code == 0, err
    ours = json.loads(out)
    assert ours["model"] == "calibration mypsm_drive.toml"
    _, out, _ = run(capsys, "linearize", "psm", "--roll", "10", "--pitch=-5", "--json")
    assert np.abs(np.subtract(ours["u0"], json.loads(out)["u0"])).max() > 1.0     # not the PSM's calibration
    one_line_error(capsys, ["linearize", sidecar, "--roll", "10", "--pitch", "0", "--params", DEFAULT_PARAMETERS],
                   "describes robot 'psm', not 'mypsm'")


def mtm_with_drive(tmp_path, text: str):
    """The bundled MTM's URDF and sidecar copied beside a drive file ``text`` that the sidecar names."""
    (tmp_path / "mtm.urdf").write_text((urdf_dir() / "mtm.urdf").read_text())
    (tmp_path / "mtm_drive.toml").write_text(text)
    (tmp_path / "mtm.toml").write_text((urdf_dir() / "mtm.toml").read_text() + 'drive = "mtm_drive.toml"\n')
    return tmp_path / "mtm.toml"


def mtm_drive_joints():
    values = {k: 1.0 for k in DRIVE_KEYS} | {"coulomb": 0.1, "viscous": 0.01, "rotor_inertia": 1e-6,
                                              "gear_ratio": 50.0, "torque_constant": 0.05, "volts_per_pwm": 0.1}
    return {"j2": values, "j3": values | {"pwm_sign": -1.0}}


@pytest.mark.parametrize("edit, message", [
    (("[j3]", "[elbow]"), "joints elbow are not actuated joints of mtm"),
    (('robot = "mtm"', 'robot = "ur5"'), "describes robot 'ur5', not 'mtm'"),
])
@pytest.mark.parametrize("command", [["linearize", "--q", "0", "0"], ["dynamics", "--q", "0", "0"],
                                     ["schedule", "--grid", "j2=0:20:3", "j3=-20:0:3", "--out", "gains"]])
def test_drive_file_of_another_robot_or_a_missing_joint_is_one_line(capsys, tmp_path, monkeypatch, edit, message,
                                                                    command):
    sidecar = mtm_with_drive(tmp_path, drive_text("mtm", mtm_drive_joints()).replace(*edit))
    monkeypatch.chdir(tmp_path)
    one_line_error(capsys, [command[0], sidecar, *command[1:]], message)
    one_line_error(capsys, [command[0], "mtm", *command[1:], "--params", tmp_path / "mtm_drive.toml"], message)
    assert not (tmp_path / "gains").exists()


def test_schedule_needs_a_drive_and_the_header_is_the_psms(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    one_line_error(capsys, ["schedule", "mtm", "--grid", "j2=0:20:3", "j3=-20:0:3", "--out", "g"],
                   "schedule needs a drive: mtm has no drive parameter file")
    sidecar = mtm_with_drive(tmp_path, drive_text("mtm", mtm_drive_joints()))
    one_line_error(capsys, ["schedule", sidecar, "--grid", "j2=0:20:3", "j3=-20:0:3", "--gravity-feedforward",
                            "--out", "g"], "PSM firmware's C header")
    one_line_error(capsys, ["schedule", sidecar, "--grid", "j2=0:20:3", "--out", "g"], "two scheduling joints")
    one_line_error(capsys, ["schedule", sidecar, "--grid", "j2=0:20:3", "j1=0:20:3", "--out", "g"],
                   "two distinct joints of the model (j2, j3)")
    assert not (tmp_path / "g").exists()


def test_schedule_of_another_robot_with_a_drive(capsys, tmp_path, monkeypatch):
    """The MTM's shoulder and elbow with a drive file: the tables equal LQR/LQI designs on axis
    models taken from the library's linear model at each grid point; the loop is stable."""
    monkeypatch.chdir(tmp_path)
    sidecar = mtm_with_drive(tmp_path, drive_text("mtm", mtm_drive_joints()))
    code, out, err = run(capsys, "schedule", sidecar, "--grid", "j2=0:40:3", "j3=-30:10:2", "--out", "g", "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["stable"] and result["model"] == "calibration mtm_drive.toml"
    tables = json.loads((tmp_path / "g" / "schedule.json").read_text())
    with (tmp_path / "g" / "schedule.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6 and tables["joints"] == ["j2", "j3"]
    robot = rk.load_robot(sidecar)
    model = driven_dynamics(robot, coulomb=False)
    lin = linearize(model, np.radians([40, 10]))              # grid point [j3 = 10][j2 = 40]
    k1 = axis_gains(lin.A, lin.B, 0, *Weights().roll(), integral=False)
    k2 = axis_gains(lin.A, lin.B, 1, *Weights().pitch(), integral=True)
    np.testing.assert_allclose(tables["k_first"][1][2], k1, rtol=1e-9)
    np.testing.assert_allclose(tables["k_second"][1][2], k2, rtol=1e-9)
    np.testing.assert_allclose([float(rows[5]["kp_j2"]), float(rows[5]["ki_j3"])], [k1[0], k2[2]], rtol=1e-8)


def test_joint_grid_is_checked(mtm, tmp_path):
    sidecar = mtm_with_drive(tmp_path, drive_text("mtm", mtm_drive_joints()))
    model = driven_dynamics(rk.load_robot(sidecar), coulomb=False)
    assert list(parse_joint_grid(["j3=0:10:2", "j2=-5:5:3"], model)) == ["j3", "j2"]
    for words, message in ((["j2=0:10", "j3=0:1:2"], "JOINT=LO:HI:N"), (["j2=0:10:1", "j3=0:1:2"], "N must be"),
                           (["j2=0:500:3", "j3=0:1:2"], "leaves the joint range")):
        with pytest.raises(RcmKinError, match=message):
            parse_joint_grid(words, model)
    with pytest.raises(RcmKinError, match="needs a drive"):
        schedule_joints(driven_dynamics(mtm, coulomb=False), {"j2": np.array([0, 10]), "j3": np.array([0, 10])})


def test_ur5_linearize_by_sidecar_path(capsys, tmp_path):
    code, out, err = run(capsys, "linearize", write_ur5(tmp_path), "--q", "0", "-1", "1", "0", "1", "0", "--json")
    assert code == 0, err
    lin = json.loads(out)
    assert lin["model"] == "CAD (URDF inertias)" and len(lin["A"]) == 12
    one_line_error(capsys, ["linearize", tmp_path / "ur5.toml", "--roll", "0", "--pitch", "0"], "give the pose of")
    one_line_error(capsys, ["dynamics", tmp_path / "ur5.toml", "--q", "0", "1"], "--q takes 6 values")


def test_massless_urdf_is_refused_in_one_line(capsys, tmp_path, monkeypatch):
    import re

    text = (urdf_dir() / "mtm.urdf").read_text()
    (tmp_path / "bare.urdf").write_text(re.sub(r"<inertial>.*?</inertial>", "", text, flags=re.S))
    sidecar = (urdf_dir() / "mtm.toml").read_text().replace('robot = "mtm"', 'robot = "bare"')
    (tmp_path / "bare.toml").write_text(sidecar.replace('urdf = "mtm.urdf"', 'urdf = "bare.urdf"'))
    monkeypatch.chdir(tmp_path)
    for argv in (["linearize", "bare.toml", "--q", "0"], ["dynamics", "bare.toml", "--q", "0"],
                 ["schedule", "bare.toml", "--grid", "j2=0:10:2", "j3=0:10:2", "--out", "g"]):
        one_line_error(capsys, argv, "needs masses: links")
    assert not (tmp_path / "g").exists()

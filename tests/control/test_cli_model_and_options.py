"""Every text output of ``dynamics``, ``linearize`` and ``schedule`` ends with the model it used;
``schedule`` refuses in one line the options its path does not use (the PSM's firmware schedule:
--at; any other robot's: --insertion, --check-points) and takes ``--at J=VALUE`` (degrees for a
revolute joint, metres for a prismatic one), checked against holding PWM from plain Pinocchio."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
from oracles.cli_calls import one_line_error, run
from oracles.dyn_robots import DRIVE_KEYS, drive_text, write_mypsm

from rcm_kin.model.loading import urdf_dir

SHIPPED_LINE = "model: calibration psm_drive.toml, PWM [counts] input"


def test_every_psm_text_output_ends_with_its_model(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for argv in (["linearize", "psm", "--roll", "10", "--pitch=-5"],
                 ["dynamics", "psm", "--q", "0.1", "-0.2", "0.08", "--u", "10", "-90", "0"],
                 ["schedule", "psm", "--grid", "roll=0:10:2", "pitch=0:10:2", "--check-points", "2", "--out", "g"]):
        code, out, err = run(capsys, *argv)
        assert code == 0, err
        assert out.splitlines()[-1] == SHIPPED_LINE, (argv, out)
        code, out, err = run(capsys, *argv[:-1], argv[-1] + "2" if argv[0] == "schedule" else argv[-1], "--json")
        assert code == 0 and json.loads(out)["model"] == "calibration psm_drive.toml", err


def mtm_three_joint_drive(folder):
    """The bundled MTM's URDF and sidecar beside a drive file over j2, j3, g3 (made-up constants)."""
    (folder / "mtm.urdf").write_text((urdf_dir() / "mtm.urdf").read_text())
    values = {k: 1.0 for k in DRIVE_KEYS} | {"coulomb": 0.1, "viscous": 0.01, "rotor_inertia": 1e-6,
                                              "gear_ratio": 50.0, "torque_constant": 0.05, "volts_per_pwm": 0.1}
    joints = {"j2": values, "j3": values | {"pwm_sign": -1.0}, "g3": values | {"gear_ratio": 20.0}}
    (folder / "mtm_drive.toml").write_text(drive_text("mtm", joints))
    (folder / "mtm.toml").write_text((urdf_dir() / "mtm.toml").read_text() + 'drive = "mtm_drive.toml"\n')
    return folder / "mtm.toml", joints


def test_schedule_at_takes_joint_values_in_degrees(capsys, tmp_path, monkeypatch, mtm):
    monkeypatch.chdir(tmp_path)
    sidecar, joints = mtm_three_joint_drive(tmp_path)
    code, out, err = run(capsys, "schedule", sidecar, "--grid", "j2=0:40:2", "j3=-30:10:2", "--at", "g3=30",
                         "--out", "g")
    assert code == 0, err
    assert out.splitlines()[-1] == "model: calibration mtm_drive.toml, PWM [counts] input"
    tables = json.loads((tmp_path / "g" / "schedule.json").read_text())
    assert tables["modelled_joints"] == ["j2", "j3", "g3"]
    assert tables["at"][2] == np.radians(30.0)
    q = np.zeros(mtm.nq)                                  # grid point [j3 = -30][j2 = 40], g3 = 30 deg
    q[[mtm.actuated.index(j) for j in ("j2", "j3", "g3")]] = np.radians([40.0, -30.0, 30.0])
    g = pin.computeGeneralizedGravity(mtm.tree, mtm.tree.createData(), q[np.argsort(mtm.tree_q_actuated)])
    tau = g[mtm.tree_q_actuated][[mtm.actuated.index(j) for j in ("j2", "j3", "g3")]]
    k_u = np.array([t["pwm_sign"] * t["torque_constant"] * t["gear_ratio"] * t["volts_per_pwm"] / t["resistance"]
                    for t in joints.values()])
    np.testing.assert_allclose(tables["u_hold"][0][1], tau / k_u, rtol=1e-9, atol=1e-12)
    one_line_error(capsys, ["schedule", sidecar, "--grid", "j2=0:40:2", "j3=-30:10:2", "--at", "0.5", "--out", "h"],
                   "--at takes JOINT=VALUE words")
    one_line_error(capsys, ["schedule", sidecar, "--grid", "j2=0:40:2", "j3=-30:10:2", "--at", "j5=1", "--out", "h"],
                   "--at j5: not a joint of the model of mtm (j2, j3, g3)")
    one_line_error(capsys, ["schedule", sidecar, "--grid", "j2=0:40:2", "j3=-30:10:2", "--at", "j2=1", "--out", "h"],
                   "--at j2: j2 is a joint of the grid")
    assert not (tmp_path / "h").exists()


def test_schedule_at_a_prismatic_joint_is_in_metres(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sidecar, _ = write_mypsm(tmp_path)
    code, out, err = run(capsys, "schedule", sidecar, "--grid", "roll=-10:10:2", "pitch=-10:10:2",
                         "--at", "insertion=0.12", "--out", "g")
    assert code == 0, err
    tables = json.loads((tmp_path / "g" / "schedule.json").read_text())
    assert tables["modelled_joints"] == ["roll", "pitch", "insertion"] and tables["at"][2] == 0.12
    code, _, err = run(capsys, "schedule", sidecar, "--grid", "roll=-10:10:2", "pitch=-10:10:2", "--out", "mid")
    assert code == 0, err
    mid = json.loads((tmp_path / "mid" / "schedule.json").read_text())
    assert mid["at"][2] == 0.08 and mid["u_hold"] != tables["u_hold"]      # mid-range insertion: 0 to 0.16 m


def test_schedule_refuses_what_its_path_does_not_use(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    sidecar, _ = write_mypsm(tmp_path)
    grid = ["--grid", "roll=-10:10:2", "pitch=-10:10:2", "--out", "g"]
    one_line_error(capsys, ["schedule", sidecar, *grid, "--insertion", "0.1"],
                   "--insertion is the bundled PSM's: hold mypsm's other joints with --at J=VALUE")
    one_line_error(capsys, ["schedule", sidecar, *grid, "--check-points", "5"],
                   "--check-points is the bundled PSM's")
    one_line_error(capsys, ["schedule", "psm", *grid, "--at", "insertion=0.1"],
                   "--at is not an option of the PSM's schedule")
    assert not (tmp_path / "g").exists()

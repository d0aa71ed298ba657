"""Every any-robot command, end to end, on robots no code names: a renamed and re-massed PSM copy
with no drive file (its CAD physics; the shipped calibration must never reach it), the same copy
with a drive file of its own, a dVRK Classic PSM generated from its modified-DH table (continuous
mimic joints, package:// meshes, inertials added), and a UR5 URDF alone. The numbers the commands
print agree with each other and with plain Pinocchio on the same URDF."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest
from oracles.dvrk_classic import write_dvrk_psm
from oracles.dyn_robots import ur5_urdf, write_mypsm


def run(*args, ok=True):
    out = subprocess.run([sys.executable, "-m", "rcm_kin.cli", *map(str, args)], capture_output=True, text=True)
    if ok:
        assert out.returncode == 0, (args, out.stderr)
    return out


def js(*args):
    return json.loads(run(*args, "--json").stdout)


@pytest.fixture(scope="module")
def robots(tmp_path_factory):
    """name -> (robot argument, its two map joints, extra flags of view/export, drive file or None)."""
    root = tmp_path_factory.mktemp("robots")
    mine, _ = write_mypsm(root)
    cad = root / "cad_mypsm.toml"                                 # the copy without its drive file
    cad.write_text(mine.read_text().replace('drive = "mypsm_drive.toml"\n', ""))
    dvrk = write_dvrk_psm(root / "dvrk", inertials=True)
    return {"mypsm-cad": (cad, ("roll", "pitch"), (), None),
            "mypsm-drive": (mine, ("roll", "pitch"), (), "mypsm_drive.toml"),
            "dvrk": (dvrk.sidecar, ("outer_yaw", "outer_pitch"), ("--package-dir", f"dvrk_model={dvrk.package_dir}"),
                     None),
            "ur5": (ur5_urdf(), ("shoulder_lift_joint", "elbow_joint"),      # package://example-robot-data/robots/...
                    ("--package-dir", f"example-robot-data={ur5_urdf().parents[2]}"), None)}


@pytest.mark.parametrize("name", ["mypsm-cad", "mypsm-drive", "dvrk", "ur5"])
def test_the_whole_pipeline_runs_on_the_robots_own_physics(robots, name, tmp_path):
    robot, (a, b), extra, drive = robots[name]
    model = "CAD (URDF inertias)" if drive is None else f"calibration {drive}"
    info = js("info", robot)
    joints = [j["name"] for j in info["joints"] if j["role"] == "actuated"]
    q = np.zeros(len(joints))
    q[joints.index(a)], q[joints.index(b)] = np.radians(10.0), np.radians(-15.0)
    if "insertion" in joints:
        q[joints.index("insertion")] = 0.08
    if "outer_insertion" in joints:
        q[joints.index("outer_insertion")] = 0.1
    fk = js("fk", robot, *q)
    assert fk["frames"]
    gravity = js("gravity", robot, *q)
    assert gravity["model"] == model and len(gravity["tau"]) == len(joints)
    assert bool(gravity["pwm"]) == (drive is not None)
    # the map at the same pose, and the linear model's holding input there: the same torques
    tmap = js("torque-map", robot, "--grid", f"{a}=5:10:2", f"{b}=-15:-10:2", "--out", tmp_path / "map",
              "--no-figures", *sum((["--at", f"{j}={v}"] for j, v in zip(joints, q) if j not in (a, b) and v), []))
    assert tmap["model"] == model and tmap["poses"] == 4
    rows = np.genfromtxt(tmp_path / "map" / "torque_map.csv", delimiter=",", names=True)
    row = rows[(np.isclose(rows[f"{a}_deg"], 10)) & (np.isclose(rows[f"{b}_deg"], -15))]
    np.testing.assert_allclose([row[f"tau_{j}"][0] for j in joints], gravity["tau"], atol=2e-9)
    lin = js("linearize", robot, "--q", *(q if drive is None else q[:3]))
    assert lin["model"] == model
    if drive is None:
        assert lin["input_unit"].startswith("torque")
        np.testing.assert_allclose(lin["u0"], gravity["tau"], atol=1e-9)
    else:
        assert lin["input_unit"].startswith("PWM")
        np.testing.assert_allclose(lin["u0"], gravity["pwm"], atol=1e-9)
    if name == "ur5":       # example-robot-data's wheel ships the UR5's collision meshes, not its visual .dae
        for args in (("export", robot, "--mjcf", tmp_path / "robot.xml"),
                     ("view", robot, "--html", tmp_path / "r.html")):
            out = run(*args, *extra, ok=False)
            assert out.returncode == 2 and out.stderr.count("\n") == 1 and "base.dae" in out.stderr, out.stderr
            assert not (tmp_path / "robot.xml").exists() and not (tmp_path / "r.html").exists()
        return
    export = js("export", robot, "--mjcf", tmp_path / "robot.xml", *extra)
    assert export["model"] == model and (tmp_path / "robot.xml").is_file()
    view = js("view", robot, "--html", tmp_path / "robot.html", *extra)
    assert view["written"] and (tmp_path / "robot.html").stat().st_size > 10_000
    for out in (gravity, tmap, lin, export):
        assert "calibration psm_drive.toml" not in json.dumps(out)   # the shipped calibration never reaches them


def test_the_ur5_numbers_are_plain_pinocchios(robots):
    """Gravity and the linear model of the UR5 (a URDF alone) against plain Pinocchio on its URDF."""
    urdf = robots["ur5"][0]
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    q = np.random.default_rng(3).uniform(-1.0, 1.0, model.nq)
    gravity = js("gravity", urdf, *q)
    np.testing.assert_allclose(gravity["tau"], pin.computeGeneralizedGravity(model, data, q), atol=1e-9)
    lin = js("linearize", urdf, "--q", *q)
    tau = pin.computeGeneralizedGravity(model, data, q)
    pin.computeABADerivatives(model, data, q, np.zeros(model.nv), tau)
    n = model.nv
    np.testing.assert_allclose(np.array(lin["A"])[n:, :n], data.ddq_dq, atol=1e-9)
    np.testing.assert_allclose(np.array(lin["B"])[n:], data.Minv, atol=1e-9)


def test_the_psm_only_commands_refuse_the_copy_in_one_line(robots):
    robot = robots["mypsm-drive"][0]
    for args in (("simulate", robot), ("robustness", robot), ("identify", robot, "."), ("excite", robot),
                 ("export", robot, "--c", "out")):
        out = run(*args, ok=False)
        lines = out.stderr.strip().splitlines()
        assert out.returncode == 2 and len(lines) == 1 and lines[0].startswith("error:"), (args, out.stderr)


def test_the_bundled_psm_by_the_path_of_its_sidecar_is_the_psm(tmp_path):
    """The PSM-only commands take the bundled PSM by its sidecar's path as by its name."""
    from rcm_kin.model.loading import urdf_dir

    out = run("export", urdf_dir() / "psm.toml", "--c", tmp_path / "c", "--json")
    assert {p.rsplit("/", 1)[-1] for p in json.loads(out.stdout)["files"]} == {"rcm_psm_model.h", "rcm_psm_model.c"}

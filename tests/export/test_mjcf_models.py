"""One model per parameter set: the exported MJCF holds the gravity model ``rcm-kin gravity`` uses, checked
in MuJoCo. At every keyframe ``gravity``'s torques, applied by the motors, leave MuJoCo's arm without
acceleration along the motions its loops allow; the other model's torques do not.

The check (:func:`~rcm_kin.export.mujoco_check.allowed_acceleration`): after ``mj_forward`` with the
torques, the M-orthogonal projection of MuJoCo's ``qacc`` onto the null space of its loop-constraint
Jacobian. MuJoCo's soft loops leave an acceleration error M^-1 J' df that this projection removes
exactly, so what is left is the closed chain's own acceleration: rounding when the torques balance
MuJoCo's gravity. Measured: at most 2e-11 rad/s^2 (the 6 g wrist's small inertia amplifies the
1e-15 N m residual force); tolerance 1e-8. A model's torques on the other model (the calibration's
offsets: up to 4.6 N m on roll, 5.5 on pitch) give 50 to 130 rad/s^2. Joint limits are off (the
grid's +-30 deg pitch is at its stops, which would hold any torque pushing into them) and the dry
friction (``frictionloss``, up to 1.3 N m) is zeroed: neither may hide a wrong torque.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import replace

import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.dynamics.drive import write_parameters
from rcm_kin.export.mjcf import write_mjcf
from rcm_kin.export.mujoco_check import actuated_q, allowed_acceleration, at_keyframe, model_text
from rcm_kin.model import load_robot
from rcm_kin.model.constrained import solve_loops
from rcm_kin.model.gravity import gravity_torque
from rcm_kin.model.loading import urdf_dir
from rcm_kin.model.reduced import tree_configuration

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the optional extra [mujoco]")

HELD = 1e-8       # rad/s^2 (m/s^2): rounding (see the module docstring)
FALLS = 1.0       # rad/s^2: the other model's torques


def _cli_json(capsys, argv: list[str]) -> dict:
    capsys.readouterr()
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _gravity(capsys, robot: str, q: np.ndarray, params: str | None = None) -> np.ndarray:
    """``rcm-kin gravity ROBOT Q... --json``'s torques (N m, N)."""
    argv = ["gravity", robot, *[repr(float(x)) for x in q]] + (["--params", params] if params else [])
    return np.array(_cli_json(capsys, argv)["tau"])


def _export(capsys, tmp_path, robot: str, name: str, *extra: str):
    """``rcm-kin export ROBOT --mjcf`` loaded by MuJoCo (limits off, dry friction zeroed), and its --json."""
    out = _cli_json(capsys, ["export", robot, "--mjcf", str(tmp_path / f"{name}.xml"), *extra])
    model = mujoco.MjModel.from_xml_path(out["files"][0])
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_LIMIT
    model.dof_frictionloss[:] = 0.0
    return model, out


def _worst(model, key: str, tau: np.ndarray) -> float:
    return float(np.max(np.abs(allowed_acceleration(model, at_keyframe(model, key, tau)))))


def _keys(model) -> list[str]:
    return [model.key(i).name for i in range(model.nkey)]


def _renamed_psm(tmp_path) -> str:
    """The PSM's sidecar as a user's robot 'mypsm' with no drive file: its CAD only."""
    text = (urdf_dir() / "psm.toml").read_text()
    lines = [line for line in text.splitlines() if not line.startswith("drive")]
    (tmp_path / "mypsm.urdf").write_text((urdf_dir() / "psm.urdf").read_text())
    (tmp_path / "mypsm.toml").write_text("\n".join(lines).replace('robot = "psm"', 'robot = "mypsm"')
                                         .replace('urdf = "psm.urdf"', 'urdf = "mypsm.urdf"') + "\n")
    return str(tmp_path / "mypsm.toml")


def _at_pose(model, robot, q: np.ndarray, tau: np.ndarray) -> float:
    """_worst at a pose of our own: MuJoCo's qpos from the closed open-tree configuration (Newton on
    the loops), the motors at ``tau``."""
    q_tree = tree_configuration(robot, q)
    q_tree = solve_loops(robot, q, q_tree) if robot.constraints else q_tree
    data = mujoco.MjData(model)
    for j in range(1, robot.tree.njoints):
        data.qpos[model.joint(robot.tree.names[j]).qposadr[0]] = q_tree[robot.tree.joints[j].idx_q]
    data.ctrl[:] = tau
    mujoco.mj_forward(model, data)
    return float(np.max(np.abs(allowed_acceleration(model, data))))


def test_psm_export_is_held_by_gravitys_torques_at_every_keyframe(tmp_path, capsys):
    """The default export (the shipped calibration) and `rcm-kin gravity psm` are one model; the CAD's
    torques (Pinocchio's gravity on the URDF) do not hold it."""
    psm = load_robot("psm")
    model, out = _export(capsys, tmp_path, "psm", "psm")
    assert out["model"] == model_text(model) == "calibration psm_drive.toml"
    assert len(_keys(model)) == 10
    for key in _keys(model):
        q = actuated_q(model, at_keyframe(model, key), psm)
        tau = _gravity(capsys, "psm", q)
        np.testing.assert_allclose(model.key(key).ctrl, tau, rtol=0, atol=1e-12)      # the keyframe's controls
        assert _worst(model, key, tau) < HELD, key
        assert _worst(model, key, gravity_torque(psm, q)) > FALLS, key                # CAD torques: it falls


POSES = [np.array([0.3, -0.4, 0.12, 0.2, -0.3, 0.1, 0.2]), np.array([-0.5, 0.5, 0.03, -1.0, 0.5, -0.5, 0.1])]


def test_cad_export_is_held_by_cad_torques_and_not_by_the_calibrated_ones(tmp_path, capsys):
    """A robot without a drive file (the PSM renamed, its sidecar's drive line removed) exports its CAD:
    `rcm-kin gravity` of it holds it at home and at poses of our own (and equals Pinocchio's gravity
    on the URDF); the calibrated PSM's torques do not."""
    sidecar = _renamed_psm(tmp_path)
    robot = load_robot(sidecar)
    model, out = _export(capsys, tmp_path, sidecar, "mypsm")
    assert out["model"] == model_text(model) == "CAD (URDF inertias)"
    assert _keys(model) == ["home"]
    home = actuated_q(model, at_keyframe(model, "home"), robot)
    for q in [home] + POSES:
        tau = _gravity(capsys, sidecar, q)
        np.testing.assert_allclose(tau, gravity_torque(robot, q), rtol=0, atol=1e-12)
        assert _at_pose(model, robot, q, tau) < HELD
        assert _at_pose(model, robot, q, _gravity(capsys, "psm", q)) > FALLS
    assert _worst(model, "home", _gravity(capsys, sidecar, home)) < HELD      # the keyframe itself


def test_mtm_export_is_held_by_gravitys_torques(tmp_path, capsys):
    """The MTM (a serial arm, no drive file: its CAD) in MuJoCo without equality constraints: qacc itself
    is ~0 under `rcm-kin gravity mtm`'s torques, and not under 0.9 of them."""
    mtm = load_robot("mtm")
    model, out = _export(capsys, tmp_path, "mtm", "mtm")
    assert out["model"] == "CAD (URDF inertias)" and model.neq == 0
    rng = np.random.default_rng(25)
    for q in [np.clip(np.zeros(mtm.nq), mtm.lower, mtm.upper)] + [rng.uniform(mtm.lower, mtm.upper) for _ in range(3)]:
        tau = _gravity(capsys, "mtm", q)
        assert _at_pose(model, mtm, q, tau) < HELD
        assert _at_pose(model, mtm, q, 0.9 * tau) > 1e-3 * FALLS


def test_params_file_is_the_model_the_export_holds(tmp_path, capsys, params):
    """--params: a calibration of the PSM with its gravity offsets halved. The export holds it (model
    named after the file); `gravity --params` of the same file holds it, the shipped set does not."""
    half = write_parameters(replace(params, gravity_offsets={k: 0.5 * v for k, v in params.gravity_offsets.items()}),
                            tmp_path / "half.toml")
    psm = load_robot("psm")
    model, out = _export(capsys, tmp_path, "psm", "half", "--params", str(half))
    assert out["model"] == model_text(model) == "calibration half.toml"
    for key in ("home", "roll30_pitch-30", "roll-30_pitch30"):
        q = actuated_q(model, at_keyframe(model, key), psm)
        assert _worst(model, key, _gravity(capsys, "psm", q, str(half))) < HELD
        assert _worst(model, key, _gravity(capsys, "psm", q)) > FALLS


def test_offsets_are_centre_of_mass_shifts_mass_and_central_inertia_kept(tmp_path, capsys):
    """MuJoCo's bodies of the calibrated export: the CAD's mass, the centre moved by h / m with h read
    from the TOML itself, the principal inertias about the centre the CAD's; every other body the CAD's."""
    psm = load_robot("psm")
    cal, _ = _export(capsys, tmp_path, "psm", "psm")
    cad = mujoco.MjModel.from_xml_path(str(write_mjcf(psm, tmp_path / "cad.xml", "cad")))
    offsets = tomllib.loads((urdf_dir() / "psm_drive.toml").read_text())["gravity_offsets"]
    assert sorted(offsets) == ["drive_link", "roll_link"]
    for b in range(1, cal.nbody):
        name = cal.body(b).name
        assert cal.body_mass[b] == cad.body_mass[b]
        np.testing.assert_allclose(np.sort(cal.body_inertia[b]), np.sort(cad.body_inertia[b]), rtol=1e-12)
        shift = np.asarray(offsets.get(name, [0.0, 0.0, 0.0])) / cal.body_mass[b]   # both link frames are the body's
        np.testing.assert_allclose(cal.body_ipos[b], cad.body_ipos[b] + shift, rtol=0, atol=1e-15)
    assert np.abs(cal.body_ipos - cad.body_ipos).max() > 0.2      # the drive link's centre: 21 cm


def test_a_tilted_base_is_held_by_its_own_gravity(tmp_path, capsys):
    """A tilted MTM copy ([base] rpy): the MJCF's gravity is the base frame's, and MuJoCo holds the
    arm with `rcm-kin gravity`'s torques of the tilted copy, not with the upright MTM's."""
    import shutil

    shutil.copy(urdf_dir() / "mtm.urdf", tmp_path / "mtm.urdf")
    sidecar = tmp_path / "tilted.toml"
    sidecar.write_text((urdf_dir() / "mtm.toml").read_text().replace('robot = "mtm"', 'robot = "tilted"')
                       + "\n[base]\nrpy = [0.4, -0.3, 0.2]\n")
    tilted = load_robot(sidecar)
    assert not np.allclose(tilted.gravity, [0.0, 0.0, -9.81])
    model, out = _export(capsys, tmp_path, str(sidecar), "tilted")
    np.testing.assert_allclose(model.opt.gravity, tilted.gravity, rtol=1e-9)
    for q in (np.zeros(tilted.nq), np.clip(np.full(tilted.nq, 0.3), tilted.lower, tilted.upper)):
        assert _at_pose(model, tilted, q, _gravity(capsys, str(sidecar), q)) < HELD
        assert _at_pose(model, tilted, q, _gravity(capsys, "mtm", q)) > 1e-3 * FALLS

"""The bundled URDFs: they load in Pinocchio and yourdfpy, pass model.check, match their generator,
and both parsers agree on the forward kinematics of every link."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy

from rcm_kin import RcmKinError, load_robot, robot_names
from rcm_kin.model.loading import urdf_dir
from rcm_kin.model.reduced import tree_configuration

REPO_URDF = Path(__file__).resolve().parents[2] / "urdf"


def test_bundled_robots():
    assert {"psm", "mtm", "davinci", "davinci_rcm"} <= set(robot_names())


@pytest.mark.parametrize("name", ["psm", "mtm", "davinci", "davinci_rcm"])
def test_pinocchio_check(name):
    robot = load_robot(name)
    assert robot.tree.check(robot.tree.createData())
    assert robot.reduced.check(robot.reduced.createData())
    assert robot.reduced.nq == robot.nq  # passive (mimic) joints have no q of their own


@pytest.mark.skipif(not (REPO_URDF / "generate.py").is_file(), reason="needs the source checkout")
def test_urdf_files_match_their_generator():
    result = subprocess.run([sys.executable, str(REPO_URDF / "generate.py"), "--check"], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("name", ["psm", "mtm", "davinci", "davinci_rcm"])
def test_yourdfpy_agrees_with_pinocchio(name):
    robot = load_robot(name)
    urdf = yourdfpy.URDF.load(str(urdf_dir() / f"{name}.urdf"), load_meshes=False)
    rng = np.random.default_rng(1)
    model, data = robot.tree, robot.tree.createData()
    for _ in range(20):
        q = rng.uniform(robot.lower, robot.upper)
        q_tree = tree_configuration(robot, q)
        urdf.update_cfg({model.names[j]: q_tree[model.joints[j].idx_q] for j in range(1, model.njoints)})
        pin.framesForwardKinematics(model, data, q_tree)
        for link in urdf.link_map:
            T = urdf.get_transform(frame_to=link, frame_from=urdf.base_link)
            M = data.oMf[model.getFrameId(link, pin.BODY)]
            np.testing.assert_allclose(T[:3, 3], M.translation, atol=1e-12)
            np.testing.assert_allclose(T[:3, :3], M.rotation, atol=1e-12)


def test_masses_are_the_reference_sheet():
    """CAD masses of the moving PSM bodies (3.606 kg) plus the two brass counterweights."""
    psm = load_robot("psm")
    mass = {psm.tree.names[j]: psm.tree.inertias[j].mass for j in range(1, psm.tree.njoints)}
    # the roll body carries the roller link (0.875 kg) and the main counterweight (2.63 kg)
    assert mass["roll"] == pytest.approx(0.875 + 2.63, abs=1e-12)
    # drive link plus DPM counterweight
    assert mass["pitch"] == pytest.approx(1.015 + 1.65, abs=1e-12)
    parallelogram = sum(mass[n] for n in ("lower_fork_joint", "upper_fork_joint", "support_joint", "framework_joint"))
    assert parallelogram == pytest.approx(0.305 + 0.377 + 0.071 + 1.238, abs=1e-12)
    carriage_and_instrument = sum(mass[n] for n in ("insertion", "instrument_roll", "wrist_pitch", "wrist_yaw", "jaw"))
    assert carriage_and_instrument == pytest.approx(0.600, abs=1e-12)


def test_unknown_robot_is_a_clear_error():
    with pytest.raises(RcmKinError, match="unknown robot 'ur5'; choose one of"):
        load_robot("ur5")


def test_bad_sidecar_is_a_clear_error(tmp_path):
    (tmp_path / "bad.toml").write_text('robot = "bad"\nurdf = "missing.urdf"\nactuated = ["a"]\n')
    with pytest.raises(RcmKinError, match="does not exist"):
        load_robot(str(tmp_path / "bad.toml"))


def test_wrong_passive_relation_is_caught(tmp_path):
    """A sidecar whose linear relations do not close the loops is refused, naming the residual."""
    text = (urdf_dir() / "psm.toml").read_text().replace('multiplier = -1.0', 'multiplier = -0.9', 1)
    (tmp_path / "psm.urdf").write_text((urdf_dir() / "psm.urdf").read_text())
    (tmp_path / "psm_drive.toml").write_text((urdf_dir() / "psm_drive.toml").read_text())
    (tmp_path / "psm.toml").write_text(text)
    with pytest.raises(RcmKinError, match="do not close the loops"):
        load_robot(str(tmp_path / "psm.toml"))

"""The holding effort and the torque map for any robot, checked against plain Pinocchio on the same URDF:
the MTM over its shoulder and elbow, a UR5 from example-robot-data (a description written here), the PSM's
generic map against its own roll x pitch map, a renamed PSM copy on its own CAD masses, and the refusals."""

from __future__ import annotations

import re

import numpy as np
import pinocchio as pin
import pytest

import rcm_kin as rk
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
from rcm_kin.model.loading import urdf_dir
from rcm_kin.statics.holding import default_pose, torque_map
from rcm_kin.statics.maps import gravity_map, holding_effort

UR5_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint")


def deg(lo, hi, n):
    return np.radians(np.linspace(lo, hi, n))


def plain_gravity(robot, q):
    """Pinocchio's own gravity of the open tree at actuated q (a serial arm: tree q = actuated q)."""
    return pin.computeGeneralizedGravity(robot.tree, robot.tree.createData(), np.asarray(q, float))


@pytest.fixture(scope="module")
def mtm():
    return rk.load_robot("mtm")


@pytest.fixture(scope="module")
def renamed(tmp_path_factory):
    """The bundled PSM copied, renamed `mypsm` and without its drive key."""
    folder = tmp_path_factory.mktemp("mypsm")
    (folder / "psm.urdf").write_bytes((urdf_dir() / "psm.urdf").read_bytes())
    text = (urdf_dir() / "psm.toml").read_text()
    text = re.sub(r'^robot = "psm"$', 'robot = "mypsm"', text, flags=re.M)
    text = re.sub(r"^drive = .*$", "", text, flags=re.M)
    (folder / "mypsm.toml").write_text(text)
    return folder / "mypsm.toml"


@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    """A UR5 from example-robot-data, described by a sidecar written here."""
    loaders = pytest.importorskip("example_robot_data.robots_loader")
    folder = tmp_path_factory.mktemp("ur5")
    (folder / "ur5.toml").write_text(f'robot = "ur5"\nurdf = "{loaders.UR5Loader().df_path}"\n'
                                     f"actuated = {list(UR5_JOINTS)!r}\n".replace("'", '"') + 'frames = ["tool0"]\n')
    return rk.load_robot(folder / "ur5.toml")


def test_the_mtm_map_over_shoulder_and_elbow_is_pinocchio_gravity(mtm):
    q = np.radians([20.0, 0, 0, 10.0, -5.0, 0, 0])
    tmap = torque_map(mtm, {"j2": deg(-40, 60, 11), "j3": deg(-30, 80, 12)}, q=q)
    assert tmap.dims == ("j2", "j3", "joint") and tmap.tau.shape == (11, 12, 7)
    assert tmap.model == "CAD (URDF inertias)" and tmap.effort is None and tmap.driven == ()
    worst = 0.0
    for a, j2 in enumerate(tmap.values[0]):
        for b, j3 in enumerate(tmap.values[1]):
            pose = q.copy()
            pose[1:3] = j2, j3
            worst = max(worst, np.abs(tmap.tau[a, b] - plain_gravity(mtm, pose)).max())
    assert worst < 1e-9
    assert np.abs(tmap.tau[..., 0]).max() > 0.05            # the shoulder carries a real load


def test_the_ur5_map_is_pinocchio_gravity(ur5):
    tmap = torque_map(ur5, {"shoulder_lift_joint": deg(-90, 0, 7), "elbow_joint": deg(0, 120, 9)},
                      q=[0.3, 0, 0, -0.5, 0.2, 0])
    for a, lift in enumerate(tmap.values[0]):
        for b, elbow in enumerate(tmap.values[1]):
            q = np.array([0.3, lift, elbow, -0.5, 0.2, 0])
            np.testing.assert_allclose(tmap.sel(shoulder_lift_joint=lift, elbow_joint=elbow).tau,
                                       plain_gravity(ur5, q), rtol=0, atol=1e-9)
    assert np.abs(tmap.tau[..., 1]).max() > 10.0


def test_the_psm_generic_map_is_its_roll_pitch_map():
    psm = rk.load_robot("psm")
    roll, pitch = np.linspace(-30, 30, 7), np.linspace(-20, 25, 6)
    old = gravity_map(psm, None, roll, pitch, [0.1])
    new = torque_map(psm, {"pitch": np.radians(pitch), "roll": np.radians(roll)}, q=[0, 0, 0.1, 0, 0, 0, 0])
    assert new.model == "calibration psm_drive.toml" and new.driven == ("roll", "pitch", "insertion")
    np.testing.assert_allclose(new.tau[..., :3], old.effort.tau[:, :, 0], rtol=0, atol=1e-9)
    for name in ("pwm", "voltage", "current"):
        np.testing.assert_allclose(getattr(new.effort, name), getattr(old.effort, name)[:, :, 0], rtol=0, atol=1e-9)


def test_the_map_over_the_drive_joints_is_holding_effort_pose_by_pose():
    psm = rk.load_robot("psm")
    tmap = torque_map(psm, {"insertion": [0.05, 0.12], "wrist_pitch": deg(-30, 30, 3)}, q=np.radians([10, -5, 0, 0,
                                                                                                       0, 0, 0]))
    for ins in (0.05, 0.12):
        q = np.radians([10, -5, 0, 0, 30, 0, 0])
        q[2] = ins
        one = holding_effort(psm, q)
        got = tmap.sel(insertion=ins, wrist_pitch=np.radians(30))
        np.testing.assert_allclose(got.tau, one.tau, rtol=0, atol=1e-9)
        np.testing.assert_allclose(got.drive.pwm, one.drive.pwm, rtol=0, atol=1e-9)


def test_a_renamed_copy_runs_on_its_own_cad_masses(renamed):
    copy, psm = rk.load_robot(renamed), rk.load_robot("psm")
    q = [np.radians(10), np.radians(-15), 0.08, 0, 0, 0, 0]
    effort = holding_effort(copy, q)
    assert effort.drive is None and effort.model == "CAD (URDF inertias)"
    np.testing.assert_allclose(effort.tau, rk.gravity_torque(psm, q, method="constrained"), rtol=0, atol=1e-9)
    assert abs(effort.tau[0] - holding_effort(psm, q).tau[0]) > 1.0     # the PSM's calibration is not applied
    with pytest.raises(rk.RcmKinError, match="describes robot 'psm', not 'mypsm'"):
        holding_effort(copy, q, DEFAULT_PARAMETERS)
    with pytest.raises(rk.RcmKinError, match="describes robot 'psm', not 'mypsm'"):
        torque_map(copy, {"roll": [0.0], "pitch": [0.0]}, drive=DEFAULT_PARAMETERS)


def test_the_map_is_labelled_and_writes_itself(tmp_path, mtm):
    tmap = torque_map(mtm, {"j2": [-0.2, 0.0, 0.3], "j3": [0.1, 0.4]})
    assert tmap.coords["joint"] == mtm.actuated and list(tmap.coords["j2"]) == [-0.2, 0.0, 0.3]
    assert not np.allclose(tmap.sel(j2=0.3, j3=0.1).tau, tmap.tau[0, 1])
    np.testing.assert_array_equal(tmap.sel(j2=0.3, j3=0.1).tau, tmap.tau[2, 0])
    with pytest.raises(rk.RcmKinError, match="j2 0.25 rad is not on the map's grid .nearest 0.3 rad"):
        tmap.sel(j2=0.25, j3=0.1)
    with pytest.raises(rk.RcmKinError, match="by its joints j2 and j3"):
        tmap.sel(j2=0.3)
    table = np.load(tmap.write(tmp_path / "m.npz"))
    np.testing.assert_allclose(table["tau_j1"], tmap.tau[..., 0].ravel(), rtol=0, atol=0)
    np.testing.assert_allclose(table["j2_deg"], np.degrees(np.repeat([-0.2, 0.0, 0.3], 2)))
    rows = tmap.write(tmp_path / "m.csv").read_text().splitlines()
    assert rows[0] == "j2_deg,j3_deg," + ",".join(f"tau_{j}" for j in mtm.actuated) and len(rows) == 7
    with pytest.raises(rk.RcmKinError, match="written as .csv or .npz"):
        tmap.write(tmp_path / "m.xlsx")


def test_without_counterweights_the_map_loses_their_torque(mtm):
    grid = {"j1": deg(-30, 30, 3), "j3": [0.0]}
    light = torque_map(mtm, grid, counterweights=False)
    heavy = torque_map(mtm, grid)
    mass, lever = 0.317, 0.0725                      # the J1 counterweight (robot-parameters.md)
    np.testing.assert_allclose(np.abs(heavy.tau[..., 0] - light.tau[..., 0]).max(), mass * 9.81 * lever, rtol=0.05)


def test_the_default_pose_is_zero_inside_the_limits():
    psm = rk.load_robot("psm")
    assert np.all(default_pose(psm) >= psm.lower) and np.all(default_pose(psm) <= psm.upper)


@pytest.mark.parametrize("grid, message", [
    ({"lower_fork_joint": [0.0], "roll": [0.0]}, "lower_fork_joint is a passive joint of psm"),
    ({"elbow": [0.0], "roll": [0.0]}, "psm has no joint 'elbow'"),
    ({"roll": [0.0]}, "must name two actuated joints"),
    ({"roll": [], "pitch": [0.0]}, "non-empty list of finite numbers"),
    ({"roll": [0.0, np.nan], "pitch": [0.0]}, "non-empty list of finite numbers"),
    ({"roll": ["a"], "pitch": [0.0]}, "must be numbers"),
    ({"roll": [-1.0, 0.0], "pitch": [0.0]}, r"outside its joint limits \[-30, 30\] deg"),
    ({"roll": np.zeros(2000), "pitch": np.zeros(2000)}, "4,000,000 poses is beyond"),
])
def test_bad_grids_are_refused_in_one_line(grid, message):
    with pytest.raises(rk.RcmKinError, match=message) as raised:
        torque_map(rk.load_robot("psm"), grid)
    assert "\n" not in str(raised.value)


def test_a_urdf_without_masses_is_refused(tmp_path):
    text = re.sub(r"<inertial>.*?</inertial>", "", (urdf_dir() / "mtm.urdf").read_text(), flags=re.S)
    (tmp_path / "bare.urdf").write_text(text)
    (tmp_path / "bare.toml").write_text((urdf_dir() / "mtm.toml").read_text().replace('"mtm.urdf"', '"bare.urdf"')
                                        .replace('robot = "mtm"', 'robot = "bare"'))
    bare = rk.load_robot(tmp_path / "bare.toml")
    for call in (lambda: torque_map(bare, {"j2": [0.0], "j3": [0.0]}), lambda: holding_effort(bare, np.zeros(7))):
        with pytest.raises(rk.RcmKinError, match="needs masses: links .* have no <inertial>"):
            call()

"""Robots no code names, loaded as their users have them: the dVRK Classic PSM generated from its
published modified-DH table (continuous mimic joints, package:// meshes, no inertials), a UR5 from
example-robot-data as a URDF alone, a renamed and re-massed PSM copy, a tilted base; every parse
problem one error line. Each is checked against something independent: the DH table's own forward
kinematics, plain Pinocchio calls on the same URDF, finite differences of the potential energy."""

from __future__ import annotations

import json
import re
import tomllib
import warnings
from pathlib import Path

import example_robot_data
import numpy as np
import pinocchio as pin
import pytest
from oracles.dvrk_classic import ACTUATED, SHAFT, TOOL_TIP, WRIST, dh_frames, links, urdf_text, write_dvrk_psm

from rcm_kin import RcmKinError, load_robot
from rcm_kin.cli import main
from rcm_kin.errors import RcmKinWarning
from rcm_kin.kinematics.rcm_scatter import rcm_scatter
from rcm_kin.model import gravity_batch, gravity_torque, require_masses
from rcm_kin.model.loading import urdf_dir

UR5 = Path(example_robot_data.getModelPath("ur_description/urdf/ur5_robot.urdf")) / "ur_description/urdf/ur5_robot.urdf"


def poses(robot, n, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(robot.lower, robot.upper, size=(n, robot.nq))


def placement(robot, q, frame) -> np.ndarray:
    data = robot.reduced.createData()
    pin.framesForwardKinematics(robot.reduced, data, robot.to_reduced(q))
    return data.oMf[robot.reduced.getFrameId(frame)].homogeneous


@pytest.fixture(scope="module")
def dvrk(tmp_path_factory):
    return write_dvrk_psm(tmp_path_factory.mktemp("dvrk"))


# --- the dVRK Classic PSM ------------------------------------------------------------------------

def test_dvrk_urdf_alone_gets_the_defaults(dvrk):
    robot = load_robot(dvrk.urdf)
    assert robot.name == "dvrk_psm"
    assert set(robot.actuated) == set(ACTUATED)
    assert list(robot.actuated) == [n for n in robot.tree.names[1:] if n in ACTUATED]      # depth-first
    relations = {p.joint: (p.follows, p.multiplier, p.offset) for p in robot.description.passive}
    assert relations == {"outer_pitch_1": ("outer_pitch", -1.0, 0.0), "outer_pitch_2": ("outer_pitch", 1.0, 0.0),
                         "jaw_2": ("jaw", -1.0, 0.0)}                 # the mimic of a mimic resolved
    assert set(robot.description.frames) == {TOOL_TIP, "jaw_1_link", "jaw_2_link", "remote_center_link"}
    assert robot.description.rcm is None and robot.description.drive is None and not robot.constraints
    assert robot.tree.nq == robot.tree.njoints - 1 and robot.reduced.nq == robot.nq == 7    # all 1-DOF
    for name in ("outer_pitch_1", "outer_pitch_2", "jaw_2"):                                # were continuous
        i = robot.tree.joints[robot.tree.getJointId(name)].idx_q
        assert (robot.tree.lowerPositionLimit[i], robot.tree.upperPositionLimit[i]) == (-np.pi, np.pi)
    jaw_2 = robot.tree.joints[robot.tree.getJointId("jaw_2")].idx_v
    assert robot.tree.effortLimit[jaw_2] == np.inf and robot.tree.velocityLimit[jaw_2] == np.inf


def test_dvrk_forward_kinematics_is_the_dh_table(dvrk):
    for robot in (load_robot(dvrk.urdf), load_robot(dvrk.sidecar)):
        for q in poses(robot, 40, seed=3):
            reference = dh_frames([q[robot.actuated.index(n)] for n in ACTUATED[:6]])
            for frame in (SHAFT, WRIST, TOOL_TIP):
                np.testing.assert_allclose(placement(robot, q, frame), reference[frame], atol=1e-9, rtol=0)


def test_dvrk_the_rcm_stays_fixed(dvrk):
    robot = load_robot(dvrk.sidecar)
    assert robot.description.rcm.joints == ("outer_yaw", "outer_pitch")
    scatter = rcm_scatter(robot, robot.description.rcm.shaft_frame, robot.description.rcm.joints)
    assert scatter.max_distance < 1e-9 and np.linalg.norm(scatter.point) < 1e-9
    for q in poses(robot, 50, seed=4):                   # every pose: the shaft line through the base origin
        T = placement(robot, q, SHAFT)
        p, u = T[:3, 3], T[:3, 2]
        assert np.linalg.norm(p - (p @ u) * u) < 1e-9


def test_dvrk_without_inertials_refuses_gravity(dvrk, capsys):
    robot = load_robot(dvrk.urdf)
    assert robot.massless_links[:3] == ("outer_yaw_link", "outer_pitch_back_link", "outer_pitch_bottom_link")
    message = re.escape("gravity needs masses: links outer_yaw_link, outer_pitch_back_link, ")
    with pytest.raises(RcmKinError, match=message + r".*\(\d+ links\) of .*dvrk_psm.urdf have no <inertial>"):
        gravity_torque(robot, np.zeros(robot.nq))
    with pytest.raises(RcmKinError, match="gravity needs masses"):
        gravity_batch(robot, poses(robot, 3))
    with pytest.raises(RcmKinError, match="torque map needs masses"):
        require_masses(robot, "torque map")
    assert gravity_torque(robot, np.zeros(robot.nq), allow_massless=True).tolist() == [0.0] * 7
    capsys.readouterr()
    assert main(["gravity", str(dvrk.urdf)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: the holding torque needs masses: links outer_yaw_link")


def test_some_links_without_inertials_warn_once(tmp_path):
    text = urdf_text("partly", inertials=True)
    text = re.sub(r'(<link name="jaw_2_link">.*?)<inertial>.*?</inertial>', r"\1", text)
    (tmp_path / "partly.urdf").write_text(text)
    robot = load_robot(tmp_path / "partly.urdf")
    assert robot.massless_links == ("jaw_2_link",)
    with pytest.warns(RcmKinWarning, match="gravity assumes zero mass for links jaw_2_link of .*partly.urdf"):
        tau = gravity_torque(robot, np.zeros(robot.nq))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_allclose(gravity_batch(robot, np.zeros((1, robot.nq)))[0], tau, atol=1e-12)
    plain = pin.buildModelFromUrdf(str(tmp_path / "partly.urdf"))   # the masses that are there, by Pinocchio
    assert np.isclose(sum(i.mass for i in robot.tree.inertias), sum(i.mass for i in plain.inertias))


@pytest.mark.parametrize("name", ["psm", "mtm"])
def test_bundled_robots_have_no_massless_links(name):
    robot = load_robot(name)
    assert robot.massless_links == ()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gravity_torque(robot, np.zeros(robot.nq))
        gravity_batch(load_robot(name, counterweights=False), np.zeros((1, robot.nq)))


@pytest.mark.parametrize("name", ["davinci", "davinci_rcm"])
def test_kinematic_bundled_robots_refuse_gravity(name):
    """The da Vinci models are kinematic (no source gives masses): gravity says so."""
    robot = load_robot(name)
    with pytest.raises(RcmKinError, match="gravity needs masses"):
        gravity_torque(robot, np.zeros(robot.nq))


def test_dvrk_meshes_resolve_through_the_package_folder(dvrk):
    from rcm_kin.model.geometry import visual_geometry

    robot = load_robot(dvrk.urdf)
    geometry = visual_geometry(robot, dvrk.packages)
    assert geometry.ngeoms == len(links())                      # one box per link
    with pytest.raises(RcmKinError, match="package 'dvrk_model'"):
        visual_geometry(robot, {})


# --- mimic tags and sidecar [[passive]] entries ---------------------------------------------------

def _sidecar(folder: Path, extra: str, robot: str = "dvrk_psm") -> Path:
    return write_dvrk_psm(folder, robot=robot, extra_sidecar=extra).sidecar


def test_a_sidecar_passive_entry_that_agrees_with_the_mimic_tag(tmp_path):
    robot = load_robot(_sidecar(tmp_path, '\n[[passive]]\njoint = "outer_pitch_2"\nfollows = "outer_pitch"\n'))
    relations = {p.joint: (p.follows, p.multiplier) for p in robot.description.passive}
    assert relations["outer_pitch_2"] == ("outer_pitch", 1.0) and len(relations) == 3


ALL = '"outer_yaw", "outer_pitch", "outer_insertion", "outer_roll", "outer_wrist_pitch", "outer_wrist_yaw", "jaw"'


@pytest.mark.parametrize("extra, message", [
    ('[[passive]]\njoint = "outer_pitch_2"\nfollows = "outer_pitch"\nmultiplier = -1.0\n',
     r"\[\[passive\]\] 'outer_pitch_2' = -1 \* outer_pitch \+ 0 disagrees with the URDF's <mimic> \(1 \* outer_pitch"),
    (f'actuated = [{ALL}, "outer_pitch_1"]\n', "joint 'outer_pitch_1' is a <mimic> of 'outer_pitch' in the URDF"),
    ("actuated = [" + ALL.replace(', "outer_pitch"', "") + "]\n",
     "passive joint 'outer_pitch_1' follows 'outer_pitch', which is not actuated"),
    (f'actuated = [{ALL}, "no_such_joint"]\n', "joint 'no_such_joint' is not in the URDF"),
    ('[base]\nrpy = [0.0, 0.1, 0.0]\ngravity = [0.0, 0.0, -9.81]\n', r"\[base\]: give 'rpy' or 'gravity', not both"),
    ('[base]\ntilt = 0.1\n', r"\[base\]: unknown keys \['tilt'\]"),
    ('[rcm]\nshaft_frame = "tool_main_link"\njoints = ["outer_yaw", "outer_pitch_1"]\n',
     r"\[rcm\] 'joints' must name two actuated joints"),
])
def test_sidecar_conflicts_are_one_line(tmp_path, extra, message):
    urdf = write_dvrk_psm(tmp_path, sidecar=False).urdf
    toml = tmp_path / "conflict.toml"
    toml.write_text(f'urdf = "{urdf.name}"\n' + extra)
    with pytest.raises(RcmKinError, match=message) as caught:
        load_robot(toml)
    assert "\n" not in str(caught.value) and re.search(r"(conflict\.toml|dvrk_psm\.urdf): ", str(caught.value))


def test_a_sidecar_may_give_only_its_urdf(tmp_path):
    urdf = write_dvrk_psm(tmp_path, sidecar=False).urdf
    (tmp_path / "minimal.toml").write_text(f'urdf = "{urdf.name}"\n')
    robot, alone = load_robot(tmp_path / "minimal.toml"), load_robot(urdf)
    assert (robot.name, robot.actuated, robot.description.frames) == (alone.name, alone.actuated,
                                                                     alone.description.frames)


# --- parse problems: one line naming the file ------------------------------------------------------

JOINT = '<joint name="j" type="{kind}"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>{more}</joint>'
LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'


def _robot(*joints: str, links=("a", "b")) -> str:
    return '<robot name="tiny">' + "".join(f'<link name="{n}"/>' for n in links) + "".join(joints) + "</robot>"


@pytest.mark.parametrize("text, message", [
    ("<robot name='x'><link", "not valid XML"),
    ("<sdf version='1.6'/>", r"not a URDF \(the root element is <sdf>"),
    (_robot(JOINT.format(kind="floating", more="")), "joint 'j' is floating: rcm-kin models fixed-base robots"),
    (_robot(JOINT.format(kind="planar", more="")), "joint 'j' is planar"),
    (_robot(JOINT.format(kind="spherical", more="")), "joint 'j' is spherical"),
    (_robot(JOINT.format(kind="revolute", more="")), "Pinocchio cannot read the URDF .*does not specify limits"),
    (_robot(JOINT.format(kind="revolute", more=LIMIT + '<mimic joint="k"/>')), "'j' mimics 'k', which is not in"),
    (_robot(JOINT.format(kind="revolute", more=LIMIT + '<mimic joint="j"/>')), "mimic joints form a cycle: j -> j"),
    (_robot(JOINT.format(kind="revolute", more=LIMIT + '<mimic joint="j" multiplier="two"/>')),
     "'multiplier' must be a number"),
    (_robot(JOINT.format(kind="fixed", more="")), "the URDF has no joint to actuate"),
])
def test_a_bad_urdf_is_one_error_line(tmp_path, capfd, text, message):
    path = tmp_path / "bad.urdf"
    path.write_text(text)
    with pytest.raises(RcmKinError, match=message) as caught:
        load_robot(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)
    assert capfd.readouterr().err == ""          # urdfdom's own messages are caught, not printed


def test_missing_files_are_one_line(tmp_path):
    with pytest.raises(RcmKinError, match="no URDF at"):
        load_robot(tmp_path / "none.urdf")
    with pytest.raises(RcmKinError, match="or give the path of a sidecar .toml or a .urdf"):
        load_robot("no_such_robot")


def test_a_continuous_joint_keeps_its_effort_and_velocity(tmp_path):
    path = tmp_path / "c.urdf"
    path.write_text(_robot(JOINT.format(kind="continuous", more='<limit effort="3" velocity="4"/>')))
    robot = load_robot(path)
    assert robot.nq == 1 and robot.tree.nq == 1 and robot.joint_kind("j") == "revolute"
    assert (robot.lower[0], robot.upper[0]) == (-np.pi, np.pi)
    assert (robot.tree.effortLimit[0], robot.tree.velocityLimit[0]) == (3.0, 4.0)
    plain = pin.buildModelFromUrdf(str(path))                  # Pinocchio's (cos, sin) joint: same motion
    q = 0.7
    data, plain_data = robot.tree.createData(), plain.createData()
    pin.forwardKinematics(robot.tree, data, np.array([q]))
    pin.forwardKinematics(plain, plain_data, np.array([np.cos(q), np.sin(q)]))
    np.testing.assert_allclose(data.oMi[1].homogeneous, plain_data.oMi[1].homogeneous, atol=1e-15)


def test_a_urdf_alone_is_cached_by_content(tmp_path):
    path = tmp_path / "c.urdf"
    path.write_text(_robot(JOINT.format(kind="revolute", more=LIMIT)))
    first = load_robot(path)
    assert load_robot(path) is first
    path.write_text(_robot(JOINT.format(kind="prismatic", more=LIMIT)))
    assert load_robot(path) is not first and load_robot(path).joint_kind("j") == "prismatic"


# --- the UR5 of example-robot-data, a URDF alone ---------------------------------------------------

def test_ur5_urdf_alone_equals_plain_pinocchio():
    robot = load_robot(UR5)
    plain = pin.buildModelFromUrdf(str(UR5))
    data = plain.createData()
    assert list(robot.actuated) == list(plain.names[1:]) and robot.nq == plain.nq == 6
    assert robot.massless_links == ()
    for q in poses(robot, 20, seed=5):
        pin.framesForwardKinematics(plain, data, q)
        for frame in robot.description.frames + ("wrist_3_link",):
            np.testing.assert_allclose(placement(robot, q, frame), data.oMf[plain.getFrameId(frame)].homogeneous,
                                       atol=1e-9, rtol=0)
        g = pin.computeGeneralizedGravity(plain, data, q)
        np.testing.assert_allclose(gravity_torque(robot, q), g, atol=1e-9, rtol=0)
        np.testing.assert_allclose(gravity_batch(robot, q[None])[0], g, atol=1e-9, rtol=0)


# --- PSM copies: renamed and re-massed, tilted ---------------------------------------------------------

def _psm_copy(folder: Path, robot: str, urdf: str | None = None, extra: str = "") -> Path:
    text = (urdf_dir() / "psm.toml").read_text()
    text = re.sub(r'^robot = "psm"', f'robot = "{robot}"', text, flags=re.M)
    text = re.sub(r'^drive = .*$', "", text, flags=re.M)           # a copy without the PSM's calibration
    (folder / "psm.urdf").write_text(urdf or (urdf_dir() / "psm.urdf").read_text())
    path = folder / f"{robot}.toml"
    path.write_text(re.sub(r"^\[rcm\]$", extra.replace("\\", "\\\\") + "\n[rcm]", text, count=1, flags=re.M))
    return path


def _potential_gravity(urdf: Path, sidecar: Path, q, robot, h=1e-6) -> np.ndarray:
    """dV/dq by central differences, V from plain Pinocchio on the open tree of the same URDF with
    the passive joints set from the sidecar's relations as the test reads them."""
    tree = pin.buildModelFromUrdf(str(urdf))
    data = tree.createData()
    relations = tomllib.loads(sidecar.read_text())["passive"]
    names = list(robot.actuated)

    def potential(qa):
        qt = np.zeros(tree.nq)
        for n, v in zip(names, qa):
            qt[tree.joints[tree.getJointId(n)].idx_q] = v
        for r in relations:
            qt[tree.joints[tree.getJointId(r["joint"])].idx_q] = r["multiplier"] * qa[names.index(r["follows"])]
        return pin.computePotentialEnergy(tree, data, qt)

    eye = np.eye(len(q))
    return np.array([(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in eye])


def test_renamed_remassed_psm_runs_on_its_own_masses(tmp_path):
    text = (urdf_dir() / "psm.urdf").read_text()
    remassed = re.sub(r'<mass value="([0-9.eE+-]+)"', lambda m: f'<mass value="{1.7 * float(m.group(1))!r}"', text)
    sidecar = _psm_copy(tmp_path, "mypsm", remassed)
    robot, psm = load_robot(sidecar), load_robot("psm")
    assert robot.name == "mypsm" and robot.description.drive is None and robot.massless_links == ()
    for q in poses(robot, 5, seed=6):
        tau = gravity_torque(robot, q)
        np.testing.assert_allclose(tau, _potential_gravity(tmp_path / "psm.urdf", sidecar, q, robot), atol=1e-6)
        np.testing.assert_allclose(gravity_batch(robot, q[None])[0], tau, atol=1e-12)
        assert np.max(np.abs(tau - gravity_torque(psm, q))) > 1e-3       # its own physics, not the PSM's


def test_tilted_base_gravity_is_pinocchio_with_gravity_set_by_hand(tmp_path, capsys):
    rpy = np.array([0.3, -0.2, 0.5])
    sidecar = _psm_copy(tmp_path, "tilted", extra=f"[base]\nrpy = {rpy.tolist()}\n")
    robot = load_robot(sidecar)
    R = pin.rpy.rpyToMatrix(*rpy)                            # base orientation in the world
    g_base = R.T @ np.array([0.0, 0.0, -9.81])
    np.testing.assert_allclose(robot.gravity, g_base, atol=1e-15)
    np.testing.assert_allclose(robot.description.base_rpy, rpy)
    capsys.readouterr()
    assert main(["info", str(sidecar), "--json"]) == 0
    np.testing.assert_allclose(json.loads(capsys.readouterr().out)["gravity"], g_base, atol=1e-15)
    model = pin.Model(load_robot("psm").reduced)
    model.gravity.linear = g_base
    data = model.createData()
    for q in poses(robot, 10, seed=7):
        g = robot.from_reduced(pin.computeGeneralizedGravity(model, data, robot.to_reduced(q)))
        np.testing.assert_allclose(gravity_torque(robot, q), g, atol=1e-9, rtol=0)
        np.testing.assert_allclose(gravity_batch(robot, q[None])[0], g, atol=1e-9, rtol=0)
        np.testing.assert_allclose(gravity_torque(robot, q, method="constrained"), g, atol=1e-9, rtol=0)


def test_a_yaw_alone_and_a_gravity_vector(tmp_path):
    psm = load_robot("psm")
    (tmp_path / "yaw").mkdir()
    (tmp_path / "vector").mkdir()
    yawed = load_robot(_psm_copy(tmp_path / "yaw", "yawed", extra="[base]\nrpy = [0.0, 0.0, 1.1]\n"))
    vector = load_robot(_psm_copy(tmp_path / "vector", "vector", extra="[base]\ngravity = [0.0, 9.81, 0.0]\n"))
    np.testing.assert_allclose(vector.gravity, [0.0, 9.81, 0.0])
    model = pin.Model(psm.reduced)
    model.gravity.linear = np.array([0.0, 9.81, 0.0])
    for q in poses(psm, 10, seed=8):
        np.testing.assert_allclose(gravity_torque(yawed, q), gravity_torque(psm, q), atol=1e-12, rtol=0)
        g = psm.from_reduced(pin.computeGeneralizedGravity(model, model.createData(), psm.to_reduced(q)))
        np.testing.assert_allclose(gravity_torque(vector, q), g, atol=1e-9, rtol=0)

"""inverse_kinematics for any description: the closed-form RCM IK from ``[rcm]`` (bundled PSM against
its twin shaft_tip_ik, the da Vinci chains, a dVRK Classic PSM generated from its published
modified-DH table) and damped least squares (a UR5 from example-robot-data), checked with plain
Pinocchio forward kinematics on the same URDF and an independent DH product; bad input in one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.ik import inverse_kinematics
from rcm_kin.kinematics.psm_ik import shaft_tip_ik
from rcm_kin.kinematics.rcm_ik import pivot_angles, rcm_chain, rcm_ik
from rcm_kin.kinematics.rcm_scatter import rcm_scatter
from rcm_kin.model import load_robot

# dVRK Classic PSM (large needle driver), modified DH (Craig): alpha, a, theta offset, d offset, type;
# the published table of the dVRK's psm kinematics (l_RCC = 0.4318 m, l_tool = 0.4162 m, wrist 9.1 mm)
DVRK_PSM_DH = [("outer_yaw", np.pi / 2, 0.0, np.pi / 2, 0.0, "revolute"),
               ("outer_pitch", -np.pi / 2, 0.0, -np.pi / 2, 0.0, "revolute"),
               ("outer_insertion", np.pi / 2, 0.0, 0.0, -0.4318, "prismatic"),
               ("outer_roll", 0.0, 0.0, 0.0, 0.4162, "revolute"),
               ("outer_wrist_pitch", -np.pi / 2, 0.0, -np.pi / 2, 0.0, "revolute"),
               ("outer_wrist_yaw", -np.pi / 2, 0.0091, -np.pi / 2, 0.0, "revolute")]
# joint ranges of the test robot (rounded dVRK-like ranges; the IK only needs some)
DVRK_LIMITS = [(-1.5, 1.5), (-0.8, 0.8), (0.0, 0.24), (-4.5, 4.5), (-1.5, 1.5), (-1.5, 1.5)]


def _dh(alpha, a, theta, d) -> np.ndarray:
    """Craig's modified DH: RotX(alpha) TransX(a) RotZ(theta) TransZ(d), as a 4 x 4 matrix."""
    ca, sa, ct, st = np.cos(alpha), np.sin(alpha), np.cos(theta), np.sin(theta)
    return np.array([[ct, -st, 0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d], [0, 0, 0, 1]])


def dvrk_dh_fk(q) -> list[np.ndarray]:
    """Frames 1..6 of the DH table at q (independent of the URDF and of Pinocchio)."""
    T, frames = np.eye(4), []
    for (_, alpha, a, theta0, d0, kind), value in zip(DVRK_PSM_DH, q):
        T = T @ (_dh(alpha, a, theta0 + value, d0) if kind == "revolute" else _dh(alpha, a, theta0, d0 + value))
        frames.append(T)
    return frames


def write_dvrk_psm(folder: Path) -> Path:
    """A URDF of the DH table (each joint's fixed part as its origin) and a sidecar with [rcm]."""
    links = ["base"] + [f"link{i + 1}" for i in range(len(DVRK_PSM_DH))]
    parts = ['<robot name="dvrk_classic_psm">'] + [f'<link name="{n}"/>' for n in links]
    for i, ((name, alpha, a, theta0, d0, kind), (lo, hi)) in enumerate(zip(DVRK_PSM_DH, DVRK_LIMITS)):
        M = pin.SE3(_dh(alpha, a, theta0, d0))
        xyz, rpy = M.translation, pin.rpy.matrixToRpy(M.rotation)
        parts.append(f'<joint name="{name}" type="{kind}"><parent link="{links[i]}"/><child link="{links[i + 1]}"/>'
                     f'<origin xyz="{" ".join(repr(float(x)) for x in xyz)}" '
                     f'rpy="{" ".join(repr(float(x)) for x in rpy)}"/><axis xyz="0 0 1"/>'
                     f'<limit lower="{lo}" upper="{hi}" effort="1" velocity="1"/></joint>')
    (folder / "dvrk_classic_psm.urdf").write_text("\n".join(parts + ["</robot>"]))
    names = ", ".join(f'"{row[0]}"' for row in DVRK_PSM_DH)
    sidecar = folder / "dvrk_classic_psm.toml"
    sidecar.write_text(f'robot = "dvrk_classic_psm"\nurdf = "dvrk_classic_psm.urdf"\nactuated = [{names}]\n'
                       'frames = ["link4", "link6"]\n\n[rcm]\nshaft_frame = "link4"\n'
                       'joints = ["outer_yaw", "outer_pitch"]\n')
    return sidecar


UR5_URDF = Path(pin.__file__).parents[4] / "share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf"
UR5_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint"]


@pytest.fixture(scope="module")
def ur5(tmp_path_factory) -> Path:
    if not UR5_URDF.is_file():
        pytest.skip("example-robot-data's UR5 URDF is not installed")
    sidecar = tmp_path_factory.mktemp("ur5") / "ur5.toml"
    sidecar.write_text(f'robot = "ur5"\nurdf = "{UR5_URDF}"\nactuated = [{", ".join(map(repr, UR5_JOINTS))}]\n'
                       .replace("'", '"'))
    return sidecar


@pytest.fixture(scope="module")
def dvrk(tmp_path_factory) -> Path:
    return write_dvrk_psm(tmp_path_factory.mktemp("dvrk"))


def random_arm_poses(robot, joints, n, seed, margin=0.02):
    rng = np.random.default_rng(seed)
    idx = [robot.actuated.index(j) for j in joints]
    lo, hi = robot.lower[idx], robot.upper[idx]
    for _ in range(n):
        q = np.zeros(robot.nq)
        q[idx] = rng.uniform(lo + margin * (hi - lo), hi - margin * (hi - lo))
        yield q


def shaft_line_miss(placement: pin.SE3, point: np.ndarray) -> float:
    """Distance (m) of ``point`` from the z axis of ``placement``."""
    return float(np.linalg.norm(np.cross(point - placement.translation, placement.rotation[:, 2])))


# --- the closed form on the bundled robots ----------------------------------------------------------------
def test_generic_closed_form_is_the_psm_twin(psm):
    """rcm_ik reads only [rcm]; shaft_tip_ik is the PSM's own derivation: they agree to 1e-9."""
    for q in random_arm_poses(psm, ("roll", "pitch", "insertion"), 300, 1):
        target = frame_placement(psm, q, "shaft_tip").translation
        q_generic, chain = rcm_ik(psm, target)
        np.testing.assert_allclose(q_generic[:3], shaft_tip_ik(psm, target), rtol=0, atol=1e-9)
        np.testing.assert_allclose(q_generic[:3], q[:3], rtol=0, atol=1e-9)   # unique within the limits
        reached = frame_placement(psm, q_generic, "shaft_tip")
        assert np.linalg.norm(reached.translation - target) < 1e-9
        assert shaft_line_miss(reached, np.zeros(3)) < 1e-12                # the RCM is the base origin
    assert chain.joints == ("roll", "pitch", "insertion") and np.linalg.norm(chain.rcm) < 1e-12


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_davinci_rcm_closed_form_round_trip(seed):
    """The reduced da Vinci chain, setup joints at a random pose (held): FK(IK(p)) = p, the shaft line
    through the RCM that rcm_scatter measures independently over a grid of the pivots."""
    robot = load_robot("davinci_rcm")
    rng = np.random.default_rng(seed)
    setup = np.zeros(robot.nq)
    setup[:6] = rng.uniform(-0.5, 0.5, 6)
    setup[0] = rng.uniform(-0.1, 0.1)
    scatter = rcm_scatter(robot, "instrument_slide_link", ("hand_roll", "hand_pitch"), "rcm_base_link", q=setup)
    base = frame_placement(robot, setup, "rcm_base_link")
    rcm = base.rotation @ scatter.point + base.translation
    for q in random_arm_poses(robot, ("hand_roll", "hand_pitch", "instrument_slide"), 40, seed):
        q[:6] = setup[:6]
        target = frame_placement(robot, q, "instrument_slide_link").translation
        solution = inverse_kinematics(robot, target, q0=setup)
        assert solution.method == "closed-form RCM" and solution.frame == "instrument_slide_link"
        assert solution.joints == ("hand_roll", "hand_pitch", "instrument_slide")
        reached = frame_placement(robot, solution.q_full, solution.frame)
        assert np.linalg.norm(reached.translation - target) < 1e-9 and solution.position_error < 1e-9
        np.testing.assert_array_equal(solution.q_full[:6], setup[:6])     # the setup joints are held
        assert shaft_line_miss(reached, rcm) < 1e-9
        robot.check_limits(solution.q_full, tol=1e-12)


def test_davinci_mimic_chain_is_finished_numerically():
    """The thesis's mimic parallelogram is not an exact RCM (lines scatter by ~12 mm): the closed form
    is only a start; the answer (damped least squares, same three joints) still lands within 1e-9."""
    robot = load_robot("davinci")
    assert rcm_chain(robot).line_error > 1e-3
    for q in random_arm_poses(robot, ("hand_roll", "hand_pitch", "instrument_slide"), 15, 3, margin=0.1):
        target = frame_placement(robot, q, "instrument_slide_link").translation
        solution = inverse_kinematics(robot, target)
        assert solution.method == "damped least squares"
        assert solution.joints == ("hand_roll", "hand_pitch", "instrument_slide")
        assert np.linalg.norm(frame_placement(robot, solution.q_full, solution.frame).translation - target) < 1e-9
        robot.check_limits(solution.q_full, tol=1e-12)


# --- a dVRK Classic PSM generated from its DH table --------------------------------------------------------
def test_dvrk_dh_psm_closed_form(dvrk):
    robot = load_robot(dvrk)
    plain = pin.buildModelFromUrdf(str(robot.description.urdf))
    plain_data = plain.createData()
    fid = plain.getFrameId("link4")
    chain = rcm_chain(robot)
    assert chain.joints == ("outer_yaw", "outer_pitch", "outer_insertion")
    assert np.linalg.norm(chain.rcm) < 1e-12 and abs(chain.offset - (0.4162 - 0.4318)) < 1e-12
    for q in random_arm_poses(robot, chain.joints, 200, 5):
        target = dvrk_dh_fk(q)[3][:3, 3]                                  # the DH product, not the URDF
        solution = inverse_kinematics(robot, target)
        assert solution.method == "closed-form RCM"
        pin.framesForwardKinematics(plain, plain_data, solution.q_full)  # plain Pinocchio, URDF order = DH order
        reached = plain_data.oMf[fid]
        assert np.linalg.norm(reached.translation - target) < 1e-9
        assert shaft_line_miss(reached, np.zeros(3)) < 1e-12             # pivots about the DH origin
        np.testing.assert_allclose(solution.q, q[:3], rtol=0, atol=1e-9)


def test_dvrk_dh_psm_cli_by_path(dvrk, capsys):
    target = dvrk_dh_fk([0.3, -0.2, 0.15, 0, 0, 0])[3][:3, 3]
    assert main(["ik", str(dvrk), *map(repr, target.tolist()), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "closed-form RCM" and out["frame"] == "link4"
    np.testing.assert_allclose(out["q"], [0.3, -0.2, 0.15], atol=1e-9)
    assert set(out) == {"q", "position_error", "frame", "joints", "method"}


def test_pivot_angles_gives_both_solutions(dvrk):
    """Paden-Kahan subproblem 2 returns both pivot pairs of a shaft direction, each checked by rotation matrices."""
    robot = load_robot(dvrk)
    chain = rcm_chain(robot)
    u = dvrk_dh_fk([0.4, 0.3, 0.2, 0, 0, 0])[3][:3, 3]
    u = u / np.linalg.norm(u)
    pairs = pivot_angles(chain.axes[chain.outer], chain.axes[1 - chain.outer], chain.shaft, u)
    assert len(pairs) == 2
    for th_outer, th_inner in pairs:   # each pair turns the rest shaft onto u (independent rotations)
        R = pin.exp3(chain.axes[chain.outer] * th_outer) @ pin.exp3(chain.axes[1 - chain.outer] * th_inner)
        np.testing.assert_allclose(R @ chain.shaft, u, atol=1e-12)


# --- damped least squares on a UR5 -------------------------------------------------------------------------
def test_ur5_numeric_ik_matches_plain_pinocchio(ur5):
    robot = load_robot(ur5)
    plain = pin.buildModelFromUrdf(str(UR5_URDF))
    plain_data = plain.createData()
    fid = plain.getFrameId("tool0")
    order = [robot.actuated.index(plain.names[j]) for j in range(1, plain.njoints)]
    rng = np.random.default_rng(7)
    for _ in range(8):
        q = rng.uniform(-2.5, 2.5, 6)
        pin.framesForwardKinematics(plain, plain_data, q[order])
        target = plain_data.oMf[fid].copy()
        solution = inverse_kinematics(robot, target.translation, frame="tool0")
        # wrist 3 turns about a line through tool0: it moves the orientation only
        assert solution.method == "damped least squares" and solution.joints == tuple(UR5_JOINTS[:5])
        pin.framesForwardKinematics(plain, plain_data, solution.q_full[order])
        assert np.linalg.norm(plain_data.oMf[fid].translation - target.translation) < 1e-9
        pose = inverse_kinematics(robot, target.translation, pin.rpy.matrixToRpy(target.rotation), frame="tool0")
        assert pose.joints == tuple(UR5_JOINTS) and pose.orientation_error < 1e-9
        pin.framesForwardKinematics(plain, plain_data, pose.q_full[order])
        assert np.linalg.norm(plain_data.oMf[fid].translation - target.translation) < 1e-9
        assert np.linalg.norm(pin.log3(plain_data.oMf[fid].rotation.T @ target.rotation)) < 1e-9


def test_ur5_cli_default_frame(ur5, capsys):
    robot = load_robot(ur5)
    q = np.array([0.3, -1.0, 1.2, -0.5, 0.7, 0.2])
    last = robot.reduced.frames[len(robot.reduced.frames) - 1].name
    target = frame_placement(robot, q, last).translation
    assert main(["ik", str(ur5), *map(repr, target.tolist()), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["frame"] == last and out["method"] == "damped least squares" and out["position_error"] < 1e-9


# --- bad input: one line each ------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, message", [
    (["ik", "psm", "0.01", "nan", "-0.06"], "must be finite numbers"),
    (["ik", "psm", "0", "0", "0"], "the remote centre of motion itself"),
    (["ik", "psm", "0", "0", "0.05"], "on the far side of the remote centre"),
    (["ik", "psm", "0.1", "0", "-0.05"], "out of reach: it needs pitch -63.43 deg outside [-30.0, 30.0] deg"),
    (["ik", "davinci_rcm", "2", "0", "1", "--frame", "no_such_link"], "has no frame 'no_such_link' (--frame)"),
    (["ik", "mtm", "0.2", "0", "-0.2", "--frame", "wrist_center", "--rpy", "0", "0", "0"], "(6 needed)"),
])
def test_bad_ik_input_is_one_line(capsys, argv, message):
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.startswith("error: ") and captured.err.count("\n") == 1
    assert message in captured.err


def test_library_bad_input(psm, mtm):
    for call, parameter in [(lambda: inverse_kinematics(psm, [0.0, np.nan, -0.05]), "position"),
                            (lambda: inverse_kinematics(mtm, [0.2, 0.0, -0.2], frame="nope"), "frame"),
                            (lambda: inverse_kinematics(psm, [0.0, 0.0, 0.0]), "position")]:
        with pytest.raises(RcmKinError) as caught:
            call()
        assert caught.value.parameter == parameter and "\n" not in str(caught.value)


def test_rcm_without_a_sliding_insertion_is_refused(ur5, tmp_path):
    """[rcm] on an arm with no prismatic joint along the shaft: a one-line description error."""
    sidecar = tmp_path / "ur5_rcm.toml"
    sidecar.write_text(ur5.read_text() + '[rcm]\nshaft_frame = "tool0"\njoints = ["wrist_1_joint", "wrist_2_joint"]\n')
    with pytest.raises(RcmKinError, match="needs one actuated prismatic joint sliding tool0"):
        inverse_kinematics(load_robot(sidecar), [0.3, 0.1, 0.4])

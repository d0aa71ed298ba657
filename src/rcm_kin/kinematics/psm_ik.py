"""Closed-form inverse kinematics of the bundled PSM's layout: shaft-tip position and wrist orientation.

The real inverse of the roll-pitch-insertion RCM kinematics (not the thesis firmware's
``atan2(...)/4`` motion scaling). Axes and offsets are read from the model, so any robot
whose roll axis, pitch axis and shaft are mutually orthogonal and meet at the RCM works.
Positions in m in the base frame; angles in rad.

:func:`shaft_tip_ik` is the twin of the generic closed form :func:`rcm_kin.kinematics.rcm_ik.rcm_ik`
(which reads only the sidecar's ``[rcm]``): a second derivation (roll and pitch from ``atan2`` on
the orthogonal axes, not Paden-Kahan subproblem 2), kept for the PSM's callers (teleoperation,
safety scenarios, the tool-pose start) and tested against the generic one to 1e-9. It also
answers a target at the RCM itself (insertion at the tip offset, shaft straight), which the
generic solver refuses as undetermined.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.rcm_ik import broken_limits
from rcm_kin.model.joints import joint_axes_world

if TYPE_CHECKING:
    from rcm_kin.model import Robot

ARM = ("roll", "pitch", "insertion")
WRIST = ("instrument_roll", "wrist_pitch", "wrist_yaw")


@dataclass(frozen=True)
class RcmGeometry:
    """The RCM arm at q = 0, in the base frame.

    ``shaft_tip = rcm + (insertion - tip_offset) * shaft_direction(roll, pitch)``.
    """

    rcm: np.ndarray
    roll_axis: np.ndarray
    pitch_axis: np.ndarray      # at roll = 0
    shaft_axis: np.ndarray      # shaft direction at q = 0, from the RCM towards the tool
    tip_offset: float           # m
    sign: float                 # pitch_axis x shaft_axis = sign * roll_axis

    @functools.cached_property
    def side(self) -> np.ndarray:
        """roll_axis x shaft_axis, found once (np.cross costs more than the rest of an IK call)."""
        return np.cross(self.roll_axis, self.shaft_axis)


@functools.lru_cache(maxsize=None)
def rcm_geometry(robot: Robot) -> RcmGeometry:
    for name in ARM + WRIST:
        if name not in robot.actuated:
            raise RcmKinError(f"{robot.name} is not an RCM arm: it has no joint '{name}'")
    q0 = np.zeros(robot.nq)
    axes = joint_axes_world(robot, q0)
    roll_axis, pitch_axis, shaft_axis = axes["roll"], axes["pitch"], axes["insertion"]
    rcm = frame_placement(robot, q0, "rcm").translation
    tip = frame_placement(robot, q0, "shaft_tip").translation
    tip_offset = -float((tip - rcm) @ shaft_axis)
    cross = np.cross(pitch_axis, shaft_axis)
    if (abs(roll_axis @ pitch_axis) > 1e-9 or abs(pitch_axis @ shaft_axis) > 1e-9
            or abs(abs(cross @ roll_axis) - 1) > 1e-9):
        raise RcmKinError(f"{robot.name}: roll, pitch and shaft axes are not mutually orthogonal")
    if np.linalg.norm(np.cross(tip - rcm, shaft_axis)) > 1e-9:
        raise RcmKinError(f"{robot.name}: the shaft does not pass through the RCM")
    return RcmGeometry(rcm, roll_axis, pitch_axis, shaft_axis, tip_offset, float(np.sign(cross @ roll_axis)))


def shaft_direction(g: RcmGeometry, roll: float, pitch: float) -> np.ndarray:
    """Unit shaft direction (RCM -> tool) in the base frame."""
    side = g.side
    return (g.sign * np.sin(pitch) * g.roll_axis
            + np.cos(pitch) * (np.cos(roll) * g.shaft_axis + np.sin(roll) * side))


def _angles_of_direction(g: RcmGeometry, u: np.ndarray) -> tuple[float, float]:
    a, b = float(u @ g.shaft_axis), float(u @ g.side)
    return float(np.arctan2(b, a)), float(np.arctan2(g.sign * (u @ g.roll_axis), np.hypot(a, b)))


def shaft_tip_ik(robot: Robot, target) -> np.ndarray:
    """[roll, pitch, insertion] (rad, rad, m) that put ``shaft_tip`` at ``target`` (m, base frame).

    Raises RcmKinError when no solution lies within the joint limits; never clamps.
    """
    target = np.asarray(target, dtype=float)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise RcmKinError(f"a target is 3 finite numbers x y z in metres, got {np.asarray(target).tolist()}")
    g = rcm_geometry(robot)
    d = target - g.rcm
    dist = float(np.linalg.norm(d))
    if dist < 1e-12:
        candidates = [(0.0, 0.0, g.tip_offset)]
    else:
        # tip beyond the RCM (the usual case), or between the RCM and the instrument interface
        candidates = [(*_angles_of_direction(g, d / dist), dist + g.tip_offset),
                      (*_angles_of_direction(g, -d / dist), g.tip_offset - dist)]
    problems = []
    for q_arm in candidates:
        broken = broken_limits(robot, ARM, q_arm)
        if not broken:
            return np.array(q_arm)
        problems.append(", ".join(broken))
    raise RcmKinError(f"shaft tip target ({', '.join(f'{x:.4f}' for x in target)}) m is out of reach: "
                      f"it needs {problems[0]}")


def clamped_shaft_tip_ik(robot: Robot, target) -> tuple[np.ndarray, bool]:
    """:func:`shaft_tip_ik` of ``target`` (m, base frame) and ``False``; for a target out of reach,
    the joints of the tip beyond the RCM on the line to it, each clipped into its limits (as the
    thesis firmware clamps its angles), and ``True``. Never raises for a finite target."""
    try:
        return shaft_tip_ik(robot, target), False
    except RcmKinError:
        target = np.asarray(target, dtype=float)
        if target.shape != (3,) or not np.all(np.isfinite(target)):
            raise
    g = rcm_geometry(robot)
    d = target - g.rcm
    dist = float(np.linalg.norm(d))
    q = np.array([*_angles_of_direction(g, d / dist), dist + g.tip_offset])
    index = [robot.actuated.index(n) for n in ARM]
    return np.clip(q, robot.lower[index], robot.upper[index]), True


def wrist_ik(robot: Robot, q_arm, rotation: np.ndarray) -> np.ndarray:
    """[instrument_roll, wrist_pitch, wrist_yaw] (rad) giving ``tool_tip`` the base-frame
    ``rotation``, with roll, pitch and insertion at ``q_arm``. Closed form.

    The wrist is three revolute joints about their local z axes with fixed rotations A, B, C
    between them: R = Rz(a) A Rz(b) B Rz(c) C. Of the two solutions, the first within the
    limits is returned.
    """
    rotation = np.asarray(rotation, dtype=float)
    if rotation.shape != (3, 3) or not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-9) \
            or np.linalg.det(rotation) < 0:
        raise RcmKinError("a tool orientation must be a 3 x 3 rotation matrix")
    A, B, C = _wrist_constants(robot)
    q = np.zeros(robot.nq)
    q[[robot.actuated.index(n) for n in ARM]] = q_arm
    R_shaft = frame_placement(robot, q, "instrument_shaft").rotation
    R = R_shaft.T @ rotation @ C.T          # = Rz(a) A Rz(b) B Rz(c)
    w = R[:, 2]
    n, v = A.T[:, 2], B[:, 2]
    alpha = n[0] * v[0] + n[1] * v[1]
    beta = n[1] * v[0] - n[0] * v[1]
    gamma = n[2] * v[2]
    rho = np.hypot(alpha, beta)
    cos_arg = (w[2] - gamma) / rho
    if abs(cos_arg) > 1 + 1e-12:
        raise RcmKinError("the wrist cannot reach that tool orientation")
    phi, delta = np.arctan2(beta, alpha), np.arccos(np.clip(cos_arg, -1.0, 1.0))
    problems = []
    i_roll = robot.actuated.index(WRIST[0])
    for b in (phi + delta, phi - delta):
        b = float(np.arctan2(np.sin(b), np.cos(b)))
        m = A @ _rz(b) @ v
        if np.hypot(w[0], w[1]) > 1e-12 and np.hypot(m[0], m[1]) > 1e-12:
            a_options = [float(np.arctan2(w[1], w[0]) - np.arctan2(m[1], m[0]))]
        else:
            # wrist singularity: yaw and instrument-roll axes coincide and only their sum
            # counts; pick the split that keeps both joints within their limits
            a_options = [0.0, *np.linspace(robot.lower[i_roll], robot.upper[i_roll], 25)]
        for a in a_options:
            a = float(np.arctan2(np.sin(a), np.cos(a)))
            K = (_rz(a) @ A @ _rz(b) @ B).T @ R
            c = float(np.arctan2(K[1, 0], K[0, 0]))
            broken = broken_limits(robot, WRIST, (a, b, c))
            if not broken:
                return _polish_wrist(robot, q, np.array([a, b, c]), rotation)
        problems.append(", ".join(broken))
    raise RcmKinError(f"tool orientation out of reach: it needs {problems[0]}")


def _polish_wrist(robot: Robot, q: np.ndarray, q_wrist: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Two Gauss-Newton steps on the orientation error. Near the wrist singularity the
    arccos above loses half the digits (error ~1e-8 rad); this restores machine precision."""
    cols = [robot.actuated.index(n) for n in WRIST]
    red_cols = robot.reduced_q_actuated[cols]
    fid = robot.frame_id("tool_tip")
    q = q.copy()
    q[cols] = q_wrist
    for _ in range(2):
        R = frame_placement(robot, q, "tool_tip").rotation
        err = R @ pin.log3(R.T @ rotation)   # base-frame rotation vector
        J = pin.computeFrameJacobian(robot.reduced, robot.reduced_data, robot.to_reduced(q), fid,
                                     pin.LOCAL_WORLD_ALIGNED)[3:, red_cols]
        step = np.linalg.lstsq(J, err, rcond=1e-10)[0]
        lo, hi = robot.lower[cols], robot.upper[cols]
        q[cols] = np.clip(q[cols] + step, lo, hi)
    return q[cols]


def _rz(angle: float) -> np.ndarray:
    return pin.utils.rotate("z", angle)


@functools.lru_cache(maxsize=None)
def _wrist_constants(robot: Robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fixed rotations between the wrist joints: A (shaft -> wrist pitch), B (pitch -> yaw),
    C (yaw -> tool_tip frame)."""
    model = robot.tree
    ids = [model.getJointId(n) for n in WRIST]
    for jid in ids:
        if model.joints[jid].shortname() != "JointModelRZ":
            raise RcmKinError(f"{robot.name}: wrist joint '{model.names[jid]}' must turn about its local z axis")
    if model.parents[ids[1]] != ids[0] or model.parents[ids[2]] != ids[1]:
        raise RcmKinError(f"{robot.name}: the wrist joints must form a chain")
    tool = model.frames[model.getFrameId("tool_tip")]
    if tool.parentJoint != ids[2]:
        raise RcmKinError(f"{robot.name}: tool_tip must sit on the wrist yaw link")
    return (model.jointPlacements[ids[1]].rotation.copy(), model.jointPlacements[ids[2]].rotation.copy(),
            tool.placement.rotation.copy())


def shaft_tip_applies(robot: Robot) -> bool:
    """Whether :func:`shaft_tip_ik` (the twin of the generic closed form) fits ``robot``: its
    ``[rcm]`` pivots ``roll`` and ``pitch`` move ``shaft_tip`` about the ``rcm`` frame, with
    ``insertion`` along the shaft (a structural check: a renamed copy fits)."""
    rcm = robot.description.rcm
    if rcm is None or rcm.shaft_frame != "shaft_tip" or tuple(rcm.joints) != ARM[:2]:
        return False
    if "insertion" not in robot.actuated:
        return False
    if not all(robot.reduced.existFrame(f) for f in ("rcm", "shaft_tip")):
        return False
    try:
        rcm_geometry(robot)
    except RcmKinError:
        return False
    return True


def tool_pose_applies(robot: Robot, frame: str) -> bool:
    """Whether :func:`tool_pose_ik` fits ``robot`` and ``frame``: the roll-pitch-insertion arm about
    an RCM (frames ``rcm``, ``shaft_tip``, ``instrument_shaft``), the three-joint z-axis wrist and
    the jaw of this module, ``frame`` being ``tool_tip`` (a structural check: a renamed copy fits)."""
    if frame != "tool_tip" or not all(n in robot.actuated for n in (*ARM, *WRIST, "jaw")):
        return False
    if not all(robot.reduced.existFrame(f) for f in ("rcm", "shaft_tip", "instrument_shaft", "tool_tip")):
        return False
    try:
        rcm_geometry(robot)
        _wrist_constants(robot)
    except RcmKinError:
        return False
    return True


def tool_pose_ik(robot: Robot, position, rotation: np.ndarray, jaw: float = 0.0):
    """Actuated ``q`` putting ``tool_tip`` at ``position`` (m) with ``rotation`` (base frame).

    Closed-form start (shaft tip at the target, wrist orientation in closed form), then damped
    least squares over the six arm and wrist joints. Returns a numeric_ik.IKResult.
    """
    q0 = np.zeros(robot.nq)
    q0[robot.actuated.index("jaw")] = jaw
    try:
        q_arm = shaft_tip_ik(robot, position)
        q0[[robot.actuated.index(n) for n in ARM]] = q_arm
        q0[[robot.actuated.index(n) for n in WRIST]] = wrist_ik(robot, q_arm, rotation)
    except RcmKinError:
        pass  # the closed-form start is only a start; solve_ik judges reachability
    return solve_ik(robot, "tool_tip", position, rotation, q0=q0, joints=ARM + WRIST)

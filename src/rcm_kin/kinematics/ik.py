"""One inverse-kinematics entry for any robot description.

- Position of the ``[rcm]`` shaft frame (the default where the sidecar has ``[rcm]``): the pivot
  joints and the insertion in closed form (:mod:`rcm_kin.kinematics.rcm_ik`); a chain whose shaft
  lines only nearly meet finishes with damped least squares over the same three joints.
- Any other frame, or a robot without ``[rcm]``: damped least squares
  (:func:`rcm_kin.kinematics.numeric_ik.solve_ik`) over the actuated joints that move the frame. The
  default frame of a position target is the last frame of interest that at most three joints
  place (a wrist centre), else the last frame of interest.
- With ``rpy``, a full pose: the last frame of interest by default; an RCM arm with the
  roll-pitch-insertion arm and z-axis wrist of :mod:`rcm_kin.kinematics.psm_ik` gets its
  closed-form start.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.psm_ik import ARM, WRIST, shaft_tip_applies, shaft_tip_ik, tool_pose_applies, tool_pose_ik
from rcm_kin.kinematics.rcm_ik import rcm_chain, rcm_ik
from rcm_kin.model.robot import check_robot

CLOSED_FORM = "closed-form RCM"
NUMERIC = "damped least squares"
EXACT = 1e-10   # m: a closed form whose forward kinematics misses by more is finished numerically


@dataclass(frozen=True)
class IKSolution:
    """The joints that place ``frame``, and how well forward kinematics reproduces the target."""

    frame: str
    joints: tuple[str, ...]           # the solved joints, in actuated order (RCM: pivots, insertion)
    q: np.ndarray                     # their values (rad, m)
    q_full: np.ndarray                # every actuated joint, the others at ``q0`` (default 0)
    position_error: float             # m, |FK(q_full) position of frame - target|
    orientation_error: float | None   # rad, full pose only
    method: str = NUMERIC             # CLOSED_FORM or NUMERIC


def _target(position) -> np.ndarray:
    try:
        position = np.asarray(position, dtype=float)
    except (TypeError, ValueError):
        position = np.full(1, np.nan)
    if position.shape != (3,) or not np.all(np.isfinite(position)):
        raise RcmKinError("a target `position` is 3 finite numbers x y z in metres, got "
                          f"{np.asarray(position).tolist()}", parameter="position")
    return position


def _rotation(rpy) -> np.ndarray:
    try:
        rpy = np.asarray(rpy, dtype=float)
    except (TypeError, ValueError):
        rpy = np.full(1, np.nan)
    if rpy.shape != (3,) or not np.all(np.isfinite(rpy)):
        raise RcmKinError(f"`rpy` is 3 finite angles roll pitch yaw in rad, got {np.asarray(rpy).tolist()}",
                          parameter="rpy")
    return pin.rpy.rpyToMatrix(*rpy)


def _sample_jacobians(robot, frame: str) -> list[np.ndarray]:
    """``frame``'s 6 x nq Jacobian (base-frame axes) at mid-range and at a seeded pose within the limits."""
    fid = robot.frame_id(frame)
    lower, upper = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    return [pin.computeFrameJacobian(robot.reduced, robot.reduced_data, robot.to_reduced(q), fid,
                                     pin.LOCAL_WORLD_ALIGNED)[:, robot.reduced_q_actuated]
            for q in (0.5 * (lower + upper), np.random.default_rng(0).uniform(lower, upper))]


def moving_joints(robot, frame: str, orientation: bool = False) -> tuple[str, ...]:
    """The actuated joints (actuated order) that move ``frame``'s position, and its orientation
    when ``orientation``: a nonzero Jacobian column at mid-range or at a seeded pose within the limits."""
    rows = slice(0, 6) if orientation else slice(0, 3)
    moved = np.zeros(robot.nq, dtype=bool)
    for J in _sample_jacobians(robot, frame):
        moved |= np.linalg.norm(J[rows], axis=0) > 1e-9
    return tuple(name for name, m in zip(robot.actuated, moved) if m)


def _check_turns(robot, frame: str, joints: tuple[str, ...]) -> None:
    """A full pose needs ``joints`` to move ``frame`` in six independent directions."""
    cols = [robot.actuated.index(j) for j in joints]
    rank = max(int(np.sum(np.linalg.svd(J[:, cols], compute_uv=False) > 1e-9))
               for J in _sample_jacobians(robot, frame))
    if rank < 6:
        raise RcmKinError(f"`rpy` asks for a full pose of {frame}, which its joints move in {rank} independent "
                          "directions only (6 needed): give the position alone or another `frame`",
                          parameter=("rpy", "frame"))


@functools.lru_cache(maxsize=32)
def default_frame(robot, orientation: bool = False) -> str:
    """The frame an IK target places when none is named (see the module docstring); found once per
    robot (it depends on the model only)."""
    frames = robot.description.frames or (robot.reduced.frames[len(robot.reduced.frames) - 1].name,)
    moving = {name: len(moving_joints(robot, name)) for name in frames}
    moved = [name for name in frames if moving[name]]     # a frame no joint moves has no IK
    if not orientation:
        for name in reversed(moved):
            if moving[name] <= 3:
                return name
    return moved[-1] if moved else frames[-1]


def inverse_kinematics(robot, position, rpy=None, frame: str | None = None, q0=None) -> IKSolution:
    """Solve for ``position`` (m, base frame) of ``frame``; with ``rpy`` (rad, roll pitch yaw as
    ``pinocchio.rpy``) for its full pose. ``q0``: actuated start (and the values of the joints not
    solved for; default 0); with ``[rcm]`` the closed-form solution nearest to it.

    Without ``frame`` and ``rpy`` a robot with ``[rcm]`` places its shaft frame in closed form.
    Unreachable targets and bad input raise a one-line ``RcmKinError``.
    """
    robot = check_robot(robot)
    position = _target(position)
    rotation = None if rpy is None else _rotation(rpy)
    if frame is not None and not isinstance(frame, str):
        raise RcmKinError(f"`frame` is a frame's name, got {type(frame).__name__}", parameter="frame")
    if frame is not None and not robot.reduced.existFrame(frame):
        raise RcmKinError(f"{robot.name} has no frame '{frame}' (`frame`); frames of interest: "
                          f"{', '.join(robot.description.frames)}", parameter="frame")
    q0 = None if q0 is None else robot.check_q(q0, allow_short=True)
    rcm = robot.description.rcm
    if rotation is None and rcm is not None and frame in (None, rcm.shaft_frame):
        return _rcm_solution(robot, position, q0)
    frame = default_frame(robot, rotation is not None) if frame is None else frame
    if rotation is not None and tool_pose_applies(robot, frame):
        joints = ARM + WRIST
        q_full = tool_pose_ik(robot, position, rotation).q
    else:
        joints = moving_joints(robot, frame, rotation is not None)
        if not joints:
            raise RcmKinError(f"no actuated joint of {robot.name} moves {frame} (`frame`)", parameter="frame")
        if rotation is not None:
            _check_turns(robot, frame, joints)
        q_full = solve_ik(robot, frame, position, rotation, q0=q0, joints=joints).q
    return _solution(robot, frame, joints, q_full, position, rotation, NUMERIC)


def _rcm_solution(robot, position, q0) -> IKSolution:
    """The shaft frame at ``position``: closed form, finished numerically over the same joints where
    the chain's shaft lines only nearly meet (the closed form is then a start, from which
    ``solve_ik`` judges reachability)."""
    chain = rcm_chain(robot, q0)
    exact = chain.line_error <= EXACT
    try:
        q_full, _ = rcm_ik(robot, position, q0)
        if shaft_tip_applies(robot) and chain.joints == ARM:
            q_full[chain.index] = shaft_tip_ik(robot, position)   # its twin, the PSM's outputs to the bit
    except RcmKinError:
        if exact:
            raise
        q_full = chain.rest
    else:
        reached = frame_placement(robot, q_full, chain.shaft_frame).translation
        if exact and np.linalg.norm(reached - position) <= EXACT:
            return _solution(robot, chain.shaft_frame, chain.joints, q_full, position, None, CLOSED_FORM)
    q_full = solve_ik(robot, chain.shaft_frame, position, q0=q_full, joints=chain.joints).q
    return _solution(robot, chain.shaft_frame, chain.joints, q_full, position, None, NUMERIC)


def _solution(robot, frame, joints, q_full, position, rotation, method) -> IKSolution:
    placement = frame_placement(robot, q_full, frame)
    error = float(np.linalg.norm(placement.translation - position))
    orientation_error = None if rotation is None else float(np.linalg.norm(pin.log3(placement.rotation.T @ rotation)))
    q = q_full[[robot.actuated.index(j) for j in joints]]
    return IKSolution(frame, tuple(joints), q, q_full, error, orientation_error, method)

"""Forward kinematics of the frames of interest, in the base frame (m, rotation matrices)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rcm_kin.model.constrained import loop_checks, loops_error
from rcm_kin.model.robot import Robot, RobotData, check_robot


@dataclass(frozen=True)
class ForwardKinematics:
    q: np.ndarray                 # actuated joints (rad, m)
    frames: dict[str, pin.SE3]    # placement of each frame in the base frame
    closure_residual: float       # largest loop-closure error of the configuration used (m)


@functools.lru_cache(maxsize=256)
def frame_ids(robot: Robot, frames: tuple[str, ...]) -> tuple[int, ...]:
    """The reduced model's ids of ``frames`` (:meth:`Robot.frame_id`: an error names an unknown
    one), looked up once per robot and frame tuple."""
    return tuple(robot.frame_id(name) for name in frames)


def frame_placement(robot: Robot, q: np.ndarray, frame: str, data: RobotData | None = None) -> pin.SE3:
    """Placement of one frame in the base frame at actuated ``q`` (reduced model); ``data``: the
    caller's workspace (:meth:`Robot.create_data`), default this thread's own."""
    fid = frame_ids(robot, (frame,))[0]
    reduced_data = robot.workspace(data).reduced
    pin.forwardKinematics(robot.reduced, reduced_data, robot.to_reduced(q))
    return pin.updateFramePlacement(robot.reduced, reduced_data, fid).copy()


def forward_kinematics(robot: Robot, q, frames: tuple[str, ...] | None = None,
                       data: RobotData | None = None, *, allow_outside_limits: bool = False) -> ForwardKinematics:
    """Frames of interest (default: the sidecar's ``frames``) at actuated ``q`` (rad, m).

    ``data``: the caller's workspace (:meth:`Robot.create_data`); default this thread's own;
    ``allow_outside_limits``: evaluate a pose outside the joint limits (refused by default,
    :meth:`Robot.check_pose`)."""
    if not isinstance(robot, Robot):
        check_robot(robot)                      # its error, naming `robot`
    q = robot.check_pose(q, allow_outside_limits=allow_outside_limits)
    data = robot.workspace(data)
    named, actuated_order, checks = _plan(robot, frames if frames is None else tuple(frames))
    model, reduced = robot.reduced, data.reduced
    pin.forwardKinematics(model, reduced, q if actuated_order else robot.to_reduced(q))
    update = pin.updateFramePlacement
    placements = {name: update(model, reduced, fid).copy() for name, fid in named}
    # loops_error: placed_closure_error without its checks of robot, data and model, done above
    return ForwardKinematics(q, placements, loops_error(checks, model, reduced, data))


@functools.lru_cache(maxsize=256)
def _plan(robot: Robot, frames: tuple[str, ...] | None) -> tuple[tuple[tuple[str, int], ...], bool, tuple]:
    """What forward kinematics looks up once per robot and frame tuple (``None``: the sidecar's
    ``frames``): each frame's name with its reduced-model id (:func:`frame_ids`), whether the
    reduced model's configuration is the actuated vector itself (the PSM's, the MTM's), which then
    skips :meth:`Robot.to_reduced`'s copy, and the robot's :func:`loop_checks`."""
    frames = robot.description.frames if frames is None else frames
    in_order = bool(np.array_equal(robot.reduced_q_actuated, np.arange(robot.nq)))
    actuated_order = robot.reduced.nq == robot.nq and in_order
    return tuple(zip(frames, frame_ids(robot, frames))), actuated_order, loop_checks(robot)

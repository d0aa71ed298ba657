"""Forward kinematics of the frames of interest, in the base frame (m, rotation matrices)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from rcm_kin.closure.constrained import closure_residual
from rcm_kin.closure.reduced import tree_configuration

if TYPE_CHECKING:
    from rcm_kin.robot import Robot


@dataclass(frozen=True)
class ForwardKinematics:
    q: np.ndarray                 # actuated joints (rad, m)
    frames: dict[str, pin.SE3]    # placement of each frame in the base frame
    closure_residual: float       # largest loop-closure error of the configuration used (m)


def frame_placement(robot: Robot, q: np.ndarray, frame: str) -> pin.SE3:
    """Placement of one frame in the base frame at actuated ``q`` (reduced model)."""
    fid = robot.frame_id(frame)
    pin.forwardKinematics(robot.reduced, robot.reduced_data, robot.to_reduced(q))
    return pin.updateFramePlacement(robot.reduced, robot.reduced_data, fid).copy()


def forward_kinematics(robot: Robot, q, frames: tuple[str, ...] | None = None) -> ForwardKinematics:
    """Frames of interest (default: the sidecar's ``frames``) at actuated ``q``."""
    q = robot.check_q(q)
    frames = robot.description.frames if frames is None else frames
    ids = [robot.frame_id(name) for name in frames]
    pin.forwardKinematics(robot.reduced, robot.reduced_data, robot.to_reduced(q))
    placements = {name: pin.updateFramePlacement(robot.reduced, robot.reduced_data, fid).copy()
                  for name, fid in zip(frames, ids)}
    residual = closure_residual(robot, tree_configuration(robot, q))
    return ForwardKinematics(q, placements, float(np.max(np.abs(residual))) if residual.size else 0.0)


def joint_axes_world(robot: Robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """Unit axis of every open-tree joint in the base frame at actuated ``q``: the rotation
    axis of a revolute joint, the direction of motion of a prismatic one."""
    q_tree = tree_configuration(robot, q)
    model, data = robot.tree, robot.tree_data
    pin.computeJointJacobians(model, data, q_tree)
    axes = {}
    for jid in range(1, model.njoints):
        column = pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED)[:, model.joints[jid].idx_v]
        axis = column[3:] if np.linalg.norm(column[3:]) > 0.5 else column[:3]
        axes[model.names[jid]] = axis / np.linalg.norm(axis)
    return axes

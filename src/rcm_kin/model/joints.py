"""The open tree's joints: their axes in the base frame and the joint table of a robot."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from rcm_kin.model.reduced import tree_configuration
from rcm_kin.model.robot import JointRow, Robot, RobotData, check_robot


def joint_axes_world(robot: Robot, q: np.ndarray, data: RobotData | None = None) -> dict[str, np.ndarray]:
    """Unit axis of every open-tree joint in the base frame at actuated ``q``: the rotation
    axis of a revolute joint, the direction of motion of a prismatic one."""
    q_tree = tree_configuration(robot, q)
    model, tree_data = robot.tree, robot.workspace(data).tree
    pin.computeJointJacobians(model, tree_data, q_tree)
    axes = {}
    for jid in range(1, model.njoints):
        column = pin.getJointJacobian(model, tree_data, jid, pin.LOCAL_WORLD_ALIGNED)[:, model.joints[jid].idx_v]
        axis = column[3:] if np.linalg.norm(column[3:]) > 0.5 else column[:3]
        axes[model.names[jid]] = axis / np.linalg.norm(axis)
    return axes


def joint_table(robot: Robot) -> list[JointRow]:
    """Every joint of the open tree, in tree order, passive loop joints included."""
    robot = check_robot(robot)
    axes = joint_axes_world(robot, np.zeros(robot.nq))
    rows = []
    for jid in range(1, robot.tree.njoints):
        name, i = robot.tree.names[jid], robot.tree.joints[jid].idx_q
        rows.append(JointRow(name, robot.joint_kind(name), "actuated" if name in robot.actuated else "passive",
                             float(robot.tree.lowerPositionLimit[i]), float(robot.tree.upperPositionLimit[i]),
                             axes[name]))
    return rows

"""One inverse-kinematics entry for the bundled robots: the PSM's shaft tip (closed form) or tool
pose, the MTM's wrist centre (numeric, first three joints)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.psm_ik import ARM, WRIST, shaft_tip_ik, tool_pose_ik

MTM_ARM = ("j1", "j2", "j3")


@dataclass(frozen=True)
class IKSolution:
    """The joints that place ``frame``, and how well forward kinematics reproduces the target."""

    frame: str
    joints: tuple[str, ...]           # the solved joints, the first ones of the actuated order
    q: np.ndarray                     # their values (rad, m)
    q_full: np.ndarray                # every actuated joint, the others at 0
    position_error: float             # m, |FK(q_full) position of frame - target|
    orientation_error: float | None   # rad, tool pose only


def inverse_kinematics(robot, position, rpy=None) -> IKSolution:
    """Solve for ``position`` (m, base frame); with ``rpy`` (rad, roll pitch yaw as
    ``pinocchio.rpy``) the PSM's tool_tip pose. Unreachable targets raise ``RcmKinError``."""
    position = np.asarray(position, dtype=float)
    orientation_error = None
    if robot.name == "psm" and rpy is None:
        frame, joints = "shaft_tip", ARM
        q_full = robot.check_q(shaft_tip_ik(robot, position), allow_short=True)
    elif robot.name == "psm":
        frame, joints = "tool_tip", ARM + WRIST
        result = tool_pose_ik(robot, position, pin.rpy.rpyToMatrix(*np.asarray(rpy, dtype=float)))
        q_full, orientation_error = result.q, result.orientation_error
    elif robot.name == "mtm":
        if rpy is not None:
            raise RcmKinError("`rpy` is for the PSM tool; the MTM IK places its wrist centre", parameter="rpy")
        frame, joints = "wrist_center", MTM_ARM
        q_full = solve_ik(robot, frame, position, joints=joints).q
    else:
        raise RcmKinError(f"no IK for robot '{robot.name}'")
    error = float(np.linalg.norm(frame_placement(robot, q_full, frame).translation - position))
    return IKSolution(frame, tuple(joints), q_full[:len(joints)], q_full, error, orientation_error)

"""Forward and inverse kinematics and the MTM -> PSM teleoperation map."""

import lazy_loader

__all__ = [
    "ForwardKinematics", "IKSolution", "TeleopMap", "forward_kinematics", "frame_placement", "inverse_kinematics",
    "shaft_tip_ik", "solve_ik", "teleop_joint_targets", "tool_pose_ik",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "fk": ["ForwardKinematics", "forward_kinematics", "frame_placement"],
        "ik": ["IKSolution", "inverse_kinematics"],
        "numeric_ik": ["solve_ik"],
        "psm_ik": ["shaft_tip_ik", "tool_pose_ik"],
        "teleop": ["TeleopMap", "teleop_joint_targets"],
    },
)

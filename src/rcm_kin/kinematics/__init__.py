"""Forward and inverse kinematics and the MTM -> PSM teleoperation map."""

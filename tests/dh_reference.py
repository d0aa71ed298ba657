"""Independent forward kinematics from the osMDV standard-DH tables (reference sheet), for tests.

Written from the tables alone: nothing here reads the URDFs or rcm_kin. Lengths in m.
"""

from __future__ import annotations

import numpy as np

PSM_L_RCM, PSM_L_TOOL, PSM_L_P2Y, PSM_L_Y2T = 0.45599, 0.43250, 0.00900, 0.01010
MTM_L_SHO, MTM_L_ARM, MTM_L_BALL, MTM_L_IMU = 0.045, 0.2175, 0.0087, 0.0374

# DH frame 0 in each robot's base frame (z up). PSM: origin at the RCM, z0 along the roll axis
# (base -x), x0 up. MTM: frame 0 has y up; the base frame is it turned +90 deg about x.
PSM_BASE_R_DH0 = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
MTM_BASE_R_DH0 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def dh(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    """Standard DH: Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def _in_base(R_base_dh0: np.ndarray, T: np.ndarray) -> np.ndarray:
    B = np.eye(4)
    B[:3, :3] = R_base_dh0
    return B @ T


def psm_frames(q) -> dict[str, np.ndarray]:
    """4x4 poses of shaft_tip (frame after the fixed l_tool row) and tool_tip (frame 6)."""
    q1, q2, q3, q4, q5, q6 = q[:6]
    T = dh(q1, 0, 0, -np.pi / 2) @ dh(q2 - np.pi / 2, 0, 0, np.pi / 2) @ dh(0, q3 - PSM_L_RCM, 0, 0)
    T = T @ dh(0, PSM_L_TOOL, 0, 0)
    shaft_tip = T
    T = T @ dh(q4, 0, 0, -np.pi / 2) @ dh(q5 - np.pi / 2, 0, PSM_L_P2Y, -np.pi / 2) @ dh(q6, 0, PSM_L_Y2T, 0)
    return {"shaft_tip": _in_base(PSM_BASE_R_DH0, shaft_tip), "tool_tip": _in_base(PSM_BASE_R_DH0, T)}


def mtm_frames(q) -> dict[str, np.ndarray]:
    """4x4 poses of wrist_center (origin of DH frame 3) and tool_tip (frame 6), left arm."""
    q1, q2, q3, q4, q5, q6 = q[:6]
    T = dh(q1, 0, MTM_L_SHO, np.pi / 2) @ dh(q2, 0, MTM_L_ARM, -np.pi / 2)
    T = T @ dh(q3 - np.pi / 2, -MTM_L_BALL, MTM_L_ARM, -np.pi / 2)
    wrist = T
    T = T @ dh(q4 - np.pi / 2, 0, 0, -np.pi / 2) @ dh(q5 - np.pi / 2, 0, 0, -np.pi / 2)
    T = T @ dh(q6 + np.pi / 2, -MTM_L_IMU, 0, -np.pi / 2)
    return {"wrist_center": _in_base(MTM_BASE_R_DH0, wrist), "tool_tip": _in_base(MTM_BASE_R_DH0, T)}

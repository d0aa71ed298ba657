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


# da Vinci patient-side arm: the FK code of the AAU 2015 thesis (Appendix C.1.1), written out from
# the digest's arrays with its two corrections (a10 = 0.520, ax9 = -2). Frames 1..13 in series,
# jaws 14L and 14R both on frame 13. T_i = [Rot_i, (a_i, b_i, d_i)] [Rot_var_i, p_i].
_DV_A = [0, 0.198, 0, 0.435, 0.057, 0.352, -0.052, 0, 0, 0.520, 0, 0.052, 0, 0, 0]
_DV_B = [0, 0, 0.583, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
_DV_D = [0, 0.812, 0, -0.001, 0.198, -0.117, 0.161, 0, 0.186, 0, -0.104, 0, 0.177, 0.009, 0.009]
_DV_AX = [3, 3, -3, -3, -1, 3, 1, -2, -2, -2, 3, 3, -1, -3, 3]
_TILT = 0.1745


def _rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


_DV_ROT = [np.eye(3), _rz(np.pi / 2) @ _rx(np.pi), _rz(np.pi / 2) @ _rx(-np.pi), np.eye(3), np.eye(3), np.eye(3),
           np.eye(3), _ry(-_TILT), _ry(_TILT) @ _rx(np.pi), _rx(np.pi), np.eye(3), _rz(np.pi / 2) @ _rx(np.pi),
           np.eye(3), _ry(np.pi / 2) @ _rx(np.pi / 2), _ry(np.pi / 2) @ _rx(np.pi / 2)]
_DV_NAMES = ["elevation", "arm_yaw1", "arm_yaw2", "arm_yaw3", "arm_roll1", "rcm_base", "hand_roll", "hand_pitch",
             "upper_bar", "instrument_holder", "instrument_slide", "instrument_roll", "instrument_pitch", "jaw_left",
             "jaw_right"]


def davinci_frames(q) -> dict[str, np.ndarray]:
    """4x4 poses (base frame) of the 15 frames of Table C.1 for the 13 independent joint values
    [d1, th2..th6, th7, th8, d11, th12, th13, th14L, th14R]; frames 8-10 all take th8."""
    d1, t2, t3, t4, t5, t6, t7, t8, d11, t12, t13, t14l, t14r = q
    state = [d1, t2, t3, t4, t5, t6, t7, t8, t8, t8, d11, t12, t13, t14l, t14r]
    rot_about = {1: _rx, 2: _ry, 3: _rz}
    out, T = {}, np.eye(4)
    for i, (name, value) in enumerate(zip(_DV_NAMES, state)):
        fixed = np.eye(4)
        fixed[:3, :3] = _DV_ROT[i]
        fixed[:3, 3] = [_DV_A[i], _DV_B[i], _DV_D[i]]
        free = np.eye(4)
        axis = abs(_DV_AX[i])
        if i in (0, 10):                                   # prismatic joints move along |ax|
            free[axis - 1, 3] = np.sign(_DV_AX[i]) * value
        else:
            free[:3, :3] = rot_about[axis](np.sign(_DV_AX[i]) * value)
        parent = out["instrument_pitch"] if name in ("jaw_left", "jaw_right") else T
        out[name] = parent @ fixed @ free
        T = out[name]
    return out


def davinci_rcm_wrist(q_rcm_base_frame) -> np.ndarray:
    """The digest's closed-form RCM geometry of the reduced chain, in the rcm_base frame:
    wrist = c + (0.097 - d9) [sin th8, sin th7 cos th8, -cos th7 cos th8], c = (0.482, 0, 0.047)."""
    t7, t8, d9 = q_rcm_base_frame
    return np.array([0.482, 0.0, 0.047]) + (0.097 - d9) * np.array(
        [np.sin(t8), np.sin(t7) * np.cos(t8), -np.cos(t7) * np.cos(t8)])


# The thesis's DH code (Table C.5, Appendix C, digest Sec. 1.4): a second parameterisation of the
# same arm, with the three values the digest flags (d1 1.0, d7 -0.045, tilt 10 deg).
_DH_A = [0.198, 0.5820, 0.435, 0, 0, 0, 0, 0.1900, 0.515, 0.0400, 0, 0, 0.0095]
_DH_D = [1.0, 0, 0, 0, 0.4122, 0.0474, -0.0450, 0, 0, 0, 0.282, 0, 0]
_DH_ALPHA = [0, 0, 0, np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, np.pi, np.pi, np.pi / 2, 0, np.pi / 2, np.pi / 2]
_DH_THETA = [0, 0, 0, np.pi / 2, np.pi, 0, -np.pi / 2, np.radians(10), np.radians(10) + np.pi / 2, 0, 0, 0, np.pi / 2]


def davinci_dh_wrist(q) -> np.ndarray:
    """Origin (m) of DH frame 12 of the DH code: on the instrument-pitch axis, for the same 13
    joint values as :func:`davinci_frames` (the code's sign changes applied)."""
    d1, t2, t3, t4, t5, t6, t7, t8, d11, t12, t13, _, _ = q
    d_free = [d1, 0, 0, 0, 0, 0, 0, 0, 0, 0, -d11, 0, 0]
    th_free = [0, -t2, -t3, -t4, -t5, t6, t7, t8, t8, t8, 0, t12, -t13]
    T = np.eye(4)
    for i in range(12):
        T = T @ dh(th_free[i] + _DH_THETA[i], d_free[i] + _DH_D[i], _DH_A[i], _DH_ALPHA[i])
    return T[:3, 3]

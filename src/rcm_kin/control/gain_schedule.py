"""Model-based gain scheduling of the PSM firmware's roll LQR and pitch LQI.

At each (roll, pitch) grid point the driven-joint model is linearised (Coulomb friction left
out: see :func:`rcm_kin.dynamics.state_space.driven_dynamics`), and per axis

- roll: LQR on ``[q, v]`` of the roll subsystem (the Riccati solve of python-control's ``lqr``);
- pitch: LQI on ``[q, v]`` plus the integral of the position error (``lqr`` with
  ``integral_action``).

Gains are stored in the firmware's units and signs (thesis Tables 4.4-4.8): with the error
``e = r - y`` in degrees, ``v`` in deg/s and ``E`` the integral of ``e`` (deg s), the firmware
applies ``u = -(Kp e + Kd v)`` (roll) and ``u = -(Kp e + Kd v + Ki E)`` (pitch), PWM counts with
the hardware sign (positive PWM lowers the angle). The LQR law ``u = -K [y - r; v]`` therefore
maps to ``Kp = -K_q``, ``Kd = K_v``, ``Ki = -K_z``. Between grid points the firmware interpolates
bilinearly (table[pitch][roll]) and clamps to the edge outside
(:func:`rcm_kin.firmware_rules.bilinear`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rcm_kin.control.friction import (
    DEFAULT_RAMP_DEG_S,
    FrictionCompensation,
    friction_compensation,
)
from rcm_kin.control.linearization import linearize_grid
from rcm_kin.control.weights import Weights
from rcm_kin.dynamics.state_space import check_model
from rcm_kin.errors import RcmKinError, WorkLimitError, as_number, as_numbers
from rcm_kin.firmware_rules import bilinear
from rcm_kin.hardware import HOME_INSERTION, INSERTION_KP
from rcm_kin.model import load_robot

if TYPE_CHECKING:
    from rcm_kin.dynamics.state_space import DrivenDynamics

THESIS_ROLL_DEG = (-20.0, 0.0, 20.0)
THESIS_PITCH_DEG = (-15.0, 0.0, 15.0)
ROLL, PITCH, INSERTION = 0, 1, 2
MAX_SCHEDULE_POSES = 201 * 201     # grid poses of one schedule (the CLI's --check-points bound, squared)
MAX_RAMP_DEG_S = 1000.0            # deg/s: a friction-compensation ramp (default 2), far above any joint speed


def axis_model(A: np.ndarray, B: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray]:
    """One joint's 2-state model ``[q; v]`` in degrees and PWM from the 6-state SI model
    (the other joints frozen). Scaling both states by the same factor leaves ``A`` unchanged;
    ``B`` goes from rad (per s^2) per count to degrees per count."""
    i = [axis, axis + 3]
    return A[np.ix_(i, i)], np.degrees(B[i][:, [axis]])


def lqr_axis(a: np.ndarray, b: np.ndarray, Q: np.ndarray, R: np.ndarray, integral: bool = False) -> np.ndarray:
    """State-feedback row ``K`` of ``u = -K x`` for one axis, ``K = R^-1 B' X`` with ``X`` the
    stabilising solution of the continuous algebraic Riccati equation (SciPy
    ``solve_continuous_are``: the operations python-control's ``lqr`` performs without Slycot,
    without its second of imports); with ``integral`` the state is augmented by the integral of
    the first state (LQI, python-control's ``integral_action=[[1, 0]]``)."""
    from scipy.linalg import solve_continuous_are  # SciPy's linalg only where gains are designed

    a, b = np.array(a, dtype=float, ndmin=2), np.array(b, dtype=float, ndmin=2)
    Q, R = np.array(Q, dtype=float, ndmin=2), np.array(R, dtype=float, ndmin=2)
    if integral:
        n, m = a.shape[0], b.shape[1]
        a = np.block([[a, np.zeros((n, 1))], [np.eye(1, n), np.zeros((1, 1))]])
        b = np.vstack([b, np.zeros((1, m))])
    for name, M, size in (("Q", Q, a.shape[0]), ("R", R, b.shape[1])):
        if M.shape != (size, size) or not np.allclose(M, M.T):
            raise RcmKinError(f"the LQR weight {name} must be a symmetric {size} x {size} matrix, got {M.tolist()}")
    X = solve_continuous_are(a, b, Q, R)
    return np.linalg.solve(R, b.T @ X)[0]


def roll_gains(A: np.ndarray, B: np.ndarray, weights: Weights) -> np.ndarray:
    """``[Kp, Kd]`` (PWM/deg, PWM/(deg/s)), firmware signs, of the roll LQR at one linear model."""
    K = lqr_axis(*axis_model(A, B, ROLL), *weights.roll())
    return np.array([-K[0], K[1]])


def pitch_gains(A: np.ndarray, B: np.ndarray, weights: Weights) -> np.ndarray:
    """``[Kp, Kd, Ki]`` (PWM/deg, PWM/(deg/s), PWM/(deg s)), firmware signs, of the pitch LQI."""
    K = lqr_axis(*axis_model(A, B, PITCH), *weights.pitch(), integral=True)
    return np.array([-K[0], K[1], -K[2]])


def pitch_feedforward(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``[F_v, F_a]`` of the pitch model inverse ``u_ff = pinv(B) (xdot_ref - A x_ref)``:
    ``u_ff = F_v rdot + F_a rddot`` (PWM per deg/s, per deg/s^2) plus the position term
    ``-pinv(B) A [r; 0]``, which is the slope of the holding PWM and is left to the gravity
    feedforward (``u_hold``)."""
    a, b = axis_model(A, B, PITCH)
    pinv_b = np.linalg.pinv(b)                       # (1, 2)
    # xdot_ref - A x_ref with x_ref = [0; rdot], xdot_ref = [rdot; rddot]
    F_v = pinv_b @ (np.array([1.0, 0.0]) - a[:, 1])
    F_a = pinv_b @ np.array([0.0, 1.0])
    return np.array([F_v[0], F_a[0]])


def closed_loop_matrix(A: np.ndarray, B: np.ndarray, k_roll, k_pitch, insertion_kp: float = INSERTION_KP) -> np.ndarray:
    """Continuous closed-loop state matrix (7, 7) of the coupled 3-joint model under the firmware
    laws: roll ``[Kp, Kd]``, pitch ``[Kp, Kd, Ki]``, insertion P (counts/m). State: the model's
    ``[q; v]`` (SI) and the pitch error integral ``z`` (rad s, ``zdot = r - y``, here ``r = 0``)."""
    kr, kp = np.degrees(k_roll), np.degrees(k_pitch)   # firmware gains per degree -> per radian
    K = np.zeros((3, 7))                 # u = -K [x; z], x in SI
    K[ROLL, [0, 3]] = [-kr[0], kr[1]]
    K[PITCH, [1, 4, 6]] = [-kp[0], kp[1], kp[2]]
    K[INSERTION, 2] = insertion_kp
    A_aug = np.zeros((7, 7))
    A_aug[:6, :6] = A
    A_aug[6, 1] = -1.0                   # zdot = e = -(y - r)
    B_aug = np.vstack([B, np.zeros((1, 3))])
    return A_aug - B_aug @ K


@dataclass(frozen=True)
class GainSchedule:
    """Gain tables indexed ``[pitch][roll]`` like the firmware's, and the models behind them."""

    roll_deg: np.ndarray     # (nr,) grid, increasing
    pitch_deg: np.ndarray    # (np,)
    insertion: float         # m, the insertion the models were taken at
    k_roll: np.ndarray       # (np, nr, 2)  [Kp, Kd]
    k_pitch: np.ndarray      # (np, nr, 3)  [Kp, Kd, Ki]
    u_hold: np.ndarray       # (np, nr, 2)  holding PWM of roll, pitch (gravity feedforward)
    ff_pitch: np.ndarray     # (np, nr, 2)  [F_v, F_a] of the pitch feedforward
    A: np.ndarray            # (np, nr, 6, 6) SI
    B: np.ndarray            # (np, nr, 6, 3)
    A_cl: np.ndarray         # (np, nr, 7, 7)
    weights: Weights = field(default_factory=Weights)
    friction: FrictionCompensation | None = None   # sliding-friction feedforward of the model's drive


def check_grid(values, what: str, lower: float, upper: float) -> np.ndarray:
    """``values`` (deg) as a strictly increasing grid inside the joint range ``[lower, upper]`` (rad)."""
    values = as_numbers(values, f"{what}_deg", f"the {what} grid in degrees")
    if values.ndim != 1 or values.size < 2 or not np.all(np.isfinite(values)):
        raise RcmKinError(f"the {what} grid needs at least 2 finite values (deg)")
    if np.any(np.diff(values) <= 0):
        raise RcmKinError(f"the {what} grid must be strictly increasing: {values.tolist()}")
    lo, hi = np.degrees([lower, upper])
    if values[0] < lo - 1e-9 or values[-1] > hi + 1e-9:
        raise RcmKinError(f"the {what} grid leaves the joint range [{lo:g}, {hi:g}] deg: {values.tolist()}")
    return values


def parse_grid(grid: str) -> tuple[np.ndarray, np.ndarray]:
    """``thesis`` or ``ROLLS:PITCHES`` with comma-separated degrees, e.g. ``-20,0,20:-15,0,15``,
    inside the PSM's joint range (its URDF limits)."""
    if grid == "thesis":
        return np.array(THESIS_ROLL_DEG), np.array(THESIS_PITCH_DEG)
    parts = grid.split(":")
    if len(parts) != 2:
        raise RcmKinError(f"`grid` is 'thesis' or ROLLS:PITCHES in degrees (e.g. -20,0,20:-15,0,15), got '{grid}'",
                          parameter="grid")
    try:
        rolls, pitches = ([float(v) for v in p.split(",")] for p in parts)
    except ValueError:
        raise RcmKinError(f"`grid` values must be numbers, got '{grid}'", parameter="grid") from None
    psm = load_robot("psm")
    limits = {joint: (lo, hi) for joint, lo, hi in zip(psm.actuated, psm.lower, psm.upper)}
    return check_grid(rolls, "roll", *limits["roll"]), check_grid(pitches, "pitch", *limits["pitch"])


def schedule_gains(model: DrivenDynamics, roll_deg, pitch_deg, insertion: float = HOME_INSERTION,
                   weights: Weights | None = None, friction_ramp_deg_s: float = DEFAULT_RAMP_DEG_S) -> GainSchedule:
    """Design the gain tables on a roll x pitch grid (degrees) at one insertion (m). The schedule
    also carries the friction-compensation feedforward of the model's sliding Coulomb friction
    (the Coulomb level the design leaves out), ramped over ``friction_ramp_deg_s`` (deg/s)."""
    if check_model(model).coulomb:
        raise RcmKinError("design on the model without Coulomb friction: driven_dynamics(..., coulomb=False)")
    if weights is not None and not isinstance(weights, Weights):
        raise RcmKinError(f"`weights` is a Weights, got {type(weights).__name__}", parameter="weights")
    weights = weights or Weights()
    ramp = as_number(friction_ramp_deg_s, "friction_ramp_deg_s", "deg/s", 0.0, MAX_RAMP_DEG_S, low_open=True)
    friction = friction_compensation(model.drive, ramp)
    insertion = as_number(insertion, "insertion", "m", model.lower[INSERTION], model.upper[INSERTION])
    roll_deg = check_grid(roll_deg, "roll", model.lower[ROLL], model.upper[ROLL])
    pitch_deg = check_grid(pitch_deg, "pitch", model.lower[PITCH], model.upper[PITCH])
    if roll_deg.size * pitch_deg.size > MAX_SCHEDULE_POSES:
        raise WorkLimitError(f"a gain schedule of {roll_deg.size} x {pitch_deg.size} poses: at most "
                             f"{MAX_SCHEDULE_POSES:,} (201 x 201, about a minute of design)",
                             requested=roll_deg.size * pitch_deg.size, limit=MAX_SCHEDULE_POSES,
                             parameter=("roll_deg", "pitch_deg"))
    P, R = np.meshgrid(pitch_deg, roll_deg, indexing="ij")
    Q = np.column_stack([np.radians(R.ravel()), np.radians(P.ravel()), np.full(R.size, insertion)])
    grid = linearize_grid(model, Q)
    shape = P.shape
    k_roll = np.array([roll_gains(a, b, weights) for a, b in zip(grid.A, grid.B)])
    k_pitch = np.array([pitch_gains(a, b, weights) for a, b in zip(grid.A, grid.B)])
    ff = np.array([pitch_feedforward(a, b) for a, b in zip(grid.A, grid.B)])
    A_cl = np.array([closed_loop_matrix(a, b, kr, kp) for a, b, kr, kp in zip(grid.A, grid.B, k_roll, k_pitch)])
    return GainSchedule(roll_deg, pitch_deg, float(insertion),
                        k_roll.reshape(*shape, 2), k_pitch.reshape(*shape, 3), grid.u0[:, :2].reshape(*shape, 2),
                        ff.reshape(*shape, 2), grid.A.reshape(*shape, 6, 6), grid.B.reshape(*shape, 6, 3),
                        A_cl.reshape(*shape, 7, 7), weights, friction)


def scheduled_gains(schedule: GainSchedule, roll_deg: float, pitch_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """``(k_roll, k_pitch)`` the firmware uses at a pose (degrees)."""
    if not (np.isfinite(roll_deg) and np.isfinite(pitch_deg)):
        raise RcmKinError("the scheduling angles must be finite (deg)")
    return (bilinear(schedule.roll_deg, schedule.pitch_deg, schedule.k_roll, roll_deg, pitch_deg),
            bilinear(schedule.roll_deg, schedule.pitch_deg, schedule.k_pitch, roll_deg, pitch_deg))

"""Stability of the scheduled loops: at the grid points and with frozen interpolated gains in
between, in continuous time and as the 400 Hz firmware runs them.

The firmware loop (thesis Listings 4.15 and the pitch LQI) samples every ``period`` s, takes
the velocity as the backward difference of the measured angle, filters the roll's with an EMA
``vf = alpha vf + (1 - alpha) v_raw``, integrates the pitch error by Euler, and holds the PWM
over the period (zero-order hold). :func:`firmware_loop_matrix` is that loop as one linear map.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcm_kin.control.gain_schedule import (
    GainSchedule,
    closed_loop_matrix,
    scheduled_gains,
)
from rcm_kin.control.linearization import linearize_grid, zero_order_hold
from rcm_kin.dynamics.state_space import DrivenDynamics
from rcm_kin.hardware import FIRMWARE_PERIOD, INSERTION_KP, ROLL_FILTER


def firmware_loop_matrix(A: np.ndarray, B: np.ndarray, k_roll, k_pitch, period: float = FIRMWARE_PERIOD,
                         roll_filter: float = ROLL_FILTER, insertion_kp: float = INSERTION_KP,
                         discrete: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """The sampled closed loop ``xi[k+1] = Phi xi[k]`` (10, 10) about an equilibrium (reference at
    the equilibrium). ``xi = [x (6, SI); previous roll, pitch angle (rad); filtered roll velocity
    (rad/s); pitch error integral (rad s)]``. Gains in firmware units and signs. ``discrete``: the
    model's ``(Ad, Bd)`` over ``period`` when already known (:func:`zero_order_hold` of ``A, B``)."""
    Ad, Bd = zero_order_hold(A, B, period) if discrete is None else discrete
    # u[k] = G xi[k]: with y = x[:2], raw velocity (y - y_prev) / T, vf' = a vf + (1 - a) raw_roll,
    # z' = z - y_pitch T (e = -y), and u = -(Kp e + Kd v [+ Ki z']).
    a = roll_filter
    vf_new = np.zeros(10)                               # vf' as a row on xi
    vf_new[0], vf_new[6], vf_new[8] = (1 - a) / period, -(1 - a) / period, a
    z_new = np.zeros(10)
    z_new[9], z_new[1] = 1.0, -period
    raw_pitch = np.zeros(10)
    raw_pitch[1], raw_pitch[7] = 1 / period, -1 / period
    kr, kp = np.degrees(k_roll), np.degrees(k_pitch)   # firmware gains per degree -> per radian
    G = np.zeros((3, 10))
    G[0] = kr[0] * np.eye(10)[0] - kr[1] * vf_new
    G[1] = kp[0] * np.eye(10)[1] - kp[1] * raw_pitch - kp[2] * z_new
    G[2, 2] = -insertion_kp
    Phi = np.zeros((10, 10))
    Phi[:6] = np.hstack([Ad, np.zeros((6, 4))]) + Bd @ G
    Phi[6, 0], Phi[7, 1] = 1.0, 1.0                     # y_prev' = y
    Phi[8], Phi[9] = vf_new, z_new
    return Phi


@dataclass(frozen=True)
class StabilitySurvey:
    """Stability over a dense roll x pitch grid with the gains the firmware would use there."""

    roll_deg: np.ndarray          # (n_r,)
    pitch_deg: np.ndarray         # (n_p,)
    max_real: np.ndarray          # (n_p, n_r) largest real part of the continuous closed loop, 1/s
    spectral_radius: np.ndarray   # (n_p, n_r) of the 400 Hz firmware loop (< 1: stable)
    min_damping: np.ndarray       # (n_p, n_r) smallest damping ratio of the firmware loop's poles,
                                  # taken as s = ln(z) / T (filter and sampling lags included)

    @property
    def stable(self) -> bool:
        return bool(np.all(self.max_real < 0) and np.all(self.spectral_radius < 1))

    def weakest(self) -> dict:
        """The slowest firmware-loop mode (largest spectral radius) and the least damped one, and where."""
        j, i = np.unravel_index(np.argmax(self.spectral_radius), self.spectral_radius.shape)
        jd, id_ = np.unravel_index(np.argmin(self.min_damping), self.min_damping.shape)
        return {"spectral_radius": float(self.spectral_radius[j, i]), "roll_deg": float(self.roll_deg[i]),
                "pitch_deg": float(self.pitch_deg[j]), "max_real": float(self.max_real.max()),
                "min_damping": float(self.min_damping[jd, id_]), "min_damping_roll_deg": float(self.roll_deg[id_]),
                "min_damping_pitch_deg": float(self.pitch_deg[jd])}


def damping_ratios(eigenvalues: np.ndarray) -> np.ndarray:
    """Damping ratio ``-Re(s) / |s|`` of continuous-time eigenvalues ``s`` (1/s); the survey's
    grid loop computes it directly rather than through a python-control system per point."""
    return -eigenvalues.real / np.abs(eigenvalues)


def survey_poses(schedule: GainSchedule, points: int):
    """The ``points x points`` grid spanning the schedule's, at its insertion: rolls and pitches
    (deg, (points,)), their meshes ``R``, ``P`` (pitch rows, roll columns) and the poses ``Q``
    ((points^2, 3): rad, rad, m) in the meshes' row order."""
    rolls = np.linspace(schedule.roll_deg[0], schedule.roll_deg[-1], points)
    pitches = np.linspace(schedule.pitch_deg[0], schedule.pitch_deg[-1], points)
    P, R = np.meshgrid(pitches, rolls, indexing="ij")
    Q = np.column_stack([np.radians(R.ravel()), np.radians(P.ravel()), np.full(R.size, schedule.insertion)])
    return rolls, pitches, R, P, Q


def stability_survey(model: DrivenDynamics, schedule: GainSchedule, points: int = 41,
                     gains=None) -> StabilitySurvey:
    """Frozen-gain stability on a ``points x points`` grid spanning the schedule's grid.

    ``gains(roll_deg, pitch_deg) -> (k_roll, k_pitch)`` defaults to the schedule's bilinear
    interpolation; pass another to judge other tables (e.g. the thesis's) on the same models."""
    gains = gains or (lambda r, p: scheduled_gains(schedule, r, p))
    rolls, pitches, R, P, Q = survey_poses(schedule, points)
    grid = linearize_grid(model, Q)
    max_real, radius, min_damping = (np.empty(R.size) for _ in range(3))
    for k, (r, p, A, B) in enumerate(zip(R.ravel(), P.ravel(), grid.A, grid.B)):
        k_roll, k_pitch = gains(r, p)
        max_real[k] = np.linalg.eigvals(closed_loop_matrix(A, B, k_roll, k_pitch)).real.max()
        z = np.linalg.eigvals(firmware_loop_matrix(A, B, k_roll, k_pitch))
        radius[k] = np.abs(z).max()
        z = z[np.abs(z) > 1e-9]                      # deadbeat modes (the stored previous angles)
        min_damping[k] = damping_ratios(np.log(z.astype(complex)) / FIRMWARE_PERIOD).min()
    shape = P.shape
    return StabilitySurvey(rolls, pitches, max_real.reshape(shape), radius.reshape(shape), min_damping.reshape(shape))

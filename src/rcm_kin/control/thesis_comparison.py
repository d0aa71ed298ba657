"""The thesis's measured gain tables (Tables 4.4-4.8) beside the model-based ones.

The tables and the identified roll model are quoted in :mod:`rcm_kin.thesis`.

The thesis prints its tables with rows labelled pitch -20/0/+20 and columns roll -15/0/+15, but
identified them on the grid pitch {-15, 0, 15} x roll {-20, 0, 20}; the rows here are that grid's
pitches and the columns its rolls (``THESIS_PITCH_DEG`` x ``THESIS_ROLL_DEG``). Units and signs
are the firmware's: PWM/deg, PWM/(deg/s), PWM/(deg s), ``u = -(Kp e + Kd v [+ Ki int e])``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcm_kin.control.gain_schedule import (
    THESIS_PITCH_DEG,
    THESIS_ROLL_DEG,
    GainSchedule,
    schedule_gains,
)
from rcm_kin.control.stability import StabilitySurvey, stability_survey
from rcm_kin.dynamics.state_space import DrivenDynamics
from rcm_kin.firmware_rules import bilinear
from rcm_kin.thesis import K_PITCH, K_ROLL, ROLL_TF

# the thesis's tables and identified roll model (sources: rcm_kin.thesis)
THESIS_K_ROLL = K_ROLL
THESIS_K_PITCH = K_PITCH
THESIS_ROLL_TF = ROLL_TF


@dataclass(frozen=True)
class ThesisComparison:
    model: GainSchedule              # ours, on the thesis grid
    ours: StabilitySurvey            # our interpolated gains on our models
    thesis: StabilitySurvey          # the thesis's interpolated gains on our models
    thesis_damping_flipped: StabilitySurvey   # the thesis's gains with Kd of the damping sign
    thesis_on_identified_roll: np.ndarray     # closed-loop poles of the thesis (0,0) roll gains on G(s)


def thesis_roll_closed_loop(kp: float, kd: float) -> np.ndarray:
    """Poles of ``u = -(Kp (r - y) + Kd ydot)`` on the thesis's identified roll model:
    ``den(s) - num(s) (Kp - Kd s) = 0``."""
    num, den = THESIS_ROLL_TF
    return np.roots(np.polysub(den, np.polymul(num, [-kd, kp])))


def compare_with_thesis(model: DrivenDynamics, points: int = 21,
                        schedule: GainSchedule | None = None) -> ThesisComparison:
    """Our schedule on the thesis grid and the thesis's tables, surveyed on ``model`` over ``points``
    per axis. ``schedule``: ours when already designed on ``model`` (``schedule_gains(model,
    THESIS_ROLL_DEG, THESIS_PITCH_DEG)``, e.g. :func:`rcm_kin.simulation.experiments.psm_schedule`),
    default designed here."""
    if schedule is None:
        schedule = schedule_gains(model, THESIS_ROLL_DEG, THESIS_PITCH_DEG)

    def thesis(r, p, flip=1.0):
        k_roll = bilinear(schedule.roll_deg, schedule.pitch_deg, THESIS_K_ROLL, r, p)
        k_pitch = bilinear(schedule.roll_deg, schedule.pitch_deg, THESIS_K_PITCH, r, p)
        return k_roll * [1, flip], k_pitch * [1, flip, 1]

    return ThesisComparison(
        schedule, stability_survey(model, schedule, points), stability_survey(model, schedule, points, thesis),
        stability_survey(model, schedule, points, lambda r, p: thesis(r, p, -1.0)),
        thesis_roll_closed_loop(*THESIS_K_ROLL[1, 1]))


@dataclass(frozen=True)
class ScheduleContrast:
    """The numbers that set the model-based schedule and the thesis's tables apart."""

    gain_spread: float             # largest relative spread (peak to peak / mean) of a model Kp over the grid
    stiffness_ratio: float         # least ratio of closed-loop (Kp times drive gain) to gravity stiffness
    model_roll_damping: float      # 1/s, the model's roll velocity damping at the grid's centre
    model_ki: float                # PWM/(deg s), mean model pitch Ki
    model_integral_time: float     # s, mean model pitch Kp / Ki
    thesis_kp_roll: tuple[float, float]    # PWM/deg, least and largest roll Kp of the thesis tables
    thesis_kp_pitch: tuple[float, float]   # PWM/deg, least and largest pitch Kp
    thesis_ki: float               # PWM/(deg s), mean pitch Ki of the thesis tables
    thesis_integrator_pole: float  # 1/s, about -Ki/Kp of the thesis's pitch at the grid's centre
    thesis_roll_damping: float     # 1/s, damping term of the identified roll model's denominator
    thesis_roll_zero: float        # rad/s, the identified roll model's zero (right half-plane if > 0)


def schedule_contrast(schedule: GainSchedule) -> ScheduleContrast:
    """What differs between ``schedule`` (model-based) and the thesis's tables, in numbers."""
    kp = (schedule.k_roll[..., 0], schedule.k_pitch[..., 0])        # roll, pitch (PWM/deg)
    # closed-loop stiffness Kp B (per rad) against the gravity stiffness dv/dq of the open loop, per axis
    stiffness = [np.min(np.degrees(k) * np.abs(schedule.B[..., 3 + a, a]) / np.abs(schedule.A[..., 3 + a, a]))
                 for a, k in enumerate(kp)]
    centre = (len(schedule.pitch_deg) // 2, len(schedule.roll_deg) // 2)
    num, den = ROLL_TF
    thesis_centre = (K_PITCH.shape[0] // 2, K_PITCH.shape[1] // 2)
    return ScheduleContrast(
        gain_spread=float(max(np.ptp(k) / np.abs(k).mean() for k in kp)),
        stiffness_ratio=float(min(stiffness)),
        model_roll_damping=float(-schedule.A[centre][3, 3]),
        model_ki=float(schedule.k_pitch[..., 2].mean()),
        model_integral_time=float(np.mean(schedule.k_pitch[..., 0] / schedule.k_pitch[..., 2])),
        thesis_kp_roll=(float(K_ROLL[..., 0].min()), float(K_ROLL[..., 0].max())),
        thesis_kp_pitch=(float(K_PITCH[..., 0].min()), float(K_PITCH[..., 0].max())),
        thesis_ki=float(K_PITCH[..., 2].mean()),
        thesis_integrator_pole=float(-K_PITCH[thesis_centre][2] / K_PITCH[thesis_centre][0]),
        thesis_roll_damping=float(den[1]),
        thesis_roll_zero=float(-num[1] / num[0]))

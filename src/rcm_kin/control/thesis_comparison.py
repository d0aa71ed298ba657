"""The thesis's measured gain tables (Tables 4.4-4.8) beside the model-based ones.

The thesis prints its tables with rows labelled pitch -20/0/+20 and columns roll -15/0/+15, but
identified them on the grid pitch {-15, 0, 15} x roll {-20, 0, 20}; the rows here are that grid's
pitches and the columns its rolls (``THESIS_PITCH_DEG`` x ``THESIS_ROLL_DEG``). Units and signs
are the firmware's: PWM/deg, PWM/(deg/s), PWM/(deg s), ``u = -(Kp e + Kd v [+ Ki int e])``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcm_kin.control.gain_schedule import (THESIS_PITCH_DEG, THESIS_ROLL_DEG, GainSchedule, bilinear,
                                           schedule_gains)
from rcm_kin.control.stability import StabilitySurvey, stability_survey
from rcm_kin.dynamics.state_space import DrivenDynamics

THESIS_K_ROLL = np.stack([np.array([[135.41, 135.41, 137.91], [136.23, 132.23, 130.12], [137.36, 135.77, 131.78]]),
                          np.array([[0.6527, 1.0829, 0.43766], [0.6854, 0.7588, 0.4810], [0.6579, 1.0788, 0.42543]])],
                         axis=-1)
THESIS_K_PITCH = np.stack([
    np.array([[188.07, 195.37, 191.11], [161.41, 166.32, 167.01], [153.37, 155.56, 151.23]]),
    np.array([[0.3124, 0.3256, 0.3154], [0.3671, 0.3671, 0.3272], [0.3643, 0.3374, 0.3576]]),
    np.array([[0.143744, 0.185649, 0.164665], [0.135649, 0.153566, 0.155123], [0.124432, 0.155649, 0.134566]])],
    axis=-1)
# The thesis's identified roll model at (0, 0): G(s) = (4.0426 s - 8.3312) / (s^2 + 6.1202 s + 16.288), PWM -> deg.
THESIS_ROLL_TF = (np.array([4.0426, -8.3312]), np.array([1.0, 6.1202, 16.288]))


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


def compare_with_thesis(model: DrivenDynamics, points: int = 21) -> ThesisComparison:
    schedule = schedule_gains(model, THESIS_ROLL_DEG, THESIS_PITCH_DEG)

    def thesis(r, p, flip=1.0):
        k_roll = bilinear(schedule.roll_deg, schedule.pitch_deg, THESIS_K_ROLL, r, p)
        k_pitch = bilinear(schedule.roll_deg, schedule.pitch_deg, THESIS_K_PITCH, r, p)
        return k_roll * [1, flip], k_pitch * [1, flip, 1]

    return ThesisComparison(
        schedule, stability_survey(model, schedule, points), stability_survey(model, schedule, points, thesis),
        stability_survey(model, schedule, points, lambda r, p: thesis(r, p, -1.0)),
        thesis_roll_closed_loop(*THESIS_K_ROLL[1, 1]))

"""Which part of a law does the work: the chosen design with one structure taken out at a time, and
the thesis law with its damping gain zeroed or flipped, each judged by the tuning's objective on the
same draws (:func:`structure_variants`, :func:`judge_variants`).

The design's structures: the sliding-friction compensation (both axes, or the roll's alone), the
gravity feedforward, the pitch's model-inverse feedforward, the pitch integral (Ki at its least,
1 PWM/(deg s)), and damping the velocity error instead of the measured velocity. Each variant is the
same tables with one part removed, not re-tuned: it says what the part is worth inside this design.

The thesis law runs here as the state-feedback law with the thesis's tables
(:func:`thesis_as_state_feedback`: measured-velocity damping, no feedforward; the same commands as
:class:`~rcm_kin.simulation.controllers.ThesisController`, a declared twin held to it by the tests),
so its Kd can be changed: 0 (no velocity term), and flipped to damping (``-Kd``, the hardware sign).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from rcm_kin.control.gain_schedule import GainSchedule, scheduled_gains
from rcm_kin.errors import RcmKinError
from rcm_kin.simulation.controllers import StateFeedbackController
from rcm_kin.thesis import K_PITCH, K_ROLL
from rcm_kin.tuning.design import tuned_schedule
from rcm_kin.tuning.draws import DrawSet
from rcm_kin.tuning.objective import Outcomes, evaluate, score, tracking_score
from rcm_kin.tuning.optimise import tuned_controller

DESIGN_VARIANTS = {
    "without friction compensation": {"roll_friction_pwm": 0.0, "pitch_friction_pwm": 0.0},
    "without the roll's friction compensation": {"roll_friction_pwm": 0.0},
    "without the pitch feedforward": {"pitch_feedforward": 0.0},
    "pitch Ki at its least (1)": {"pitch_ki": 1.0},
}
FLAG_VARIANTS = {"without gravity feedforward": {"gravity": False},
                 "damping the measured velocity": {"track_velocity": False}}
THESIS_KD = {"thesis law": 1.0, "thesis law, Kd 0": 0.0, "thesis law, Kd flipped (damping)": -1.0}


def table_gains(schedule: GainSchedule, roll_deg: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """A schedule's five loop gains (m, 5) at poses (deg), interpolated bilinearly as the firmware does."""
    return np.array([np.r_[scheduled_gains(schedule, r, p)] for r, p in zip(roll_deg, pitch_deg)])


def thesis_as_state_feedback(base: GainSchedule, kd_scale: float = 1.0, name: str = "thesis law"):
    """The thesis law as :class:`StateFeedbackController` on ``base``'s grid (the thesis grid): the
    thesis's tables (Kd of both axes times ``kd_scale``), measured-velocity damping, no feedforward."""
    schedule = dataclasses.replace(base, k_roll=K_ROLL * np.array([1.0, kd_scale]),
                                   k_pitch=K_PITCH * np.array([1.0, kd_scale, 1.0]),
                                   ff_pitch=np.zeros_like(base.ff_pitch), friction=None)
    return StateFeedbackController(schedule, scheduled=True, gravity=False, track_velocity=False, friction=False,
                                   name=name), schedule


def structure_variants(base: GainSchedule, values: dict[str, float]) -> dict[str, tuple[object, GainSchedule]]:
    """``name -> (controller, its schedule)`` of every variant of the module's notes."""
    out = {}
    for name, change in DESIGN_VARIANTS.items():
        schedule = tuned_schedule(base, {**values, **change})
        out[f"design {name}"] = (tuned_controller(schedule), schedule)
    schedule = tuned_schedule(base, values)
    for name, flags in FLAG_VARIANTS.items():
        out[f"design {name}"] = (dataclasses.replace(tuned_controller(schedule), **flags), schedule)
    for name, scale in THESIS_KD.items():
        out[name] = thesis_as_state_feedback(base, scale, name)
    return out


def table_radius(schedule: GainSchedule, draws: DrawSet) -> float:
    """The largest frozen-loop spectral radius of ``schedule``'s tables over every pose of every draw
    (the draws share their grid of poses: the gains are interpolated once)."""
    if not draws.draws:
        return np.nan
    first = draws.draws[0].loops
    gains = table_gains(schedule, first.roll_deg, first.pitch_deg)
    for d in draws.draws:
        same = np.array_equal(d.loops.roll_deg, first.roll_deg) and np.array_equal(d.loops.pitch_deg, first.pitch_deg)
        if not same:
            raise RcmKinError("the draws' stability grids differ: build them in one DrawSet", parameter="draws")
    return max(float(d.loops.spectral_radius(gains).max()) for d in draws.draws)


def judge_variants(base: GainSchedule, values: dict[str, float], draws: DrawSet,
                   thesis: Outcomes) -> dict[str, dict]:
    """Each variant on ``draws``: its score against ``thesis`` (the thesis law's outcomes there), the
    frozen loop's worst spectral radius (once per distinct set of tables: a feedforward or a flag
    leaves the loop as it is), its unstable runs and its outcome summary."""
    out, radii = {}, {}
    for name, (controller, schedule) in structure_variants(base, values).items():
        outcomes = evaluate(controller, draws)
        key = np.r_[schedule.k_roll.ravel(), schedule.k_pitch.ravel()].tobytes()
        if key not in radii:
            radii[key] = table_radius(schedule, draws)
        radius = radii[key]
        out[name] = {"score": score(outcomes, thesis, radius), "tracking_score": tracking_score(outcomes, thesis),
                     "spectral_radius": radius, "unstable_runs": int(outcomes.unstable.sum()),
                     "summary": outcomes.summary()}
    return out

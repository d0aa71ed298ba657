"""The whole design: tune a fixed and a scheduled gain set, judge both beside the thesis law and the
LQR/LQI schedule on the tuning draws and on draws the tuning never saw, and choose.

:func:`design_study`:

1. draws ``samples`` plants from seed ``seed`` (:func:`~rcm_kin.tuning.draws.build_draws`, the
   frozen loops on the full ``points x points`` grid) and ``samples`` more from ``check_seed``;
2. tunes the ``fixed`` space on the first ``tune_samples`` draws of the first set (their loops on a
   9 x 9 grid), from the LQR/LQI design (``scheduled-friction``) and hand-picked starts, then the
   four pose slopes of the proportional gains (the ``slopes`` space) with the fixed winner's gain set
   held, from slopes of zero: the scheduled design is the fixed one plus what scheduling adds, so
   the two differ only in the scheduling. Each search within its share of ``budget_s``;
3. judges the thesis law, the LQR/LQI schedule and both tuned designs on both draw sets in full:
   tracking outcomes, the frozen 400 Hz loop's spectral radius at every pose of every draw (the
   thesis law's through its state-feedback twin), and the issue's criteria (:func:`criteria`);
4. chooses (:func:`choose`) the scheduled design only where it beats the fixed one by at least
   :data:`SCHEDULE_MARGIN` of the score on all the tuning seed's draws; the held-out draws are not
   used to choose, only to check the choice; otherwise fixed gains are as good on this robot, and
   the study says so;
5. judges the chosen design with one structure taken out at a time, and the thesis law with its Kd
   zeroed or flipped (:mod:`rcm_kin.tuning.structures`), on both draw sets.

A :class:`DesignStudy` knows how to say itself (:meth:`~DesignStudy.to_dict`) and draw itself
(:meth:`~DesignStudy.plot`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.errors import RcmKinError
from rcm_kin.model.loading import urdf_dir
from rcm_kin.simulation.controllers import ThesisController, make_controller
from rcm_kin.simulation.experiments import psm_schedule
from rcm_kin.tuning.design import DesignSpace, bounds_excess, tuned_schedule
from rcm_kin.tuning.draws import LOOP_POINTS, DrawSet, build_draws
from rcm_kin.tuning.objective import RADIUS_LIMIT, Outcomes, evaluate, saturation_excess, score, tracking_score
from rcm_kin.tuning.optimise import Search, loop_radius, tune, tuned_controller
from rcm_kin.tuning.structures import judge_variants, table_radius, thesis_as_state_feedback

SHIPPED_STUDY = urdf_dir() / "psm_tuned" / "tuning.json"   # the study behind the shipped tuned gains
SCHEDULE_MARGIN = 0.02      # the scheduled design must score 2 % below the fixed one on both draw sets
TUNE_POINTS = 9             # poses per axis of the stability grid while tuning (every 5th of 41)
FIXED_SHARE = 0.6           # of the time budget, for the fixed space (the rest: the slopes)
SLOPES_POPSIZE = 8          # members per slope in the slopes search (4 dimensions: 32 a generation)
CONTROLLERS = ("thesis", "lqr", "fixed", "scheduled")
HAND_START = {"roll_kp": 300.0, "roll_kd": -5.0, "pitch_kp": 150.0, "pitch_kd": -1.0, "pitch_ki": 300.0,
              "roll_friction_pwm": 10.0, "pitch_friction_pwm": 10.0, "friction_ramp_deg_s": 2.0,
              "pitch_feedforward": 1.0}


def lqr_start(schedule: GainSchedule) -> dict[str, float]:
    """The LQR/LQI schedule's design at the grid's centre as a point of the fixed space (its
    friction compensation and model-inverse feedforward as designed)."""
    j, i = schedule.pitch_deg.size // 2, schedule.roll_deg.size // 2
    kr, kp = schedule.k_roll[j, i], schedule.k_pitch[j, i]
    fc = schedule.friction
    return {"roll_kp": kr[0], "roll_kd": kr[1], "pitch_kp": kp[0], "pitch_kd": kp[1], "pitch_ki": kp[2],
            "roll_friction_pwm": fc.pwm[0], "pitch_friction_pwm": fc.pwm[1], "friction_ramp_deg_s": fc.ramp_deg_s,
            "pitch_feedforward": 1.0}


@dataclass(frozen=True)
class Judged:
    """One controller on one draw set: outcomes, the frozen loop's worst spectral radius over every
    pose and draw (NaN for a law the linear loop does not model), and its score against the thesis."""

    outcomes: Outcomes
    radius: float
    score: float
    tracking_score: float         # the score without the constraints' penalties


@dataclass(frozen=True)
class DesignStudy:
    """What :func:`design_study` found (see the module's notes)."""

    seeds: tuple[int, int]                     # tuning draws, held-out draws
    samples: int
    tune_samples: int
    rejected: tuple[int, int]                  # drawn sets the holds ruled out, per draw set
    searches: dict[str, Search]                # "fixed", "scheduled"
    judged: dict[str, dict[str, Judged]]       # draw set ("tuning", "held_out") -> controller -> judged
    chosen: str                                # "fixed" or "scheduled"
    schedule: GainSchedule                     # the chosen design's tables (gain_schedule.h, gains.json)
    points: int
    structures: dict[str, dict[str, dict]]     # draw set -> variant -> judged (:mod:`.structures`)

    designs: dict[str, dict[str, float]]       # "fixed", "scheduled": the designs judged
    budget_s: float = np.nan                   # the search's time budget (s)
    generations: int | None = None             # and its limit of generations per search

    @property
    def values(self) -> dict[str, float]:
        return self.designs[self.chosen]

    def criteria(self) -> dict[str, dict[str, bool]]:
        """Per draw set, the issue's done-when criteria for the chosen design against the thesis law."""
        return {name: criteria(sets[self.chosen], sets["thesis"]) for name, sets in self.judged.items()}

    def to_dict(self) -> dict:
        """The study as plain data (SI and firmware units as named in the keys)."""
        def judged(j: Judged) -> dict:
            o = j.outcomes
            per_draw = {"max_error_deg": o.max_error_deg, "mean_error_deg": o.mean_error_deg,
                        "saturation_s": o.saturation_s, "unstable": o.unstable}
            return {"summary": o.summary(), "spectral_radius": None if np.isnan(j.radius) else j.radius,
                    "score": j.score, "tracking_score": j.tracking_score,
                    "per_draw": {k: np.where(np.isnan(v), None, v).tolist() if v.dtype.kind == "f" else v.tolist()
                                 for k, v in per_draw.items()},
                    "per_draw_axes": ["draw", "experiment", "axis (roll, pitch)"]}
        searches = {kind: {"values": s.best.values, "score_tuning_subset": s.best.score,
                           "evaluations": s.minimum.evaluations, "generations": len(s.minimum.history),
                           "wall_s": s.minimum.wall_s, "stopped": s.minimum.stopped, "runs_per_s": s.runs_per_s,
                           "history": list(s.minimum.history),
                           "space": [vars(p) for p in s.space.parameters]} for kind, s in self.searches.items()}
        scores = {name: {c: j.score for c, j in sets.items()} for name, sets in self.judged.items()}
        return {"seeds": {"tuning": self.seeds[0], "held_out": self.seeds[1]}, "samples": self.samples,
                "tune_samples": self.tune_samples, "rejected_as_inconsistent_with_holds": list(self.rejected),
                "stability_points": self.points, "radius_limit": RADIUS_LIMIT, "chosen": self.chosen,
                "experiments": list(self.judged["tuning"]["thesis"].outcomes.experiments),
                "schedule_margin": SCHEDULE_MARGIN, "scores": scores, "values": self.values,
                "criteria": self.criteria(), "searches": searches, "structures": self.structures,
                "budget_s": self.budget_s, "generations_limit": self.generations,
                "designs": self.designs,
                "judged": {name: {c: judged(j) for c, j in sets.items()} for name, sets in self.judged.items()}}


def criteria(design: Judged, thesis: Judged) -> dict[str, bool]:
    """The issue's criteria of ``design`` against ``thesis`` on one draw set: median max and mean
    errors at or below the thesis's on both axes and experiments; the worst draw's max error no
    worse; no unstable run; the frozen loop stable at every pose of every draw; saturation no more."""
    d, t = design.outcomes, thesis.outcomes
    with np.errstate(invalid="ignore"):
        median = np.all(np.nanmedian(d.max_error_deg, 0) <= np.nanmedian(t.max_error_deg, 0)) and \
            np.all(np.nanmedian(d.mean_error_deg, 0) <= np.nanmedian(t.mean_error_deg, 0))
        worst = np.all(np.nanmax(d.max_error_deg, 0) <= np.nanmax(t.max_error_deg, 0))
    return {"median_at_or_below_thesis": bool(median), "worst_no_worse": bool(worst),
            "no_unstable_run": not bool(d.unstable.any()), "frozen_loop_stable": bool(design.radius < 1.0),
            "saturation_no_more": saturation_excess(d, t) == 0.0}


def judge_all(designs: dict[str, dict[str, float]], lqr: GainSchedule, draws: DrawSet) -> dict[str, Judged]:
    """The thesis law, the LQR/LQI schedule (``scheduled-friction``) and the tuned ``designs`` on
    ``draws``, each scored against the thesis law there with every penalty (the thesis law's frozen
    loop through its twin's tables, :func:`~rcm_kin.tuning.structures.thesis_as_state_feedback`)."""
    thesis = evaluate(ThesisController(), draws)

    def judged(outcomes: Outcomes, radius: float, bounds: float = 0.0) -> Judged:
        return Judged(outcomes, radius, score(outcomes, thesis, radius, bounds), tracking_score(outcomes, thesis))

    out = {"thesis": judged(thesis, table_radius(thesis_as_state_feedback(lqr)[1], draws)),
           "lqr": judged(evaluate(make_controller("scheduled-friction", lqr), draws), table_radius(lqr, draws))}
    for kind, values in designs.items():
        out[kind] = judged(evaluate(tuned_controller(tuned_schedule(lqr, values)), draws), loop_radius(values, draws),
                           bounds_excess(values))
    return out


def choose(scores: dict[str, float], margin: float = SCHEDULE_MARGIN) -> str:
    """``"scheduled"`` where the scheduled design's score on the tuning seed's draws (``scores``, by
    controller) is at least ``margin`` below the fixed one's, else ``"fixed"``."""
    return "scheduled" if scores["scheduled"] <= (1 - margin) * scores["fixed"] else "fixed"


def design_study(params: DriveParameters, samples: int = 64, seed: int = 0, check_seed: int = 1,
                 tune_samples: int = 16, budget_s: float = 300.0, workers: int = 1, points: int = LOOP_POINTS,
                 progress: bool = False, generations: int | None = None) -> DesignStudy:
    """The design study of the module's notes on the PSM with ``params`` (``generations``: each search
    also stops after that many generations, :func:`~rcm_kin.tuning.optimise.minimise`)."""
    if seed == check_seed:
        raise RcmKinError(f"the held-out draws need a seed of their own, got {seed} for both", parameter="check_seed")
    if not 1 <= tune_samples <= samples:
        raise RcmKinError(f"tune_samples is 1 to samples ({samples}), got {tune_samples}", parameter="tune_samples")
    if (points - 1) % (TUNE_POINTS - 1):
        raise RcmKinError(f"points - 1 must be a multiple of {TUNE_POINTS - 1} (e.g. 41), got {points}",
                          parameter="points")
    lqr = psm_schedule(params)
    sets = {"tuning": build_draws(params, samples, seed, points, progress=progress),
            "held_out": build_draws(params, samples, check_seed, points, progress=progress)}
    tuning = sets["tuning"].subset(tune_samples, TUNE_POINTS)
    fixed = tune(lqr, tuning, DesignSpace("fixed"), seed, budget_s * FIXED_SHARE,
                 start=(lqr_start(lqr), HAND_START), workers=workers, progress=progress, generations=generations)
    slopes = DesignSpace("slopes")
    scheduled = tune(lqr, tuning, slopes, seed, budget_s * (1 - FIXED_SHARE), SLOPES_POPSIZE,
                     start=({p.name: 0.0 for p in slopes.parameters},), workers=workers, progress=progress,
                     generations=generations, held=fixed.best.values)
    searches = {"fixed": fixed, "scheduled": scheduled}
    designs = {kind: s.best.values for kind, s in searches.items()}
    judged = {name: judge_all(designs, lqr, draws) for name, draws in sets.items()}
    chosen = choose({name: j.score for name, j in judged["tuning"].items()})
    structures = {name: judge_variants(lqr, designs[chosen], draws, judged[name]["thesis"].outcomes)
                  for name, draws in sets.items()}
    return DesignStudy((seed, check_seed), samples, tune_samples, (sets["tuning"].rejected, sets["held_out"].rejected),
                       searches, judged, chosen, tuned_schedule(lqr, designs[chosen]), points, structures, designs,
                       budget_s, generations)


def read_study(path=None) -> dict:
    """A design study as data (:meth:`DesignStudy.to_dict`; default :data:`SHIPPED_STUDY`, the study
    ``rcm-kin schedule psm --tune`` wrote for the shipped tuned gains)."""
    path = SHIPPED_STUDY if path is None else path
    try:
        data = json.loads(open(path).read())
    except OSError as exc:
        raise RcmKinError(f"cannot read the design study {path}: {exc.strerror}", parameter="path") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RcmKinError(f"{path}: not a design study (not JSON: {exc})", parameter="path") from None
    missing = [k for k in ("chosen", "judged", "experiments", "scores", "values") if k not in data] \
        if isinstance(data, dict) else ["an object"]
    if missing:
        raise RcmKinError(f"{path}: not a design study of rcm-kin schedule psm --tune (no {', '.join(missing)})",
                          parameter="path")
    return data

"""Prediction bands of the identified drive train: what the model says a log does, and how sure it is.

The band is an ensemble's, simulated on the log (:func:`rcm_kin.identification.drive_train.predict_log`,
the recorded PWM or the recorded law, no refitting), its members the product of

- the parameter sets: the file's own and its leave-one-log-out folds (``[uncertainty.folds]``, each
  fitted on every log but one: how far the choice of logs moves the parameters; the local
  Gauss-Newton errors are far narrower than that spread);
- each parameter the logs do not determine (``[uncertainty.ranges]``), put in every set at the ends
  and the middle of its range (the middle geometric where the range spans a decade or more);
- the presliding spring's state before the record, which the log does not record: its force at the
  first rest (``preload`` F_p, :func:`rcm_kin.identification.drive_train.at_rest`, which keeps the
  rest a static equilibrium by shifting the gravity by as much) taken at the values the other logs
  show (:func:`best_preloads`: each log's best preload under the set; ``[uncertainty.preloads]`` in
  a drive file), or evenly over [-1, 1] where none is known.

Pointwise, the band is the ``(1 - level) / 2`` and ``(1 + level) / 2`` quantiles of the members'
angles, the median between them, each member counted once. It is a spread of the model, not a
calibrated probability: how often it holds the measured angle is what :class:`PredictionBand`
measures (``coverage``, ``final_inside``), from the sample before the step of a step log.

The ensemble spans what the parameters and the preload leave open, not what the model class
misses; that is measured on the logs themselves (conformal calibration): each log's widening score
(:func:`widening_score`) is how far, in units of the median's travel, its band built without it must
widen to hold ``level`` of its samples, and a band is widened by the conformal quantile of the
scores of logs it was not fitted on (:func:`widened`; ``[uncertainty.discrepancy]`` in a drive file,
:func:`calibrated_bands` in the cross-validation), the logs inside the calibrated poses only.

A record that starts outside the calibrated poses (``[uncertainty.hull]``) is flagged
``extrapolated``: the band is not widened (it carries the drive train's uncertainty, not the
rigid-body model's away from where it was calibrated), so there it is not a confident number.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from rcm_kin.dynamics.stick_slip import AxisFriction, AxisPlant
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.drive_train import AxisLog, fit_percent, predict_log
from rcm_kin.identification.figures import prediction_figure
from rcm_kin.identification.log_checks import stick_time
from rcm_kin.identification.telemetry import step_index
from rcm_kin.statics.holding_band import check_level, conformal_half_width

LEVEL = 0.9          # default band level
PRELOADS = 9         # presliding preloads evenly over [-1, 1] when the logs' own are not known
PRELOAD_TOLERANCE = 1e-3   # a log's best preload, to this fraction of the slip force
MIN_SCALE = np.radians(0.05)   # rad: the travel scale of a widening where the median barely moves
HULL_TOLERANCE = np.radians(0.1)   # rad: a pose this close to the calibrated hull is inside it (the holds'
                                   # poses are the logs' own, to the encoder: roll 0.009 deg a count)
FLAT = 1e-6          # a preload whose cost varies less than this (relative) over [-1, 1] does not show
RANGE_VALUES = 3     # values of each undetermined parameter: its ends and middle
DECADE = 10.0        # a range with hi / lo at least this is spread geometrically
WORKERS = 4          # threads simulating the members at most (the kernels release the GIL)


@dataclass(frozen=True)
class Ensemble:
    """The members of a band (parameter set, preload) and where their spread comes from: per source
    the number of values it takes (``sources``), and the values of each undetermined parameter (SI)."""

    members: tuple[tuple[AxisFriction, float], ...]
    sources: dict[str, int]
    undetermined: dict[str, tuple[float, ...]] = field(default_factory=dict)


def range_values(lo: float, hi: float, count: int = RANGE_VALUES) -> np.ndarray:
    """``count`` values over [lo, hi], both ends included: log-spaced when the range spans a decade
    or more (``hi / lo >= 10``, ``lo > 0``), else evenly."""
    if lo > 0 and hi / lo >= DECADE:
        return np.geomspace(lo, hi, count)
    return np.linspace(lo, hi, count)


def ensemble(sets, ranges: dict[str, tuple[float, float]] | None = None, preloads: int = PRELOADS,
             folds: int | None = None, preload_values=None) -> Ensemble:
    """Every parameter set of ``sets`` with each parameter of ``ranges`` (name: (lo, hi), SI) at
    :func:`range_values`, at the presliding preloads ``preload_values`` (fractions of the slip force in
    [-1, 1], e.g. :func:`best_preloads`) or, without them (None or empty), at ``preloads`` preloads evenly over
    [-1, 1] (1: the relaxed rest only). ``folds``: how many of ``sets`` are fold sets (the rest the
    file's own); None: all of them."""
    sets = list(sets)
    if not sets:
        raise RcmKinError("a prediction band needs at least one parameter set", parameter="sets")
    if preloads < 1:
        raise RcmKinError(f"a prediction band needs at least 1 preload, got {preloads}", parameter="preloads")
    ranges = ranges or {}
    values = {n: tuple(float(v) for v in range_values(*ranges[n])) for n in sorted(ranges)}
    variants = [dict()]
    for name, vs in values.items():
        variants = [{**v, name: x} for v in variants for x in vs]
    if preload_values is None or len(preload_values) == 0:
        loads = np.linspace(-1.0, 1.0, preloads) if preloads > 1 else np.zeros(1)
    else:
        loads = np.asarray(preload_values, dtype=float).ravel()
        if not np.all((loads >= -1.0) & (loads <= 1.0)):
            raise RcmKinError("presliding preloads are fractions of the slip force in [-1, 1], got "
                              f"{preload_values!r}"[:200], parameter="preload_values")
    members = tuple((replace(s, **v), float(p)) for s in sets for v in variants for p in loads)
    folds = len(sets) if folds is None else folds
    sources = {"fold_sets": folds, "own_set": len(sets) - folds, **{n: len(v) for n, v in values.items()},
               "preload": int(loads.size)}
    return Ensemble(members, sources, values)


def best_preload(friction: AxisFriction, plant: AxisPlant, log: AxisLog) -> float:
    """The preload (fraction of the slip force, in [-1, 1]) under which ``friction`` predicts
    ``log`` best (least squares from the sample before the step; bounded scalar search), or NaN
    where the log does not show it (the cost flat within :data:`FLAT` over -1, 0, 1 and the
    optimum: a spring that only deflects moves the same from any preload, its force and the
    gravity's shift cancelling)."""
    start = scored_from(log)

    def cost(p: float) -> float:
        return float(np.sum((predict_log(friction, plant, log, preload=p)[start:] - log.measured[start:]) ** 2))

    best = float(minimize_scalar(cost, bounds=(-1.0, 1.0), method="bounded", options={"xatol": PRELOAD_TOLERANCE}).x)
    costs = [cost(p) for p in (-1.0, 0.0, 1.0, best)]
    return float("nan") if max(costs) - min(costs) <= FLAT * max(costs) else best


def best_preloads(friction: AxisFriction, plants, logs,
                  hull: dict[str, tuple[float, float]] | None = None) -> tuple[float, ...]:
    """The step logs' best preloads (:func:`best_preload`) under ``friction``: how far from relaxed
    the spring's state at a first rest was, as the logs show it. Closed-loop records
    (their rest is the loop's) are left out, and so are logs outside the calibrated poses ``hull``
    (:func:`hull_check`): a preload is also a gravity offset (``at_rest``), so there it would
    measure the rigid-body model's error away from its calibration, not the spring; so are logs that
    do not show a preload (:func:`best_preload` NaN). None left: ``()`` (an :func:`ensemble` given
    no values spreads its preloads evenly over [-1, 1])."""
    return tuple(named_preloads(friction, plants, logs, hull).values())


def named_preloads(friction: AxisFriction, plants, logs,
                   hull: dict[str, tuple[float, float]] | None = None) -> dict[str, float]:
    """:func:`best_preloads` by log name."""
    best = {g.name: best_preload(friction, p, g) for p, g in zip(plants, logs) if g.law is None and calibrated(g, hull)}
    return {n: b for n, b in best.items() if np.isfinite(b)}


def calibrated(log: AxisLog, hull: dict[str, tuple[float, float]] | None) -> bool:
    """Whether ``log`` stays inside the calibrated poses ``hull`` (:func:`hull_check` over its
    measured angles; no hull: every log)."""
    return not (hull and hull_check(log, hull, (log.measured.min(), log.measured.max()))[0])


def simulate_members(members, plant: AxisPlant, log: AxisLog, workers: int | None = None) -> np.ndarray:
    """The angle (rad) each member ``(friction, preload)`` predicts over ``log``
    (:func:`predict_log`), as rows; on up to ``workers`` threads (default: the cores, at most
    :data:`WORKERS`)."""
    members = list(members)
    workers = workers or min(WORKERS, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                             else (os.cpu_count() or 1))
    chunks = [members[k::workers] for k in range(workers)]

    def run(chunk):
        return [predict_log(f, plant, log, preload=p) for f, p in chunk]

    with ThreadPoolExecutor(workers) as pool:
        done = list(pool.map(run, chunks))
    out = np.empty((len(members), log.measured.size))
    for k, rows in enumerate(done):
        if rows:
            out[k::workers] = rows
    return out


def scored_from(log: AxisLog) -> int:
    """The first sample a band is scored from: the sample before the step of a step log (the rest
    before it says nothing about the drive train), the first of a closed-loop record."""
    if log.law is not None:
        return 0
    try:
        return max(step_index(log.pwm) - 1, 0)
    except RcmKinError:
        return 0


@dataclass(frozen=True)
class PredictionBand:
    """A pointwise band of the predicted angle (rad) over a log, its median, and how it holds the
    measured angle from sample ``start`` on (:func:`scored_from`)."""

    name: str
    joint: str
    time: np.ndarray          # (n,) s
    measured: np.ndarray      # (n,) rad
    median: np.ndarray        # (n,) rad
    lower: np.ndarray         # (n,) rad, the (1 - level) / 2 quantile
    upper: np.ndarray         # (n,) rad, the (1 + level) / 2 quantile
    level: float
    members: int
    sources: dict[str, int]                         # per source of uncertainty, how many values it took
    undetermined: dict[str, tuple[float, ...]]      # the undetermined parameters and their values (SI)
    start: int = 0
    extrapolated: bool = False
    note: str = ""                                  # why extrapolated (or that the poses were not checked)
    widened: bool = False

    @property
    def coverage(self) -> float:
        """Fraction of the samples from ``start`` whose measured angle is inside the band."""
        s = slice(self.start, None)
        return float(np.mean((self.measured[s] >= self.lower[s]) & (self.measured[s] <= self.upper[s])))

    @property
    def final_inside(self) -> bool:
        return bool(self.lower[-1] <= self.measured[-1] <= self.upper[-1])

    @property
    def end_width(self) -> float:
        """Width of the band at the last sample, rad."""
        return float(self.upper[-1] - self.lower[-1])

    @property
    def travel(self) -> float:
        """Measured travel from ``start`` to the end, rad."""
        return float(self.measured[-1] - self.measured[self.start])

    @property
    def end_width_over_travel(self) -> float | None:
        """:attr:`end_width` over the measured travel's size (None when the log did not move)."""
        return self.end_width / abs(self.travel) if self.travel else None

    @property
    def median_fit(self) -> float:
        """NRMSE fit (%) of the median from ``start`` on."""
        return fit_percent(self.measured[self.start:], self.median[self.start:])

    def scores(self) -> dict:
        """The band's scores on its log (what ``identify --cv`` reports per left-out log): coverage,
        final angle inside, end width over travel, the median's fit (%), final error (deg) and stick
        time (s) beside the measured one."""
        period = float(self.time[1] - self.time[0]) if self.time.size > 1 else 0.0
        return {"coverage": self.coverage, "final_inside": self.final_inside,
                "end_width_over_travel": self.end_width_over_travel, "median_fit_percent": self.median_fit,
                "median_final_error_deg": float(np.degrees(self.median[-1] - self.measured[-1])),
                "travel_deg": float(np.degrees(self.travel)), "stick_time_s": stick_time(self.measured, period),
                "median_stick_time_s": stick_time(self.median, period), "members": self.members,
                "extrapolated": self.extrapolated, "widened": self.widened, "note": self.note}

    def as_dict(self) -> dict:
        """The band in degrees, its scores and sources (the ``predict --band`` JSON's ``band``)."""
        def deg(x):
            return np.degrees(x).tolist()
        return {"level": self.level, "lower": deg(self.lower), "upper": deg(self.upper), "median": deg(self.median),
                "coverage": self.coverage, "final_inside": self.final_inside,
                "end_width_over_travel": self.end_width_over_travel, "end_width_deg": float(np.degrees(self.end_width)),
                "travel_deg": float(np.degrees(self.travel)), "median_fit_percent": self.median_fit,
                "scored_from_s": float(self.time[self.start]), "members": self.members, "sources": dict(self.sources),
                "undetermined": {n: list(v) for n, v in self.undetermined.items()},
                "extrapolated": self.extrapolated, "widened": self.widened, "note": self.note}

    def plot(self, path: str | Path, predicted: np.ndarray | None = None, title: str = "") -> Path:
        """PNG of the measured angle, ``predicted`` (rad; default the median) and the band shaded."""
        curve = self.median if predicted is None else predicted
        label = f"{self.level:.0%} band ({self.members} members)" + (", extrapolated" if self.extrapolated else "")
        return prediction_figure(self.time, np.degrees(self.measured), np.degrees(curve), path,
                                 title or f"{self.name}, {self.joint}",
                                 band=(np.degrees(self.lower), np.degrees(self.upper)), band_label=label,
                                 median=np.degrees(self.median) if predicted is not None else None)


def hull_check(log: AxisLog, hull: dict[str, tuple[float, float]] | None,
               reach: tuple[float, float]) -> tuple[bool, str]:
    """Whether ``log`` leaves the calibrated poses ``hull`` (joint: (lo, hi) rad): the other joints
    where the record holds them, its own joint over ``reach`` (the lowest and highest angle measured
    or in the band's median); and a note saying where (or that the file has no hull)."""
    if not hull:
        return False, "the file has no [uncertainty.hull]: the poses were not checked against a calibration"
    outside = []
    for k, joint in enumerate(("roll", "pitch")):
        if joint not in hull:
            continue
        lo, hi = hull[joint]
        a, b = reach if joint == log.joint else (log.pose[k], log.pose[k])
        if a < lo - HULL_TOLERANCE or b > hi + HULL_TOLERANCE:
            at = f"{np.degrees(a):.2f}..{np.degrees(b):.2f}" if a != b else f"{np.degrees(a):.2f}"
            outside.append(f"{joint} {at} deg outside the calibrated {np.degrees(lo):.1f}..{np.degrees(hi):.1f} deg")
    if not outside:
        return False, ""
    return True, ("; ".join(outside) + ": extrapolated, the band not widened (it carries the drive train's "
                  "uncertainty and what the model missed inside its calibration, not the rigid-body model's "
                  "error outside it)")


def band_of(trajectories: np.ndarray, log: AxisLog, level: float = LEVEL, sources: dict[str, int] | None = None,
            undetermined: dict | None = None, hull: dict[str, tuple[float, float]] | None = None) -> PredictionBand:
    """The pointwise band of ``trajectories`` (rows: members' angles over ``log``, rad) at ``level``."""
    level = check_level(level)
    trajectories = np.asarray(trajectories, dtype=float)
    if not np.all(np.isfinite(trajectories)):
        bad = int(np.sum(~np.all(np.isfinite(trajectories), axis=1)))
        raise RcmKinError(f"{log.name}: {bad} of the band's {len(trajectories)} members predict a non-finite "
                          f"{log.joint} angle (is the [uncertainty] of the file sensible?)")
    lower, median, upper = np.quantile(trajectories, [(1 - level) / 2, 0.5, (1 + level) / 2], axis=0)
    reach = (min(median.min(), log.measured.min()), max(median.max(), log.measured.max()))
    extrapolated, note = hull_check(log, hull, reach)
    return PredictionBand(log.name, log.joint, log.time, log.measured, median, lower, upper, level,
                          len(trajectories), dict(sources or {"members": len(trajectories)}), dict(undetermined or {}),
                          scored_from(log), extrapolated, note)


def prediction_band(sets, plant: AxisPlant, log: AxisLog, level: float = LEVEL,
                    ranges: dict[str, tuple[float, float]] | None = None, preloads: int = PRELOADS,
                    hull: dict[str, tuple[float, float]] | None = None, folds: int | None = None,
                    preload_values=None) -> PredictionBand:
    """The band of the parameter sets ``sets`` (:class:`AxisFriction`; ``folds`` of them fold sets,
    default all) over ``log`` on ``plant``: the :func:`ensemble` (at ``preload_values`` when given)
    simulated (:func:`simulate_members`) and its quantiles
    (:func:`band_of`). Sets fitted without ``log`` give its left-out band."""
    level = check_level(level)
    members = ensemble(sets, ranges, preloads, folds, preload_values)
    return band_of(simulate_members(members.members, plant, log), log, level, members.sources,
                   members.undetermined, hull)


def left_out_band(fold: AxisFriction, inner, plant: AxisPlant, log: AxisLog, others, level: float = LEVEL,
                  ranges: dict[str, tuple[float, float]] | None = None,
                  hull: dict[str, tuple[float, float]] | None = None) -> PredictionBand:
    """The band of a log left out of the fit: its fold's set ``fold`` (fitted without ``log``) and
    that fold's inner sets ``inner`` (each fitted without ``log`` and one other), the preloads the
    other logs show under ``fold`` (``others``: their (plant, log) pairs, :func:`best_preloads`),
    and the undetermined ``ranges``: nothing in it was fitted on ``log``."""
    plants, logs = zip(*others) if others else ((), ())
    sets = [fold, *inner]
    loads = best_preloads(fold, plants, logs, hull) if log.law is None else None    # a loop's rest is its own
    return prediction_band(sets, plant, log, level, ranges, PRELOADS, hull, folds=len(sets), preload_values=loads)


def travel_scale(band: PredictionBand) -> float:
    """The scale (rad) ``band`` widens in: its median's travel from ``start``, at least :data:`MIN_SCALE`."""
    return max(abs(float(band.median[-1] - band.median[band.start])), MIN_SCALE)


def widening_score(band: PredictionBand) -> float:
    """How far ``band`` must widen on each side, in :func:`travel_scale` units, to hold ``level`` of
    its log's measured samples from ``start``: the ``level`` quantile of their distances outside it."""
    s = slice(band.start, None)
    outside = np.maximum(np.maximum(band.lower[s] - band.measured[s], band.measured[s] - band.upper[s]), 0.0)
    return float(np.quantile(outside, band.level)) / travel_scale(band)


def widened(band: PredictionBand, scores) -> PredictionBand:
    """``band`` widened on each side by the conformal quantile of ``scores`` (other logs'
    :func:`widening_score`, :func:`rcm_kin.statics.holding_band.conformal_half_width`) times its
    :func:`travel_scale`: what the model class missed on logs the band was not fitted on."""
    w = conformal_half_width(scores, band.level) * travel_scale(band)
    return replace(band, lower=band.lower - w, upper=band.upper + w, widened=True)


def calibrated_bands(folds, inner, plants, logs, level: float = LEVEL,
                     ranges: dict[str, tuple[float, float]] | None = None,
                     hull: dict[str, tuple[float, float]] | None = None) -> tuple[tuple[PredictionBand, ...], tuple]:
    """Per log ``k``: its :func:`left_out_band` (``folds[k]``, ``inner[k]``: the sets fitted without
    ``k``, and without ``k`` and each other log ``j`` in log order) widened by the scores of the other
    logs ``j`` under the bands of their inner sets (fitted without ``k`` and ``j``, the preloads of
    the rest): nothing of log ``k`` enters its band. Also each log's own score under its left-out
    band, by log name (the drive file's ``[uncertainty.discrepancy]``). Logs outside the calibrated
    poses ``hull`` give no score and are not widened (there the miss is the rigid-body model's
    extrapolation: their bands say "extrapolated" instead), nor do closed-loop records (their rests
    are the loop's). The calibration is not fully left-out: an inner set is polished from the fold's
    (:mod:`rcm_kin.identification.cross_validation`), which saw ``j``, so its score leans low; and
    ``j`` is scored under its one inner set, ``k`` under the fold's and every inner set."""
    pairs = list(zip(plants, logs))
    out, own = [], []
    for k, (plant, log) in enumerate(pairs):
        others = pairs[:k] + pairs[k + 1:]
        base = left_out_band(folds[k], inner[k], plant, log, others, level, ranges, hull)
        scores = []
        for i, (p, g) in enumerate(others):
            if g.law is not None or not calibrated(g, hull):
                continue
            rest = others[:i] + others[i + 1:]
            loads = best_preloads(inner[k][i], [q for q, _ in rest], [h for _, h in rest], hull)
            scores.append(widening_score(prediction_band([inner[k][i]], p, g, level, ranges, PRELOADS, hull,
                                                         preload_values=loads)))
        out.append(widened(base, scores) if scores and not base.extrapolated else base)
        if log.law is None and calibrated(log, hull):
            own.append((log.name, widening_score(base)))
    return tuple(out), tuple(own)

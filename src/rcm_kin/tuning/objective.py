"""How a controller does over a :class:`~rcm_kin.tuning.draws.DrawSet`, and the tuning's objective.

:func:`evaluate` runs a controller on every draw and experiment in the compiled closed loop
(:func:`rcm_kin.robustness.task.closed_loop_run`: a run that diverges or leaves the joint range is
*unstable*) and gathers, per draw, experiment and axis, the largest and the mean absolute tracking
error from ``skip`` s on (degrees) and the time at the PWM limit (s): an :class:`Outcomes`.

The objective (:func:`score`) compares two :class:`Outcomes` on the same draws, a design's and a
baseline's (the thesis law's): for every experiment and axis, three ratios design / baseline, of the
90th percentile of the max error, of the median of the mean error and of the worst draw's max
error; the objective is the mean of the twelve ratios plus the largest (so no criterion is traded
away for the others), below 2 where the design beats the baseline on every one
(:func:`tracking_score`). Constraints add penalties of at least :data:`PENALTY`: any unstable run
(ten times that); a frozen-gain 400 Hz loop with a spectral radius of :data:`RADIUS_LIMIT` or more at
any pose of any draw's grid; more time at the PWM limit than the baseline's, per experiment and
axis, summed over the draws; gains beyond their bounds.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from rcm_kin.robustness.task import closed_loop_run
from rcm_kin.simulation.loop import tracking_metrics
from rcm_kin.tuning.draws import DrawSet

AXES = ("roll", "pitch")
SKIP_S = 1.0             # s: the thesis's sinusoid starts at full speed; statistics from 1 s
RADIUS_LIMIT = 0.999     # frozen 400 Hz loop: |z| below this at every pose (about 0.4 1/s of decay)
PENALTY = 100.0
SATURATION_SLACK_S = 0.0025   # one firmware period per experiment and axis


@dataclass(frozen=True)
class Outcomes:
    """Per draw (n), experiment (the draw set's order) and axis (roll, pitch): ``max_error_deg``,
    ``mean_error_deg`` (NaN where the run was unstable), ``saturation_s``; ``unstable`` (n, experiments)."""

    experiments: tuple[str, ...]
    max_error_deg: np.ndarray       # (n, e, 2)
    mean_error_deg: np.ndarray      # (n, e, 2)
    saturation_s: np.ndarray        # (n, e, 2)
    unstable: np.ndarray            # (n, e) bool

    def summary(self) -> dict:
        """Per experiment and axis: median, 90th percentile and worst of the max error, median and
        worst of the mean error (over the stable runs), the saturation summed over draws, and the
        unstable runs."""
        out = {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)      # no stable run: NaN, written as None
            for k, experiment in enumerate(self.experiments):
                out.update(self._entries(k, experiment))
        return out

    def _entries(self, k: int, experiment: str) -> dict:
        """:meth:`summary`'s entries of experiment ``k`` (called with NaN warnings silenced)."""
        out = {}
        for a, axis in enumerate(AXES):
            mx, mean = self.max_error_deg[:, k, a], self.mean_error_deg[:, k, a]
            out[f"{experiment}.{axis}"] = _finite_or_none({
                "median_max_deg": float(np.nanmedian(mx)), "p90_max_deg": float(np.nanpercentile(mx, 90)),
                "worst_max_deg": float(np.nanmax(mx)), "median_mean_deg": float(np.nanmedian(mean)),
                "worst_mean_deg": float(np.nanmax(mean)), "saturation_s": float(self.saturation_s[:, k, a].sum()),
                "unstable_runs": int(self.unstable[:, k].sum())})
        return out


def _finite_or_none(entry: dict) -> dict:
    """NaN (no stable run) as None: strict JSON."""
    return {k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in entry.items()}


def evaluate(controller, draws: DrawSet, skip: float = SKIP_S) -> Outcomes:
    """``controller`` (a :class:`~rcm_kin.simulation.controllers.Controller`) on every draw and
    experiment of ``draws`` (see the module's notes)."""
    experiments = tuple(draws.references)
    n, e = len(draws), len(experiments)
    mx, mean, sat = np.full((n, e, 2), np.nan), np.full((n, e, 2), np.nan), np.zeros((n, e, 2))
    unstable = np.zeros((n, e), dtype=bool)
    for i, d in enumerate(draws.draws):
        for k, experiment in enumerate(experiments):
            result = closed_loop_run(d.plant, controller, draws.references[experiment], draws.settings,
                                     d.holds[experiment])
            if result is None:
                unstable[i, k] = True
                continue
            metrics = tracking_metrics(result, skip)
            for a, axis in enumerate(AXES):
                m = metrics[axis]
                mx[i, k, a], mean[i, k, a], sat[i, k, a] = m.max_error_deg, m.mean_error_deg, m.saturation_s
    return Outcomes(experiments, mx, mean, sat, unstable)


def ratios(design: Outcomes, baseline: Outcomes) -> np.ndarray:
    """The twelve ratios design / baseline (experiment, axis, [p90 max, median mean, worst max]),
    each statistic over the stable runs (NaN where an outcome has none)."""
    return statistics(design) / statistics(baseline)


def statistics(o: Outcomes) -> np.ndarray:
    """(experiment, axis, [p90 max, median mean, worst max]) over the stable runs."""
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)          # an outcome without a stable run: NaN
        return np.stack([np.nanpercentile(o.max_error_deg, 90, axis=0), np.nanmedian(o.mean_error_deg, axis=0),
                         np.nanmax(o.max_error_deg, axis=0)], axis=-1)


def saturation_excess(design: Outcomes, baseline: Outcomes) -> float:
    """Seconds at the PWM limit beyond the baseline's, summed over draws, experiments and axes
    (each experiment and axis allowed :data:`SATURATION_SLACK_S` more)."""
    excess = design.saturation_s.sum(axis=0) - baseline.saturation_s.sum(axis=0) - SATURATION_SLACK_S
    return float(np.clip(excess, 0, None).sum())


def tracking_score(design: Outcomes, baseline: Outcomes) -> float:
    """The mean plus the largest of the twelve :func:`ratios` (the stable runs'; 2 for the baseline
    itself), without the constraints' penalties."""
    r = ratios(design, baseline)
    r = r[np.isfinite(r)]
    return float(r.mean() + r.max()) if r.size else np.inf


def score(design: Outcomes, baseline: Outcomes, radius: float, bounds: float = 0.0) -> float:
    """The objective of the module's notes (lower is better): :func:`tracking_score` plus each
    violated constraint's penalty, added (so more violations always cost more): unstable runs
    ``10 PENALTY (1 + their fraction)``, above any stable design's; a frozen-loop ``radius`` (the
    largest over the draws' grids) at :data:`RADIUS_LIMIT` or more; saturation beyond the
    baseline's; ``bounds`` > 0, gains beyond their bounds (:func:`~rcm_kin.tuning.design.bounds_excess`)."""
    tracking = tracking_score(design, baseline)
    value = tracking if np.isfinite(tracking) else 10 * PENALTY
    if design.unstable.any():
        value += 10 * PENALTY * (1 + design.unstable.mean())
    if radius >= RADIUS_LIMIT:
        value += PENALTY + 1000 * (radius - RADIUS_LIMIT)
    excess = saturation_excess(design, baseline)
    if excess > 0:
        value += PENALTY + excess
    if bounds > 0:
        value += PENALTY + 100 * bounds
    return float(value)

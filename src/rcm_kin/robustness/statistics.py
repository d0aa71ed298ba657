"""The distributions over the samples of a robustness run, per controller and axis.

Percentiles are NumPy's default (linear interpolation between order statistics); ``worst`` is
the largest value, but for the damping ratio, where it is the smallest. Error statistics are taken over the
samples whose run was stable (an unstable run has no error to speak of: it counts in
``unstable_fraction``); a figure no sample has is NaN (``null`` in JSON).

A sample is *unstable* for a controller when its simulated run (the nonlinear plant with the
friction that sticks, PWM saturated) diverged (its state left the finite numbers) or left the
joints' range (:func:`rcm_kin.robustness.task.closed_loop_run`). The linear verdicts are reported beside it, on the
roll and pitch modes (:func:`rcm_kin.robustness.task.loop_margins`): the 400 Hz firmware loop
linearised about some pose of the stability grid with a pole on or outside
the unit circle (spectral radius >= 1; sampling and filter lags included), and the continuous
loop with a pole in the closed right half-plane. Both linearise the smooth model without
Coulomb friction (as the design does), so a loop the friction holds can be linearly unstable
and still track: the two figures answer different questions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcm_kin.robustness.sampling import Uncertain, drive_train_sources
from rcm_kin.robustness.task import SampleOutcome, Study
from rcm_kin.simulation.loop import AXES


@dataclass(frozen=True)
class Spread:
    """Distribution of one figure over the samples (its units)."""

    p5: float
    median: float
    p95: float
    worst: float                 # the largest (the smallest for a figure where less is worse)

    def as_dict(self) -> dict:
        """The four figures; None (JSON ``null``) for one no sample has (NaN)."""
        return {k: None if np.isnan(v) else v for k, v in vars(self).items()}


def spread(values, worst=np.max) -> Spread:
    """:class:`Spread` of the finite ``values`` (all NaN when there are none); ``worst`` picks the
    worst of them (``np.max``, or ``np.min`` where less is worse)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return Spread(np.nan, np.nan, np.nan, np.nan)
    p5, median, p95 = np.percentile(v, [5.0, 50.0, 95.0])
    return Spread(float(p5), float(median), float(p95), float(worst(v)))


@dataclass(frozen=True)
class AxisRobustness:
    max_error_deg: Spread        # largest |reference - measured| of a run, deg
    mean_error_deg: Spread       # mean |reference - measured| of a run, deg
    saturated_fraction: float    # of the samples, those whose command reached the PWM limit

    def as_dict(self) -> dict:
        return {"max_error_deg": self.max_error_deg.as_dict(), "mean_error_deg": self.mean_error_deg.as_dict(),
                "saturated_fraction": self.saturated_fraction}


@dataclass(frozen=True)
class ControllerRobustness:
    axes: dict[str, AxisRobustness]        # roll, pitch
    unstable_fraction: float               # the simulated run diverged or left the joint range (module notes)
    continuous_max_real: Spread            # 1/s, largest real part of the continuous loop over the grid
    firmware_spectral_radius: Spread       # largest |z| of the 400 Hz loop's roll/pitch modes over the grid
    firmware_min_damping: Spread           # least damping ratio of those modes over the grid
    continuous_unstable_fraction: float    # max real part >= 0
    firmware_unstable_fraction: float      # spectral radius >= 1
    has_margin: bool                       # False: a law the linear survey does not model (PID)

    def as_dict(self) -> dict:
        out = {axis: a.as_dict() for axis, a in self.axes.items()}
        out["unstable_fraction"] = self.unstable_fraction
        out["stability"] = ({"continuous_max_real": self.continuous_max_real.as_dict(),
                             "firmware_spectral_radius": self.firmware_spectral_radius.as_dict(),
                             "firmware_min_damping": self.firmware_min_damping.as_dict(),
                             "continuous_unstable_fraction": self.continuous_unstable_fraction,
                             "firmware_unstable_fraction": self.firmware_unstable_fraction}
                            if self.has_margin else None)
        return out


@dataclass(frozen=True)
class Robustness:
    """A robustness run's result: the distributions and what was drawn."""

    experiment: str
    seed: int
    uncertain: tuple[Uncertain, ...]
    controllers: dict[str, ControllerRobustness]
    outcomes: tuple[SampleOutcome, ...]    # per sample, in sample order

    @property
    def samples(self) -> int:
        return len(self.outcomes)

    def as_dict(self) -> dict:
        return {"samples": self.samples, "seed": self.seed, "experiment": self.experiment,
                "controllers": {name: c.as_dict() for name, c in self.controllers.items()},
                "uncertainty": {u.name: u.as_dict() for u in self.uncertain},
                "drive_train_source": drive_train_sources(self.uncertain)}


def controller_robustness(outcomes: list[SampleOutcome], c: int) -> ControllerRobustness:
    """The distributions of controller number ``c`` over ``outcomes``."""
    max_error = np.array([o.max_error_deg[c] for o in outcomes])
    mean_error = np.array([o.mean_error_deg[c] for o in outcomes])
    saturated = np.array([o.saturated[c] for o in outcomes])
    unstable = np.array([o.unstable[c] for o in outcomes])
    max_real = np.array([o.max_real[c] for o in outcomes])
    radius = np.array([o.spectral_radius[c] for o in outcomes])
    damping = np.array([o.min_damping[c] for o in outcomes])
    axes = {axis: AxisRobustness(spread(max_error[:, a]), spread(mean_error[:, a]), float(saturated[:, a].mean()))
            for a, axis in enumerate(AXES)}
    has_margin = bool(np.all(np.isfinite(radius)))
    return ControllerRobustness(axes, float(unstable.mean()), spread(max_real), spread(radius),
                                spread(damping, worst=np.min),
                                float(np.mean(max_real >= 0)) if has_margin else np.nan,
                                float(np.mean(radius >= 1)) if has_margin else np.nan, has_margin)


def summarise(study: Study, seed: int, outcomes: list[SampleOutcome]) -> Robustness:
    """The run's result from its samples' outcomes (any order)."""
    outcomes = sorted(outcomes, key=lambda o: o.index)
    return Robustness(study.experiment, seed, study.uncertain,
                      {name: controller_robustness(outcomes, c) for c, name in enumerate(study.controllers)},
                      tuple(outcomes))

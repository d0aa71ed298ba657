"""Leave-one-hold-out residuals of the calibration, and the left-out coverage of its holding bands.

A holding band (:mod:`rcm_kin.statics.holding_band`) is the nominal holding PWM -+ a conformal
quantile of leave-one-hold-out residuals: hold ``k`` measured minus hold ``k`` predicted by the
calibration (:func:`~rcm_kin.identification.calibration.calibrate`) refitted on every hold but
``k``. Its honesty is checked the same way it is built (:func:`left_out_coverage`): for each hold
``k``, the band built without it (the calibration refitted without ``k``, the half-width from the
residuals of the other holds, each refitted with both ``k`` and itself left out), and whether hold
``k``'s measured PWM lies inside. The nested refits are the fits without each pair of holds,
``n (n - 1) / 2`` small least-squares problems, each started from the fit on all holds.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from itertools import combinations
from typing import TYPE_CHECKING

import numpy as np

from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.identification.calibration import CalibrationResult, calibrate, predict_pwm
from rcm_kin.statics.holding_band import DEFAULT_LEVEL, check_level, conformal_half_width

if TYPE_CHECKING:
    from rcm_kin.model import Robot

JOINTS = ("roll", "pitch")      # the calibrated joints, the columns of every (n, 2) array here


@dataclass(frozen=True)
class BandCoverage:
    """The left-out check of the holding bands over ``n`` holds, per joint of :data:`JOINTS`
    (columns); PWM counts with the hardware sign, poses rad."""

    level: float
    sources: tuple[str, ...]
    residuals: np.ndarray        # (n, 2) leave-one-hold-out residuals, measured minus predicted
    half_width: np.ndarray       # (n, 2) hold k's band half-width, built without hold k
    inside: np.ndarray           # (n, 2) bool: hold k's measured PWM inside its left-out band
    extrapolated: np.ndarray     # (n,) bool: hold k outside the poses of the other holds
    hull: dict[str, tuple[float, float]]   # the poses of all holds, rad
    full_half_width: np.ndarray  # (2,) the band of all n residuals (what the drive file carries)

    def as_dict(self) -> dict:
        """JSON-ready (``rcm-kin calibrate --json``'s ``holding_band``): per joint by name, degrees."""
        by_joint = lambda x: {j: x[..., i].tolist() for i, j in enumerate(JOINTS)}  # noqa: E731
        return {"level": self.level, "holds": len(self.sources), "half_width_pwm": by_joint(self.full_half_width),
                "left_out_inside": {j: int(n) for j, n in zip(JOINTS, self.inside.sum(axis=0))},
                "left_out_half_width_pwm": by_joint(self.half_width), "holding_residuals_pwm": by_joint(self.residuals),
                "left_out_extrapolated": [s for s, e in zip(self.sources, self.extrapolated) if e],
                "hull_deg": {j: np.degrees(v).tolist() for j, v in self.hull.items()}}


def measured_pwm(points) -> np.ndarray:
    """(n, 2) measured holding PWM of roll and pitch."""
    return np.array([[p.pwm_roll, p.pwm_pitch] for p in points])


def hull_of(points) -> dict[str, tuple[float, float]]:
    """Per calibrated joint the least and largest pose of the holds, rad."""
    poses = np.array([[p.roll, p.pitch] for p in points])
    return {j: (float(poses[:, i].min()), float(poses[:, i].max())) for i, j in enumerate(JOINTS)}


def _refit(robot: Robot, base: DriveParameters, points, drop, start) -> DriveParameters:
    return calibrate(robot, base, [p for i, p in enumerate(points) if i not in drop], start=start).parameters


def leave_one_out_residuals(robot: Robot, base: DriveParameters, points, fit: CalibrationResult | None = None
                            ) -> np.ndarray:
    """(n, 2) PWM: each hold measured minus predicted by the calibration refitted without it (``fit``:
    the calibration on all holds, the refits' start; computed when not given)."""
    points = tuple(points)
    fit = fit or calibrate(robot, base, points)
    predicted = [predict_pwm(robot, _refit(robot, base, points, {k}, fit.values), [points[k]])[0]
                 for k in range(len(points))]
    return measured_pwm(points) - np.array(predicted)


def left_out_coverage(robot: Robot, base: DriveParameters, points, level: float = DEFAULT_LEVEL,
                      fit: CalibrationResult | None = None) -> BandCoverage:
    """The left-out check of the level-``level`` holding bands on the holds ``points`` (module doc):
    each hold's band built without it, nested, and whether the hold lies inside."""
    level = check_level(level)
    points = tuple(points)
    n = len(points)
    fit = fit or calibrate(robot, base, points)
    measured = measured_pwm(points)
    residuals = leave_one_out_residuals(robot, base, points, fit)
    nested = np.zeros((n, n, 2))            # nested[k, i]: hold i's residual with k and i left out
    for i, k in combinations(range(n), 2):
        params = _refit(robot, base, points, {i, k}, fit.values)
        r = measured[[i, k]] - predict_pwm(robot, params, [points[i], points[k]])
        nested[k, i], nested[i, k] = r
    half = np.array([[conformal_half_width(np.delete(nested[k, :, j], k), level) for j in range(2)]
                     for k in range(n)])
    hull = hull_of(points)
    poses = np.array([[p.roll, p.pitch] for p in points])
    extrapolated = np.array([any(not (np.delete(poses[:, j], k).min() <= poses[k, j] <= np.delete(poses[:, j], k).max())
                                 for j in range(2)) for k in range(n)])
    full = np.array([conformal_half_width(residuals[:, j], level) for j in range(2)])
    return BandCoverage(level, tuple(p.source for p in points), residuals, half, np.abs(residuals) <= half,
                        extrapolated, hull, full)


def with_holding_uncertainty(params: DriveParameters, coverage: BandCoverage) -> DriveParameters:
    """``params`` with ``[uncertainty.hull]`` and ``[uncertainty.holding_residuals]`` of the
    calibrated joints set from ``coverage``; its other uncertainty tables (folds, ranges) kept."""
    u = params.uncertainty
    hull = {**u.hull, **coverage.hull}
    residuals = {**u.holding_residuals, **{j: coverage.residuals[:, i] for i, j in enumerate(JOINTS)}}
    return replace(params, uncertainty=replace(u, hull=hull, holding_residuals=residuals))

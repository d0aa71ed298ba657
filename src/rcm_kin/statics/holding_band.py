"""Holding-effort bands: the PWM range a held pose needs, from the drive file's ``[uncertainty]``.

The band rule, in one place (:func:`conformal_half_width`): the half-width at level ``L`` from
``n`` leave-one-hold-out residuals ``r_i`` (``[uncertainty.holding_residuals]``, PWM counts,
measured minus predicted, each hold left out of its calibration) is the split-conformal /
jackknife+ quantile, the ``ceil((n + 1) L)``-th smallest ``|r_i|``. If that index exceeds ``n``
the largest is taken, with a warning that ``n`` holds cannot support level ``L``.

The centre is the model's nominal holding effort (:func:`rcm_kin.statics.holding_effort`'s PWM):
no bias correction, the residuals' mean is not used (on the shipped holds it is 0.01 PWM roll,
0.2 pitch: nothing to correct). The band is symmetric: ``nominal -+ half_width``.

Outside the calibrated poses (``[uncertainty.hull]``: per joint the least and largest pose the
calibration saw, rad) the band is flagged ``extrapolated``, not widened: the holds give no rate of
growth (they do not reach beyond the hull, and the one a left-out check finds outside it is 1 deg
out), so a widening rule would be a number without a source. An extrapolated band has no
coverage the holds support; the output says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rcm_kin.dynamics.drive import DriveParameters, drive_effort, resolve_drive
from rcm_kin.errors import RcmKinError, warn
from rcm_kin.model.gravity import gravity_batch
from rcm_kin.model.masses import require_masses

if TYPE_CHECKING:
    from rcm_kin.model import Robot

DEFAULT_LEVEL = 0.9


def check_level(level, parameter: str = "level") -> float:
    """A band's level: a number strictly between 0 and 1, or a one-line error (the one rule of every
    band: holding efforts here, predictions in :mod:`rcm_kin.identification.bands`)."""
    try:
        value = float(level)
    except (TypeError, ValueError):
        raise RcmKinError("the band level must be a number strictly between 0 and 1 (e.g. 0.9), got "
                          f"{str(level)[:40]!r}",
                          parameter=parameter) from None
    if not 0.0 < value < 1.0:
        raise RcmKinError(f"the band level must be strictly between 0 and 1 (e.g. 0.9), got {value:g}",
                          parameter=parameter)
    return value


def conformal_half_width(residuals, level: float = DEFAULT_LEVEL) -> float:
    """Half-width (the residuals' unit) of the level-``level`` band from ``n`` left-out residuals: the
    ``ceil((n + 1) level)``-th smallest ``|residual|``; the largest, with a warning, when that index
    exceeds ``n`` (``n`` holds cannot support the level)."""
    level = check_level(level)
    r = np.sort(np.abs(np.asarray(residuals, dtype=float).ravel()))
    if r.size == 0 or not np.all(np.isfinite(r)):
        raise RcmKinError("a band needs at least one finite left-out residual", parameter="residuals")
    k = math.ceil(round((r.size + 1) * level, 9))
    if k > r.size:
        warn(f"{r.size} left-out residuals cannot support a {level:g} band (it needs "
             f"{math.ceil(level / (1 - level) - 1e-9)}): the largest |residual| is used")
        k = r.size
    return float(r[k - 1])


def residuals_of(params: DriveParameters) -> dict[str, np.ndarray]:
    """The drive's joints with leave-one-hold-out residuals (``driven`` order), or a one-line error
    naming the file when none has any."""
    residuals = {j: params.uncertainty.holding_residuals[j] for j in params.driven
                 if j in params.uncertainty.holding_residuals}
    if not residuals:
        raise RcmKinError(f"no holding residuals in {file_name(params)}: run rcm-kin calibrate", parameter="drive")
    return residuals


def file_name(params: DriveParameters) -> str:
    """The drive file's name, for messages."""
    return Path(params.source).name if params.source else "the drive parameters (in memory)"


def outside_hull(params: DriveParameters, poses: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Per joint of ``[uncertainty.hull]`` found in ``poses`` ({joint: values, rad}): where the pose is
    outside the calibrated range (bool arrays of the poses' shape)."""
    return {j: (np.asarray(poses[j]) < lo - 1e-12) | (np.asarray(poses[j]) > hi + 1e-12)
            for j, (lo, hi) in params.uncertainty.hull.items() if j in poses}


def hull_text(params: DriveParameters) -> str:
    """The calibrated poses, for people: ``roll [-15.1, 19.9] deg, pitch [-16.6, 14.9] deg``."""
    return ", ".join(f"{j} [{np.degrees(lo):.1f}, {np.degrees(hi):.1f}] deg"
                     for j, (lo, hi) in params.uncertainty.hull.items())


@dataclass(frozen=True)
class HoldingBand:
    """Holding PWM band at one pose, per joint of :attr:`joints` (the drive's joints with holding
    residuals): counts with the hardware sign."""

    joints: tuple[str, ...]
    level: float
    nominal: np.ndarray        # the model's holding PWM (the centre)
    lower: np.ndarray
    upper: np.ndarray
    half_width: np.ndarray
    extrapolated: bool         # the pose is outside the calibrated poses of some joint
    outside: tuple[str, ...]   # those joints
    hull: dict[str, tuple[float, float]]   # the calibrated poses, rad

    def as_dict(self) -> dict:
        """JSON-ready: per joint by name, PWM counts; the hull in degrees."""
        by_joint = lambda x: {j: float(v) for j, v in zip(self.joints, x)}  # noqa: E731
        return {"level": self.level, "joints": list(self.joints), "nominal_pwm": by_joint(self.nominal),
                "lower_pwm": by_joint(self.lower), "upper_pwm": by_joint(self.upper),
                "half_width_pwm": by_joint(self.half_width), "extrapolated": self.extrapolated,
                "outside": list(self.outside),
                "hull_deg": {j: np.degrees(v).tolist() for j, v in self.hull.items()}}


def holding_band(robot: Robot, q, level: float = DEFAULT_LEVEL, drive=None) -> HoldingBand:
    """The level-``level`` band of the holding PWM of ``robot``'s drive at actuated ``q`` (rad, m):
    the nominal holding effort (the numbers of :func:`rcm_kin.statics.holding_effort`) -+ the
    conformal half-width of each joint's holding residuals, flagged ``extrapolated`` outside the
    calibrated poses. ``drive``: as holding_effort's (default the robot's sidecar drive); a drive
    without holding residuals is a one-line error."""
    level = check_level(level)
    q = robot.check_q(q)
    params = resolve_drive(robot, drive)
    if params is None:
        raise RcmKinError(f"a holding band needs a drive and {robot.name} has none (its sidecar names no `drive` "
                          "file): give `drive`", parameter="drive")
    residuals = residuals_of(params)
    require_masses(robot, "the holding band")
    tau = gravity_batch(robot, q[None], params.gravity_offsets)[0]
    pwm = drive_effort(params, tau[[robot.actuated.index(j) for j in params.driven]]).pwm
    joints = tuple(residuals)
    nominal = np.array([pwm[params.driven.index(j)] for j in joints])
    half = np.array([conformal_half_width(r, level) for r in residuals.values()])
    poses = {j: q[robot.actuated.index(j)] for j in params.uncertainty.hull if j in robot.actuated}
    outside = tuple(j for j, flag in outside_hull(params, poses).items() if flag)
    return HoldingBand(joints, level, nominal, nominal - half, nominal + half, half, bool(outside), outside,
                       dict(params.uncertainty.hull))


def band_columns(params: DriveParameters, driven: tuple[str, ...], pwm: np.ndarray, poses: dict[str, np.ndarray],
                 level: float) -> dict[str, np.ndarray]:
    """Table columns of a map's band: ``lower_pwm_<joint>``, ``upper_pwm_<joint>`` of the joints with
    holding residuals (``pwm``: (..., len(driven)) nominal PWM), and ``extrapolated`` (1.0 where the
    pose, ``poses`` {joint: values of the map's pose shape, rad}, is outside the calibrated poses)."""
    level = check_level(level)
    columns = {}
    for j, r in residuals_of(params).items():
        if j in driven:
            half = conformal_half_width(r, level)
            columns[f"lower_pwm_{j}"] = pwm[..., driven.index(j)] - half
            columns[f"upper_pwm_{j}"] = pwm[..., driven.index(j)] + half
    flags = np.zeros(pwm.shape[:-1], dtype=bool)
    for flag in outside_hull(params, poses).values():
        flags |= np.broadcast_to(flag, flags.shape)
    columns["extrapolated"] = flags.astype(float)
    return columns


def band_summary(params: DriveParameters, level: float, columns: dict[str, np.ndarray]) -> dict:
    """JSON-ready summary of a map's band (:func:`band_columns`): level, half-width per joint (PWM),
    the columns it added, how many poses are extrapolated, the calibrated poses (deg)."""
    residuals = residuals_of(params)
    return {"level": check_level(level),
            "half_width_pwm": {j: conformal_half_width(r, level) for j, r in residuals.items()
                               if f"lower_pwm_{j}" in columns},
            "columns": list(columns), "extrapolated_poses": int(np.count_nonzero(columns["extrapolated"])),
            "hull_deg": {j: np.degrees(v).tolist() for j, v in params.uncertainty.hull.items()}}

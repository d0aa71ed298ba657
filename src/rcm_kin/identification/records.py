"""Identification records from telemetry logs: uniform resampling, the thesis's step trimming,
operating points from file names, and PRBS inputs for new experiments."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.errors import RcmKinError, WorkLimitError
from rcm_kin.identification.telemetry import TelemetryLog, step_index

METHODS = ("step", "prbs")
# The most grid points a resampled record may have per logged sample: the 1 ms grid of the drive-train
# fits (rcm_kin.identification.drive_train.PERIOD) over the slowest shared logs (a sample every 11 ms)
# is 11; more is a grid the data do not justify (and, over a gap in the stamps, one that fills memory).
MAX_UPSAMPLING = 20


@dataclass(frozen=True)
class Record:
    """A uniformly sampled input/output record of one joint: deviations from ``u0``, ``y0``."""

    joint: str
    period: float          # s
    u: np.ndarray          # PWM counts (deviation from u0)
    y: np.ndarray          # deg (deviation from y0)
    u0: float              # PWM counts at the operating point
    y0: float              # deg


def tick_period(log: TelemetryLog) -> float:
    """The mean interval (s) of ``log``'s samples, each taken as one controller tick (a closed-loop
    log: the firmware acted once per logged sample; its stamps are whole milliseconds, 2 or 3 ms
    apart around a 2.4 ms loop, so only the mean is the period)."""
    t = log.time
    if t.size < 10 or not t[-1] > t[0]:
        raise RcmKinError(f"{log.path.name}: too few time-stamped samples to identify from")
    return float((t[-1] - t[0]) / (t.size - 1))


def resample(log: TelemetryLog, joint: str, period: float | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """``(u, y, period)`` on a uniform grid: the PWM held (previous sample, as the driver holds it),
    the angle linearly interpolated. ``period`` defaults to the median sample interval. A sample
    whose stamp is not after every earlier one (a repeated stamp) is left out: the first of each
    stamp is kept. A grid of more than :data:`MAX_UPSAMPLING` points per kept sample is refused
    (a :class:`~rcm_kin.errors.WorkLimitError`) before it is built."""
    log.require(joint)
    t = log.time
    keep = np.r_[True, t[1:] > np.maximum.accumulate(t)[:-1]]
    t, u, y = t[keep], log.pwm[joint][keep], log.position[joint][keep]
    period = float(np.median(np.diff(t))) if period is None else period
    if t.size < 10 or not period > 0:
        raise RcmKinError(f"{log.path.name}: too few time-stamped samples to identify from")
    points = t[-1] / period
    if not points <= MAX_UPSAMPLING * t.size:
        raise WorkLimitError(f"{log.path.name}: a grid of {period:g} s over its {t[-1]:.6g} s is {points:.3g} points, "
                             f"more than {MAX_UPSAMPLING} per logged sample ({t.size:,}); a longer `period`, or a log "
                             "without a gap in its time stamps", requested=points, limit=MAX_UPSAMPLING * t.size,
                             parameter="period")
    grid = np.arange(0.0, t[-1], period)
    held = u[np.clip(np.searchsorted(t, grid, side="right") - 1, 0, t.size - 1)]
    return held, np.interp(grid, t, y), period


def step_record(log: TelemetryLog, joint: str, samples: int = 1000, period: float | None = None) -> Record:
    """The thesis's trimming: from the sample before the step (first ``|diff(u)| > 0.1``) for
    ``samples`` samples, minus the values there (so the record starts at rest, at the step)."""
    u, y, period = resample(log, joint, period)
    start = step_index(u) - 1
    stop = min(start + samples, u.size)
    if stop - start < 50:
        raise RcmKinError(f"{log.path.name}: only {stop - start} samples after the {joint} step")
    return Record(joint, period, u[start:stop] - u[start], y[start:stop] - y[start], float(u[start]), float(y[start]))


def prbs_record(log: TelemetryLog, joint: str, period: float | None = None) -> Record:
    """The whole record about its means (the closed-loop PRBS experiments hover at a pose)."""
    u, y, period = resample(log, joint, period)
    return Record(joint, period, u - u.mean(), y - y.mean(), float(u.mean()), float(y.mean()))


def operating_point(path: str | Path) -> tuple[float, float] | None:
    """``(roll, pitch)`` in degrees from a name like ``..._roll_-15_pitch_m15...``; None if absent."""
    match = re.search(r"roll_(m?-?\d+(?:\.\d+)?)_pitch_(m?-?\d+(?:\.\d+)?)", Path(path).name)
    if not match:
        return None
    value = lambda s: -float(s[1:]) if s.startswith("m") else float(s)  # noqa: E731
    return value(match.group(1)), value(match.group(2))


def prbs(duration: float, period: float, amplitude: float = 15.0, min_hold: float = 0.005,
         max_hold: float = 1.0, seed: int = 0) -> np.ndarray:
    """A random binary sequence ``+-amplitude`` sampled every ``period`` s whose level holds for a
    uniformly random time in ``[min_hold, max_hold]`` s (the logs': +-15 PWM, 5-1000 ms)."""
    if not (duration > 0 and period > 0 and 0 < min_hold <= max_hold and amplitude > 0):
        raise RcmKinError("PRBS: duration, period, amplitude > 0 and 0 < min_hold <= max_hold (s)")
    rng = np.random.default_rng(seed)
    n = int(round(duration / period))
    out = np.empty(n)
    k, level = 0, rng.choice([-1.0, 1.0])
    while k < n:
        hold = max(1, int(round(rng.uniform(min_hold, max_hold) / period)))
        out[k:k + hold] = level * amplitude
        k, level = k + hold, -level
    return out

"""Reference trajectories of the thesis experiments, sampled at the controller rate.

Positions are (roll rad, pitch rad, insertion m) with their first two derivatives, from t = 0.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rcm_kin.errors import RcmKinError, WorkLimitError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.kinematics.teleop import default_teleop_map, teleop_joint_targets
from rcm_kin.thesis import SINE_AMPLITUDE_DEG, SINE_CYCLE_S

if TYPE_CHECKING:
    from rcm_kin.model import Robot

EXPERIMENTS = ("sine", "step", "target")
BUNDLED_TRAJECTORY = "figure_eight.csv"


@dataclass(frozen=True)
class Reference:
    time: np.ndarray          # (N,) s, uniform at the controller period
    position: np.ndarray      # (N, 3) rad, rad, m
    velocity: np.ndarray      # (N, 3) per s
    acceleration: np.ndarray  # (N, 3) per s^2


MAX_SAMPLES = 200_000      # controller periods of one run: 500 s at 400 Hz, one to two minutes of simulation


def _samples(duration: float, period: float) -> np.ndarray:
    if not (np.isfinite(duration) and duration > 0):
        raise RcmKinError(f"the duration must be a positive number of seconds, got {duration}")
    samples = duration / period + 1
    if samples > MAX_SAMPLES:
        message = (f"{duration:g} s at {1 / period:g} Hz is {samples:,.0f} controller periods; the limit is "
                   f"{MAX_SAMPLES:,} (one to two minutes of simulation): shorten the duration or lower the rate")
        raise WorkLimitError(message, requested=samples, limit=MAX_SAMPLES, parameter="duration")
    return np.arange(int(round(duration / period)) + 1) * period


def sine_reference(duration: float, period: float, amplitude_deg=SINE_AMPLITUDE_DEG, cycle: float = SINE_CYCLE_S,
                   insertion: float = HOME_INSERTION) -> Reference:
    """The thesis sinusoid (:mod:`rcm_kin.thesis`): roll 20 deg and pitch 15 deg
    amplitude, 3 s period, together."""
    t = _samples(duration, period)
    w = 2 * np.pi / cycle
    amp = np.radians(np.r_[amplitude_deg, 0.0])
    pos = np.outer(np.sin(w * t), amp) + [0.0, 0.0, insertion]
    return Reference(t, pos, np.outer(w * np.cos(w * t), amp), np.outer(-w**2 * np.sin(w * t), amp))


def step_reference(duration: float, period: float, step_deg=(10.0, 10.0), at: float = 0.5,
                   insertion: float = HOME_INSERTION) -> Reference:
    """Roll and pitch steps from 0 to ``step_deg`` at ``at`` s (zero derivatives: a step)."""
    t = _samples(duration, period)
    pos = np.zeros((t.size, 3))
    pos[:, :2] = np.where(t[:, None] >= at, np.radians(step_deg), 0.0)
    pos[:, 2] = insertion
    return Reference(t, pos, np.zeros_like(pos), np.zeros_like(pos))


def load_mtm_trajectory(path: str | Path | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(time s from 0, displacement (N, 3) m)`` of an MTM recording (``unix_time,x,y,z``), repeated
    time stamps dropped; the default is the small trajectory bundled with the package."""
    source = Path(path) if path is not None else resources.files("rcm_kin.simulation") / BUNDLED_TRAJECTORY
    try:
        with open(source, newline="") as fh:
            rows = list(csv.reader(fh))
    except OSError as exc:
        raise RcmKinError(f"cannot read the MTM trajectory {source}: {exc.strerror}") from None
    except (UnicodeDecodeError, csv.Error):
        raise RcmKinError(f"{source}: not an MTM trajectory (not a CSV text file)") from None
    header = [h.strip() for h in rows[0]] if rows else []
    missing = [c for c in ("unix_time", "x", "y", "z") if c not in header]
    if missing:
        raise RcmKinError(f"{source}: not an MTM trajectory (no '{missing[0]}' column; expected unix_time,x,y,z)")
    try:
        data = np.array([[float(r[header.index(c)]) for c in ("unix_time", "x", "y", "z")] for r in rows[1:] if r])
    except (ValueError, IndexError):
        raise RcmKinError(f"{source}: non-numeric or short rows") from None
    if len(data) < 4 or not np.all(np.isfinite(data)) or np.any(np.diff(data[:, 0]) < 0):
        raise RcmKinError(f"{source}: needs at least 4 finite samples with non-decreasing time")
    keep = np.r_[True, np.diff(data[:, 0]) > 1e-6]
    return data[keep, 0] - data[0, 0], data[keep, 1:]


def target_reference(psm: Robot, duration: float | None, period: float,
                     trajectory: str | Path | None = None) -> Reference:
    """The target-following experiment: MTM displacements through the teleoperation map and the
    PSM IK, splined (C2) at the controller rate; ``duration`` None = the recording's length."""
    from scipy.interpolate import CubicSpline  # 0.35 s of SciPy imports: only for this experiment

    t_raw, displacement = load_mtm_trajectory(trajectory)
    joints = teleop_joint_targets(psm, default_teleop_map(psm), displacement)
    spline = CubicSpline(t_raw, joints, bc_type="clamped")
    t = _samples(duration if duration is not None else t_raw[-1], period)
    tc = np.minimum(t, t_raw[-1])                              # hold the last target afterwards
    moving = (t <= t_raw[-1])[:, None]
    return Reference(t, spline(tc), spline(tc, 1) * moving, spline(tc, 2) * moving)

"""Telemetry logs of the PSM (PlotJuggler CSV exports of the robot's ROS 2 telemetry).

Column meaning (per joint ``roll``, ``pitch``, ``insertion``): ``.../<joint>/position`` (or
``<joint>_position``) is the measured position in degrees; ``.../<joint>/velocity`` is the
commanded motor PWM (the input, counts); ``.../<joint>/effort`` the position setpoint (deg).
Time is the microcontroller stamp when present, else ``__time``/``time`` (s). ROS 2 bags of the
same telemetry (``.mcap``, ``.db3``) are read by :mod:`rcm_kin.identification.rosbag`.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.errors import LogDataError, LogDataWarning, RcmKinError, warn
from rcm_kin.identification.rosbag import BAG_SUFFIXES, is_bag, read_joint_states

JOINTS = ("roll", "pitch", "insertion")
_TIME_COLUMNS = ("/psm_joint_telemetry/header/stamp", "__time", "time")


@dataclass(frozen=True)
class TelemetryLog:
    path: Path
    time: np.ndarray                    # s, starting at 0
    position: dict[str, np.ndarray]     # deg, measured, per joint present
    pwm: dict[str, np.ndarray]          # counts, commanded input
    setpoint: dict[str, np.ndarray]     # deg (0 when unused)

    def require(self, joint: str) -> None:
        """A clear error naming the missing column when ``joint`` is not in the log."""
        for what, table in (("position", self.position), ("velocity", self.pwm)):
            if joint not in table:
                raise RcmKinError(f"{self.path.name}: no '{joint}/{what}' column "
                                  f"(the {'measured position' if what == 'position' else 'PWM input'} of {joint})")


def _find(header: list[str], joint: str, quantity: str) -> int | None:
    for i, name in enumerate(header):
        if name.endswith(f"/{joint}/{quantity}") or name == f"{joint}_{quantity}":
            return i
    return None


def load_telemetry(path: str | Path) -> TelemetryLog:
    """Read one telemetry CSV (or ROS 2 bag); a missing or non-finite value in a used column of a
    CSV is an error naming it."""
    path = Path(path)
    if is_bag(path):
        return load_bag(path)
    try:
        with path.open(newline="") as fh:
            rows = list(csv.reader(fh))
    except FileNotFoundError:
        raise RcmKinError(f"no log file at {path}") from None
    except OSError as exc:
        raise RcmKinError(f"cannot read the log {path}: {exc.strerror}") from None
    except (UnicodeDecodeError, csv.Error):
        raise RcmKinError(f"{path}: not a CSV text file") from None
    if len(rows) < 3:
        raise RcmKinError(f"{path}: not a telemetry log (fewer than 2 data rows)")
    header = [h.strip() for h in rows[0]]
    time_col = next((header.index(c) for c in _TIME_COLUMNS if c in header), None)
    if time_col is None:
        raise RcmKinError(f"{path}: not a telemetry log (no time column: expected one of {', '.join(_TIME_COLUMNS)})")
    complete = [r for r in rows[1:] if len(r) == len(header)]
    if len(complete) < len(rows) - 1:       # a recording cut off mid-row, typically its last line
        warn(f"{path}: {len(rows) - 1 - len(complete)} rows with a wrong number of fields left out "
             f"(of {len(rows) - 1})", LogDataWarning)
    try:
        data = np.array([[float(x) if x.strip() else np.nan for x in r] for r in complete])
    except ValueError:
        raise RcmKinError(f"{path}: not a telemetry log (non-numeric values)") from None
    if data.ndim != 2 or len(data) < 2:
        raise RcmKinError(f"{path}: not a telemetry log (no complete data rows)")
    columns = {(j, q): _find(header, j, q) for j in JOINTS for q in ("position", "velocity", "effort")}
    used = [time_col] + [i for i in columns.values() if i is not None]
    bad = ~np.isfinite(data[:, used])
    if np.any(bad):          # dropping rows would leave a time gap the fits read as dynamics
        row, col = np.argwhere(bad)[0]
        raise LogDataError(f"{path}: {np.count_nonzero(np.any(bad, axis=1))} rows with a missing or non-finite value, "
                          f"the first in data row {row + 1}, column '{header[used[col]]}'; clean the log (rows are "
                          "not dropped: the gap would be read as dynamics)", path=path, row=int(row) + 1,
                          column=header[used[col]])
    pick = lambda q: {j: data[:, columns[(j, q)]] for j in JOINTS if columns[(j, q)] is not None}  # noqa: E731
    position, pwm = pick("position"), pick("velocity")
    if not position or not pwm:
        raise RcmKinError(f"{path}: not a telemetry log (no '<joint>/position' and '<joint>/velocity' columns)")
    t = data[:, time_col]
    return TelemetryLog(path, t - t[0], position, pwm, pick("effort"))


def load_bag(path: str | Path, topic: str | None = None) -> TelemetryLog:
    """A :class:`TelemetryLog` from a ROS 2 bag (:func:`rcm_kin.identification.rosbag.read_joint_states`
    of ``topic``, default the current :func:`~rcm_kin.identification.rosbag.telemetry_topic`)."""
    t, data = read_joint_states(path, topic)
    pick = lambda field: {j: data[(j, field)] for j in JOINTS if (j, field) in data}  # noqa: E731
    position, pwm = pick("position"), pick("velocity")
    if not position or not pwm:
        raise RcmKinError(f"{path}: not a telemetry log (no position and velocity of {', '.join(JOINTS)})")
    return TelemetryLog(Path(path), t, position, pwm, pick("effort"))


def telemetry_files(folder: str | Path, pattern: str = "*") -> list[Path]:
    """The logs below ``folder`` whose names match ``pattern`` (a glob without the suffix), sorted:
    CSV files and ROS 2 bags (``.mcap``/``.db3`` files; a rosbag2 folder counts once, as the folder)."""
    found = Path(folder).glob(pattern)
    return sorted(p for p in found if (p.is_dir() and is_bag(p))
                  or (p.suffix in (".csv", *BAG_SUFFIXES) and p.is_file() and not is_bag(p.parent)))


def step_index(u: np.ndarray, threshold: float = 0.1) -> int:
    """Index of the first input change larger than ``threshold`` (the thesis's step trimming)."""
    jumps = np.flatnonzero(np.abs(np.diff(u)) > threshold)
    if jumps.size == 0:
        raise RcmKinError("the input has no step (no change above the threshold)")
    return int(jumps[0]) + 1

"""Telemetry logs of the PSM (PlotJuggler CSV exports of the robot's ROS 2 telemetry).

Column meaning (per joint ``roll``, ``pitch``, ``insertion``): ``.../<joint>/position`` (or
``<joint>_position``) is the measured position in degrees; ``.../<joint>/velocity`` is the
commanded motor PWM (the input, counts); ``.../<joint>/effort`` the position setpoint (deg).
Time is the microcontroller stamp when present, else ``__time``/``time`` (s). ROS 2 bags of the
same telemetry (``.mcap``, ``.db3``) are read by :mod:`rcm_kin.identification.rosbag`.

Bounded reads: a CSV is streamed (one row at a time into a flat float array, about 8 bytes a
value) and refused above :data:`MAX_LOG_BYTES` or :data:`MAX_LOG_ROWS`. Its time stamps (and a
bag's) are checked when it is read: a stamp earlier than the one before by more than
:data:`TIME_TOLERANCE`, or later by more than :data:`MAX_GAP`, is a :class:`~rcm_kin.errors.LogDataError`
naming the row; rows are never reordered or dropped for it (either changes the fitted model).
A repeated stamp (within the tolerance) is kept, with a warning: as a controller tick where the
samples are used as ticks; resampling onto a grid keeps the first sample of each stamp.
"""

from __future__ import annotations

import csv
from array import array
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.atomic import atomic_path
from rcm_kin.errors import LogDataError, LogDataWarning, RcmKinError, WorkLimitError, warn
from rcm_kin.identification.rosbag import BAG_SUFFIXES, is_bag, read_joint_states

JOINTS = ("roll", "pitch", "insertion")
_TIME_COLUMNS = ("/psm_joint_telemetry/header/stamp", "__time", "time")
# Bounds of a readable log, from the shared logs (/work/shared/data/psm-sysid: at most 25,331 rows,
# 3.7 MB and 61 s a log; a sample every 2-11 ms, the widest step between two stamps 5 ms; no stamp
# repeated or going back). A log at the bounds reads in well under a minute on one core, in about
# 8 bytes a value (a few hundred MB for 2 million rows of 20 columns).
MAX_LOG_BYTES = 256 * 2**20     # bytes of one CSV: about 70 times the largest shared log
MAX_LOG_ROWS = 2_000_000        # data rows of one CSV (messages of one bag topic): 80 min at the 2.4 ms loop
TIME_TOLERANCE = 1e-6           # s a stamp may lie before the one above it (float rounding of a
                                # stamp in Unix seconds: 0.24 us at 1.7e9 s; the stamps are 10 us
                                # or 1 ms apart)
MAX_GAP = 1.0                   # s between two stamps: 200 times the widest step of the shared logs,
                                # as long as a whole fitted step record (1000 samples at 1 ms); a
                                # longer one is a recording paused or two logs joined, which a fit
                                # would read as dynamics (and a grid over it would fill memory)


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
    CSV is an error naming it, and so are time stamps out of order or with a gap (:func:`check_time`);
    a CSV larger than :data:`MAX_LOG_BYTES` or :data:`MAX_LOG_ROWS` is refused before it is read."""
    path = Path(path)
    if is_bag(path):
        return load_bag(path)
    header, data, lines = _read_csv(path)
    time_col = next((header.index(c) for c in _TIME_COLUMNS if c in header), None)
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
    check_time(path, t, header[time_col], lines)
    return TelemetryLog(path, t - t[0], position, pwm, pick("effort"))


def _read_csv(path: Path) -> tuple[list[str], np.ndarray, np.ndarray]:
    """The header, the rows with the header's number of fields as floats (an empty field NaN) and
    the line of the file each ends on (the header's is 1), streamed within the size bounds."""
    try:
        size = path.stat().st_size
        if size > MAX_LOG_BYTES:
            raise WorkLimitError(f"{path}: a log of {size:,} bytes, beyond the {MAX_LOG_BYTES:,} a log may have "
                                 "(split it)", requested=size, limit=MAX_LOG_BYTES)
        plain = _read_plain_csv(path)
        if plain is not None:
            return _with_time(path, plain)
        with path.open(newline="") as fh:
            reader = csv.reader(fh)
            header = [h.strip() for h in next(reader, [])]
            values, lines, rows, numeric = array("d"), array("q"), 0, True
            for row in reader:
                rows += 1
                if rows > MAX_LOG_ROWS:
                    raise WorkLimitError(f"{path}: more than {MAX_LOG_ROWS:,} data rows, the most a log may have "
                                         "(split it)", requested=rows, limit=MAX_LOG_ROWS)
                if len(row) != len(header) or not numeric:
                    continue
                try:
                    values.extend([float(x) if x.strip() else np.nan for x in row])
                except ValueError:
                    numeric = False
                lines.append(reader.line_num)
    except FileNotFoundError:
        raise RcmKinError(f"no log file at {path}") from None
    except OSError as exc:
        raise RcmKinError(f"cannot read the log {path}: {exc.strerror}") from None
    except (UnicodeDecodeError, csv.Error):
        raise RcmKinError(f"{path}: not a CSV text file") from None
    if rows < 2:
        raise RcmKinError(f"{path}: not a telemetry log (fewer than 2 data rows)")
    _with_time(path, (header, None, None))
    if len(lines) < rows and numeric:       # a recording cut off mid-row, typically its last line
        warn(f"{path}: {rows - len(lines)} rows with a wrong number of fields left out (of {rows})", LogDataWarning)
    if not numeric:
        raise RcmKinError(f"{path}: not a telemetry log (non-numeric values)")
    if len(lines) < 2:
        raise RcmKinError(f"{path}: not a telemetry log (no complete data rows)")
    data = np.frombuffer(values, dtype=float).reshape(len(lines), len(header))
    data.flags.writeable = True             # the array.array's own memory, not a copy
    return header, data, np.frombuffer(lines, dtype=np.int64)


def _with_time(path: Path, read: tuple) -> tuple:
    """``read`` (header, ...) unchanged when its header has a time column, else the error."""
    if not any(c in read[0] for c in _TIME_COLUMNS):
        raise RcmKinError(f"{path}: not a telemetry log (no time column: expected one of {', '.join(_TIME_COLUMNS)})")
    return read


def _read_plain_csv(path: Path) -> tuple[list[str], np.ndarray, np.ndarray] | None:
    """:func:`_read_csv` of a plain numeric CSV, by NumPy's C parser (``np.loadtxt``: about 2.5
    times the csv module's speed, the same floats: both round correctly): no quotes, no blank,
    short or long rows, no empty or non-numeric fields, within :data:`MAX_LOG_ROWS`. None for any
    other file, which the csv module reads with its warnings and errors."""
    raw = path.read_bytes()
    first = raw[:raw.find(b"\n")] if b"\n" in raw else raw
    lines = raw.count(b"\n") + (0 if raw.endswith(b"\n") else 1)
    if b'"' in raw or lines < 3 or lines - 1 > MAX_LOG_ROWS:
        return None
    del raw
    try:
        header = [h.strip() for h in first.decode().rstrip("\r").split(",")]
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, comments=None, encoding="utf-8")
    except (ValueError, UnicodeDecodeError):
        return None
    if data.shape != (lines - 1, len(header)) or data.dtype != np.float64:
        return None
    return header, data, np.arange(2, lines + 1, dtype=np.int64)


def check_time(path: str | Path, t: np.ndarray, column: str, lines: np.ndarray | None = None,
               noun: str = "data row") -> None:
    """Refuse time stamps ``t`` (s, one per row) that go back by more than :data:`TIME_TOLERANCE`
    or jump forward by more than :data:`MAX_GAP`: a :class:`LogDataError` naming the first such
    row (``noun`` and its number from 1, with its line of the file when ``lines`` are given);
    repeated stamps (within the tolerance) are a :class:`LogDataWarning`."""
    step = np.diff(t)
    wrong = np.flatnonzero((step < -TIME_TOLERANCE) | (step > MAX_GAP))
    if wrong.size:
        k = int(wrong[0]) + 1                   # the row whose stamp is wrong, from 0
        where = f"{noun} {k + 1}" + (f" (line {lines[k]})" if lines is not None else "")
        if step[k - 1] < 0:
            problem = (f"time goes back {-step[k - 1]:.6g} s at {where} ({t[k]:.6f} s after {t[k - 1]:.6f} s): "
                       "rows out of order; sort the log by time")
        else:
            problem = (f"a gap of {step[k - 1]:.6g} s in the time stamps at {where} ({t[k - 1]:.6f} s, then "
                       f"{t[k]:.6f} s), more than the {MAX_GAP:g} s a log may skip; split the log at the gap")
        raise LogDataError(f"{path}: {problem} (rows are not reordered or dropped: either changes the fit)",
                           path=path, row=k + 1, column=column)
    repeated = np.count_nonzero(step <= 0)
    if repeated:
        warn(f"{path}: {repeated} {noun}s repeat the time stamp before them (within {TIME_TOLERANCE:g} s); kept as "
             "samples, and resampling keeps the first of each stamp", LogDataWarning)


def load_bag(path: str | Path, topic: str | None = None) -> TelemetryLog:
    """A :class:`TelemetryLog` from a ROS 2 bag (:func:`rcm_kin.identification.rosbag.read_joint_states`
    of ``topic``, default the current :func:`~rcm_kin.identification.rosbag.telemetry_topic`)."""
    t, data = read_joint_states(path, topic, max_messages=MAX_LOG_ROWS)
    return telemetry_log(path, t, data)


def telemetry_log(path: str | Path, t: np.ndarray, data: dict) -> TelemetryLog:
    """The :class:`TelemetryLog` of JointState columns ``data`` ({(joint, field): values}) at times
    ``t`` (s): a bag's (:func:`load_bag`) or a live topic's; its time stamps checked (:func:`check_time`)."""
    check_time(path, t, "header/stamp", noun="complete message")
    pick = lambda field: {j: data[(j, field)] for j in JOINTS if (j, field) in data}  # noqa: E731
    position, pwm = pick("position"), pick("velocity")
    if not position or not pwm:
        raise RcmKinError(f"{path}: not a telemetry log (no position and velocity of {', '.join(JOINTS)})")
    return TelemetryLog(Path(path), t, position, pwm, pick("effort"))


def write_telemetry(log: TelemetryLog, path: str | Path) -> Path:
    """``log`` as a telemetry CSV at ``path`` (the PlotJuggler export's columns: ``__time`` s, and
    ``/psm_joint_telemetry/<joint>/position`` deg, ``.../velocity`` PWM counts, ``.../effort`` deg per
    joint of the log), which :func:`load_telemetry` reads back to the same numbers."""
    path = Path(path)
    header, columns = ["__time"], [log.time]
    for joint in JOINTS:
        for field, table in (("position", log.position), ("velocity", log.pwm), ("effort", log.setpoint)):
            if joint in table:
                header.append(f"/psm_joint_telemetry/{joint}/{field}")
                columns.append(table[joint])
    try:
        with atomic_path(path) as temporary:
            np.savetxt(temporary, np.column_stack(columns), delimiter=",", header=",".join(header), comments="",
                       fmt="%.17g")
    except OSError as exc:
        raise RcmKinError(f"cannot write {path}: {exc.strerror}") from None
    return path


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

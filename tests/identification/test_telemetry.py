"""Bounded reads of telemetry logs: time stamps checked when a log is read (out of order, gaps,
repeats), a resampling grid no larger than the data justify, size bounds, a streamed reader that
reads every shared log as the plain ``csv`` module does."""

from __future__ import annotations

import csv
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest

from rcm_kin.errors import LogDataError, LogDataWarning, WorkLimitError
from rcm_kin.identification import records, telemetry
from rcm_kin.identification.drive_train import PERIOD
from rcm_kin.identification.records import resample
from rcm_kin.identification.telemetry import TelemetryLog, load_telemetry, telemetry_files

HEADER = ["__time", "/t/roll/position", "/t/roll/velocity", "/t/pitch/position", "/t/pitch/velocity"]
PERIOD_LOG = 0.0025          # s between the synthetic log's samples


def write_log(path: Path, t: np.ndarray) -> Path:
    """A roll step log at the stamps ``t`` (s): the PWM -40 from row 200, the angle rising after it."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(HEADER)
        for i, ti in enumerate(t):
            w.writerow([repr(float(ti)), 0.01 * max(i - 200, 0), -40.0 if i >= 200 else 0.0, 0, 0])
    return path


def stamps(rows: int = 1200) -> np.ndarray:
    return np.arange(rows) * PERIOD_LOG


def peak_bytes(function, *args) -> tuple[int, BaseException | None]:
    """The peak of memory traced while ``function(*args)`` runs, and what it raised."""
    tracemalloc.start()
    raised = None
    try:
        function(*args)
    except Exception as exc:         # noqa: BLE001 (the caller checks what)
        raised = exc
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak, raised


def test_two_rows_swapped_are_refused_naming_the_row(tmp_path):
    t = stamps()
    t[[500, 501]] = t[[501, 500]]          # data rows 501 and 502 (from 1) swapped: the 502nd goes back
    path = write_log(tmp_path / "swapped.csv", t)
    with pytest.raises(LogDataError, match=r"time goes back 0\.0025 s at data row 502 \(line 503\)") as caught:
        load_telemetry(path)
    assert (caught.value.path, caught.value.row, caught.value.column) == (path, 502, "__time")
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_a_1000_s_jump_is_refused_fast_naming_the_row(tmp_path):
    t = stamps()
    t[700:] += 1000.0                      # data row 701 (line 702) comes 1000 s after the one above
    path = write_log(tmp_path / "jump.csv", t)
    peak, raised = peak_bytes(load_telemetry, path)
    assert isinstance(raised, LogDataError) and raised.row == 701, raised
    assert "a gap of 1000" in str(raised) and "data row 701 (line 702)" in str(raised)
    # the file's values are 1200 x 5 x 8 = 48 kB; a 1 ms grid over the gap would be 8 MB an array
    assert peak < 2_000_000, peak


def test_the_gap_bound_is_the_stated_one(tmp_path):
    t = stamps()
    t[700:] += telemetry.MAX_GAP - PERIOD_LOG - 1e-3     # a step of MAX_GAP - 1 ms: read
    assert load_telemetry(write_log(tmp_path / "under.csv", t)).time.size == 1200
    t[700:] += 2e-3                                      # MAX_GAP + 1 ms: refused
    with pytest.raises(LogDataError, match="data row 701"):
        load_telemetry(write_log(tmp_path / "over.csv", t))


def test_resampling_over_a_gap_is_refused_before_allocating():
    """The second guard: a log that did not come through the reader (built in Python) with a
    1000 s gap; a 1 ms grid over it would be 1e6 points in each of four arrays."""
    t = stamps()
    t[700:] += 1000.0
    u = np.where(np.arange(t.size) >= 200, -40.0, 0.0)
    log = TelemetryLog(Path("built.csv"), t, {"roll": np.zeros(t.size)}, {"roll": u}, {})
    peak, raised = peak_bytes(resample, log, "roll", 1e-3)
    assert isinstance(raised, WorkLimitError) and "built.csv" in str(raised), raised
    assert raised.limit == records.MAX_UPSAMPLING * t.size and raised.requested > 1e6
    assert peak < 1_000_000, peak


def test_repeated_stamps_are_kept_with_a_warning_and_resampling_keeps_the_first(tmp_path):
    t = stamps()
    t[200] = t[199]                        # the step's first row repeats the stamp above it
    t[400] = t[399] - 0.5 * telemetry.TIME_TOLERANCE    # a step back within the tolerance
    with pytest.warns(LogDataWarning, match="2 data rows repeat the time stamp"):
        log = load_telemetry(write_log(tmp_path / "repeat.csv", t))
    assert log.time.size == 1200           # kept as samples (ticks)
    u, y, period = resample(log, "roll", PERIOD_LOG)
    # the first sample of the stamp 199 * 2.5 ms is the one before the step (PWM 0), held until row
    # 201's stamp: the grid point at 0.5 s (between the two) holds 0; keeping the last would hold -40
    assert period == PERIOD_LOG and u[200] == 0.0 and u[202] == -40.0
    assert np.all(np.isfinite(y)) and u.size == int(np.ceil(t[-1] / PERIOD_LOG))


@pytest.mark.parametrize("bound, value, message", [("MAX_LOG_ROWS", 1000, "more than 1,000 data rows"),
                                                    ("MAX_LOG_BYTES", 10_000, "bytes, beyond the 10,000")])
def test_logs_beyond_the_size_bounds_are_refused(tmp_path, monkeypatch, bound, value, message):
    path = write_log(tmp_path / "long.csv", stamps())
    monkeypatch.setattr(telemetry, bound, value)
    with pytest.raises(WorkLimitError, match=message) as caught:
        load_telemetry(path)
    assert caught.value.limit == value


def test_the_reader_streams(tmp_path):
    """The values are held as floats (8 bytes each), not as lists of strings (the old reader's
    peak was about 30 times the values)."""
    path = write_log(tmp_path / "log.csv", stamps(20_000))
    peak, raised = peak_bytes(load_telemetry, path)
    assert raised is None
    assert peak < 6 * 20_000 * len(HEADER) * 8, peak


def _plain_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """The header and the complete rows of ``path`` by the csv module (an independent reading)."""
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    header = [h.strip() for h in rows[0]]
    return header, np.array([[float(x) for x in r] for r in rows[1:] if len(r) == len(header)])


def test_every_shared_log_reads_as_the_csv_module_reads_it(shared_data):
    logs = telemetry_files(shared_data / "psm-sysid", "*/*")
    assert len(logs) >= 20
    for path in logs:
        with warnings.catch_warnings():
            warnings.simplefilter("error", LogDataWarning)       # none is cut off, repeated or out of order
            log = load_telemetry(path)
        header, rows = _plain_csv(path)
        column = next(c for c in ("/psm_joint_telemetry/header/stamp", "__time", "time") if c in header)
        t = rows[:, header.index(column)]
        np.testing.assert_array_equal(log.time, t - t[0], err_msg=path.name)
        for joint, values in log.position.items():
            name = next(h for h in header if h.endswith(f"/{joint}/position") or h == f"{joint}_position")
            np.testing.assert_array_equal(values, rows[:, header.index(name)], err_msg=path.name)
        for joint in log.pwm:            # the drive-train fits' 1 ms grid is within the upsampling bound
            u, _, period = resample(log, joint, PERIOD)
            assert period == PERIOD and u.size == int(np.ceil(log.time[-1] / PERIOD)), path.name


PLAIN = ("__time,/t/roll/position,/t/roll/velocity\n0.0,0.1,-3\n"
         "0.0025,0.1000000000000000055511151231257827,4e-3\n0.005,-0.2,5\n")


@pytest.mark.parametrize("text, fast", [
    (PLAIN, True),
    (PLAIN.replace("\n", "\r\n"), True),                           # Windows line ends
    (PLAIN.rstrip("\n"), True),                                    # no newline at the end
    (PLAIN + "0.0075,0.3,6\n" * 3, True),
    (PLAIN.replace("0.005,-0.2,5\n", "\n0.005,-0.2,5\n"), False),  # a blank line: its row is left out, warned
    (PLAIN + "0.0075,0.3", False),                                 # cut off mid-row
    (PLAIN.replace("-0.2", ""), False),                            # an empty field: NaN
    (PLAIN.replace("-0.2", '"-0.2"'), False),                      # quoted
    (PLAIN.replace("-0.2", "-0.2,7"), False),                      # a long row
    (PLAIN.replace("-0.2", "1_0"), False),                         # Python's float reads 10
    (PLAIN + "# note,1,2\n", False),                               # not numeric: refused
])
def test_the_plain_reader_reads_as_the_csv_module(tmp_path, monkeypatch, text, fast):
    """The fast reading (NumPy's parser) of a plain CSV and the csv module's reading of any CSV:
    the same header, floats (bit for bit), line numbers, warnings and errors."""
    path = tmp_path / "log.csv"
    path.write_bytes(text.encode())
    assert (telemetry._read_plain_csv(path) is not None) == fast

    def read():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                header, data, lines = telemetry._read_csv(path)
            except Exception as exc:         # noqa: BLE001 - the same error either way
                return type(exc), str(exc)
        return header, data.tobytes(), data.shape, lines.tolist(), [str(w.message) for w in caught]

    plain = read()
    monkeypatch.setattr(telemetry, "_read_plain_csv", lambda path: None)
    assert plain == read()
    if fast:
        rows = [r for r in csv.reader(text.splitlines())][1:]
        assert plain[1] == np.array([[float(x) for x in r] for r in rows]).tobytes()

"""The exception types for user errors (bad input, unreachable targets, bad files), the warning
types for what the library does differently than asked (one line each), and the file helpers that
turn the operating system's errors into an error.

An error's message names the library's parameters (``params``, ``harmonics``); ``parameter``
says which one was wrong, so that the CLI can name its flag instead. The subclasses carry the
facts their message states as attributes (``path``, ``key``, ``values``, ...; None where not
known). Warnings go through :mod:`warnings` (never printed by the library): the CLI prints each
distinct one as a line ``warning: <message>`` after a successful run.
"""

import math
import sys
import tomllib
import warnings
from pathlib import Path

import numpy as np


class RcmKinError(ValueError):
    """A request rcm_kin cannot satisfy; the message (one line) says what was wrong and what to do.

    ``parameter``: the name of the function parameter at fault (a tuple when several are), or
    None. The CLI prints it as one line ``error: <message>`` (the parameter named by its flag)
    and exits with status 2.
    """

    def __init__(self, message: str = "", *, parameter: str | tuple[str, ...] | None = None):
        super().__init__(" ".join(str(message).split()))      # one line, whatever a shown value held
        self.parameter = parameter

    @property
    def parameters(self) -> tuple[str, ...]:
        """The parameters at fault, as a tuple (empty when none is named)."""
        if self.parameter is None:
            return ()
        return (self.parameter,) if isinstance(self.parameter, str) else tuple(self.parameter)


class ParameterFileError(RcmKinError):
    """A parameter file holds a key, type or value outside its schema (the file and key are named).

    ``path`` the file, ``table`` the TOML table (``roll``, ``gravity_offsets``), ``key`` the key in it.
    """

    def __init__(self, message: str = "", *, path=None, table: str | None = None, key: str | None = None,
                 parameter: str | tuple[str, ...] | None = None):
        super().__init__(message, parameter=parameter)
        self.path, self.table, self.key = path, table, key


class JointLimitError(RcmKinError):
    """A pose (given, or reached by a simulation) outside the joints' limits: refused, not computed.

    ``joints`` the names of the joints outside, ``values`` their positions, ``lower`` and ``upper``
    their limits (the model's units: rad, m), in the same order.
    """

    def __init__(self, message: str = "", *, joints: tuple[str, ...] | None = None, values=None, lower=None,
                 upper=None, parameter: str | tuple[str, ...] | None = None):
        super().__init__(message, parameter=parameter)
        self.joints, self.values, self.lower, self.upper = joints, values, lower, upper


class WorkLimitError(RcmKinError):
    """A request that would need more memory or time than the stated bound (the message says how much).

    ``requested`` the amount asked for and ``limit`` the bound, in the message's unit (poses,
    controller periods, logs).
    """

    def __init__(self, message: str = "", *, requested=None, limit=None,
                 parameter: str | tuple[str, ...] | None = None):
        super().__init__(message, parameter=parameter)
        self.requested, self.limit = requested, limit


class LogDataError(RcmKinError):
    """A measured log with missing or non-finite values where a fit needs numbers.

    ``path`` the log, ``row`` the first bad data row (CSV, from 1) or complete message (bag, from
    1), ``column`` its column (CSV) or ``joint/field`` (bag).
    """

    def __init__(self, message: str = "", *, path=None, row: int | None = None, column: str | None = None,
                 parameter: str | tuple[str, ...] | None = None):
        super().__init__(message, parameter=parameter)
        self.path, self.row, self.column = path, row, column


class NonFiniteResultError(RcmKinError):
    """A computation gave NaN or an infinity: the inputs are outside what the model can compute.

    ``where`` says where the first non-finite number is (a result's key, or the time reached).
    """

    def __init__(self, message: str = "", *, where: str | None = None,
                 parameter: str | tuple[str, ...] | None = None):
        super().__init__(message, parameter=parameter)
        self.where = where


class RcmKinWarning(UserWarning):
    """Something rcm_kin did differently than asked, or data it left out: a one-line user-facing
    message (the CLI prints it as ``warning: <message>``)."""


class CompilerFallbackWarning(RcmKinWarning):
    """No C compiler (or no writable cache): the compiled code is replaced by a slower
    interpreted equivalent with the same results. Given once per process and reason."""


class EngineFallbackWarning(RcmKinWarning):
    """A closed loop asked for the compiled kernel runs in the readable Python loop instead (the
    controller or the plant has no kernel form): the same result, slower (docs/performance.md)."""


class LogDataWarning(RcmKinWarning):
    """Records of a log left out (cut-off rows, messages missing a field); the log is still read."""


def warn(message: str, category: type[Warning] = RcmKinWarning) -> None:
    """:func:`warnings.warn` of ``message``, located at the first caller outside rcm_kin (the
    line of the user's code that led to it)."""
    frame, level = sys._getframe(1), 1
    while frame.f_back is not None and _inside(frame):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level + 1)


def recording_warnings(function, *args, **kwargs) -> tuple[object, list[tuple[type[Warning], str]]]:
    """``function(*args, **kwargs)`` and the warnings it raised, as ``(category, message)`` pairs:
    what a worker process (a report piece, a Dask batch) sends back with its result, since the
    caller's record of warnings does not reach into another process. :func:`reissue` raises them
    again where the result arrives."""
    with warnings.catch_warnings(record=True) as caught:     # the filters in force decide what is recorded
        value = function(*args, **kwargs)
    return value, [(w.category, str(w.message)) for w in caught]


def reissue(records) -> None:
    """Raise again, in this process, the warnings :func:`recording_warnings` recorded in another."""
    for category, message in records:
        warn(message, category)


def _inside(frame) -> bool:
    name = frame.f_globals.get("__name__", "")
    return name == "rcm_kin" or name.startswith("rcm_kin.")


MAX_TEXT_FILE_BYTES = 8 * 2**20
"""The largest parameter, robot description or gains file read (bytes): about 500 times the
shipped drive file, 20 times a dVRK URDF with every link's inertial."""


def read_bounded(path: Path, what: str, limit: int = MAX_TEXT_FILE_BYTES) -> bytes:
    """The bytes of the file ``path`` (a ``what``), at most ``limit``: a larger file is a
    :class:`WorkLimitError` naming it, read no further (an OSError is ``open``'s)."""
    with open(path, "rb") as fh:
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise WorkLimitError(f"the {what} {path} is larger than {limit // 2**20} MiB: not a {what}",
                             requested=Path(path).stat().st_size, limit=limit)
    return data


def read_text(path: Path, what: str, limit: int = MAX_TEXT_FILE_BYTES) -> str:
    """:func:`read_bounded` decoded as UTF-8 (a UnicodeDecodeError as ``bytes.decode``'s)."""
    return read_bounded(path, what, limit).decode()


def read_toml(path: Path, what: str, text: str | None = None) -> dict:
    """The parsed TOML file ``path`` (or ``text``, already read from it; either at most
    :data:`MAX_TEXT_FILE_BYTES`); a missing, oversized or malformed file is an RcmKinError naming ``what``."""
    try:
        return tomllib.loads(read_text(path, what) if text is None else text)
    except FileNotFoundError:
        raise RcmKinError(f"no {what} at {path}") from None
    except OSError as exc:
        raise RcmKinError(f"cannot read the {what} {path}: {exc.strerror}") from None
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise RcmKinError(f"{path}: not valid TOML ({exc})") from None


def output_folder(path) -> Path:
    """``path`` as a created folder; an OSError becomes an RcmKinError naming the folder."""
    out = Path(path)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RcmKinError(f"cannot create the output folder {out}: {exc.strerror}") from None
    return out


def as_numbers(value, parameter: str, what: str) -> np.ndarray:
    """``value`` as a float array, or an RcmKinError naming ``parameter`` and saying ``what`` it
    should be (strings, None and ragged lists are refused here, not as NumPy's ValueError)."""
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise RcmKinError(f"`{parameter}` must be {what}, got {' '.join(str(value).split())[:60]!r}",
                          parameter=parameter) from None


def as_number(value, parameter: str, unit: str, low: float, high: float, *, low_open: bool = False) -> float:
    """``value`` as a finite float in ``[low, high]`` (``(low, high]`` when ``low_open``), or an
    RcmKinError naming ``parameter`` and the range in ``unit``."""
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        number = math.nan
    if isinstance(value, bool) or not math.isfinite(number) or number > high or number < low \
            or (low_open and number == low):
        bracket = "(" if low_open else "["
        raise RcmKinError(f"`{parameter}` is a number in {bracket}{low:g}, {high:g}] {unit}, got "
                          f"{' '.join(str(value).split())[:40]}", parameter=parameter)
    return number

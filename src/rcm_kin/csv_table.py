"""Large numeric tables as CSV, fast and in bounded memory.

Each value is written with ``DECIMALS`` = 9 decimals, trailing zeros dropped but one kept
(``-30.0``, ``0.08``, ``12.533010697``): the text of ``repr(round(x, 9))`` but for ties in the
last place (the value is scaled by 1e9 and rounded in binary; the written number is within
0.5e-9 of ``x`` plus an ulp). Blocks of rows are formatted by a compiled C function
(:mod:`rcm_kin.csv_native`) or, without a C compiler, by the same rules vectorised in NumPy
(:func:`format_rows_numpy`, slower; timings in docs/performance.md), both in the memory of one
block of text.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

import numpy as np

from rcm_kin.atomic import atomic_open
from rcm_kin.csv_native import native_formatter
from rcm_kin.errors import RcmKinError

DECIMALS = 9
LIMIT = 9.0e9          # |x| * 10**DECIMALS must fit an int64
_CELL = 23             # characters per value: sign, 10 integer digits, point, 9 decimals, 2 separators


def format_rows(table: np.ndarray) -> bytes:
    """CSV text (bytes, one CR LF line per row, no header) of a finite float table (rows, cols):
    the compiled formatter, or :func:`format_rows_numpy` where there is none."""
    table = _checked(table)
    native = native_formatter()
    return native(np.ascontiguousarray(table)) if native is not None else format_rows_numpy(table)


def _checked(table: np.ndarray) -> np.ndarray:
    """``table`` as floats, or a user error unless it is 2-D with columns, finite and below :data:`LIMIT`."""
    table = np.asarray(table, dtype=float)
    if table.ndim != 2 or table.shape[1] == 0:
        raise RcmKinError(f"a CSV table is 2-D with at least one column, got shape {table.shape}")
    if not np.all(np.isfinite(table)) or (table.size and np.abs(table).max() >= LIMIT):
        raise RcmKinError(f"CSV values must be finite and below {LIMIT:g} in magnitude")
    return table


def format_rows_numpy(table: np.ndarray) -> bytes:
    """:func:`format_rows` vectorised in NumPy.

    Vectorised: every value is laid out in a fixed cell of characters, with a mask of those
    written (the sign if negative, the integer digits from the first non-zero one, the point,
    the decimals up to the last non-zero one), and the masked characters are read out in order.
    The cells are built one character position at a time over the whole table."""
    table = _checked(table)
    n = np.rint(np.abs(table) * 10.0 ** DECIMALS).astype(np.int64)
    whole, frac = np.divmod(n, 10 ** DECIMALS)
    chars = np.empty((_CELL,) + table.shape, dtype=np.uint8)
    keep = np.zeros((_CELL,) + table.shape, dtype=bool)
    chars[0], keep[0] = ord("-"), (table < 0) & (n != 0)
    for k in range(10, 0, -1):                     # integer digits, units (position 10) first
        keep[k] = whole > 0 if k < 10 else True    # a digit at this place or above: shown
        whole, digit = np.divmod(whole, 10)
        chars[k] = 48 + digit
    chars[11], keep[11] = ord("."), True
    later = np.zeros(table.shape, dtype=bool)      # a non-zero decimal at or after this one
    for k in range(20, 11, -1):                    # decimals, the last (position 20) first
        frac, digit = np.divmod(frac, 10)
        chars[k] = 48 + digit
        later |= digit != 0
        keep[k] = later
    keep[12] = True
    chars[21], keep[21] = ord(","), True
    chars[21, :, -1], chars[22, :, -1], keep[22, :, -1] = ord("\r"), ord("\n"), True
    return chars.transpose(1, 2, 0)[keep.transpose(1, 2, 0)].tobytes()


def write_csv_blocks(path: str | Path, header: list[str], blocks: Iterable[np.ndarray]) -> Path:
    """Write ``header`` then every block of rows (each a 2-D float array with ``len(header)``
    columns) to ``path``; only one block's text is in memory at a time."""
    path = Path(path)
    try:
        with atomic_open(path, "wb") as fh:
            fh.write((",".join(header) + "\r\n").encode())
            for block in blocks:
                if np.shape(block)[1:] != (len(header),):
                    raise RcmKinError(f"a block of {np.shape(block)} does not fit the {len(header)} columns")
                fh.write(format_rows(block))
    except OSError as exc:
        raise RcmKinError(f"cannot write {path}: {exc.strerror}") from None
    return path

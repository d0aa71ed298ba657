"""The CSV number formatter of :mod:`rcm_kin.csv_table` in C: compiled once and cached on disk.

The C function writes exactly the characters of the NumPy formatter
(:func:`rcm_kin.csv_table.format_rows_numpy`, the tests compare them byte for byte), faster
(docs/performance.md) and without its per-character temporaries. It is built with the C compiler that
compiles the CasADi functions (``$CC``, default ``cc``; :mod:`rcm_kin.symbolic.compiled`) and
cached beside them, named by a SHA-256 of its source, the compile command and the machine.
Without a working compiler :func:`native_formatter` is None after a
:class:`~rcm_kin.errors.CompilerFallbackWarning`, and the tables are formatted by NumPy.
"""

from __future__ import annotations

import ctypes
import functools
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rcm_kin.errors import CompilerFallbackWarning, RcmKinError, warn
from rcm_kin.symbolic.compiled import build_library, cache_key, compiler_command, load_library

COMPILE_FLAGS = ("-std=c99", "-O2", "-fPIC", "-shared")
NAME = "rcm_csv_format_rows"

SOURCE = r"""
#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* The rows of a row-major table (rows x cols doubles, each finite and below 9e9 in magnitude)
 * as CSV text: n = rint(|x| * 1e9); '-' if x < 0 and n > 0, the integer digits of n / 1e9 (at
 * least one), '.', the decimals of n % 1e9 up to the last non-zero one (at least one); ','
 * between values, CR LF after each row (no text for no columns). text holds at least
 * rows * (23 * cols + 2) characters. Returns the number of characters written. */
size_t rcm_csv_format_rows(const double *table, size_t rows, size_t cols, unsigned char *text)
{
    const uint64_t unit = 1000000000u;
    size_t at = 0;
    if (cols == 0) {
        return 0;
    }
    for (size_t i = 0; i < rows; ++i) {
        for (size_t j = 0; j < cols; ++j) {
            const double x = table[i * cols + j];
            uint64_t n = (uint64_t) rint(fabs(x) * 1e9);
            if (x < 0.0 && n != 0) {
                text[at++] = '-';
            }
            uint64_t whole = n / unit, frac = n % unit;
            size_t width = 1;
            for (uint64_t rest = whole / 10; rest != 0; rest /= 10) {
                ++width;
            }
            for (size_t k = at + width; k > at; --k, whole /= 10) {
                text[k - 1] = (unsigned char) ('0' + whole % 10);
            }
            at += width;
            text[at++] = '.';
            size_t shown = 9;
            while (shown > 1 && frac % 10 == 0) {
                frac /= 10;
                --shown;
            }
            for (size_t k = at + shown; k > at; --k, frac /= 10) {
                text[k - 1] = (unsigned char) ('0' + frac % 10);
            }
            at += shown;
            text[at++] = ',';
        }
        text[at - 1] = '\r';                 /* the row's last ',' */
        text[at++] = '\n';
    }
    return at;
}
"""


def native_formatter() -> Callable[[np.ndarray], bytes] | None:
    """The compiled formatter (``table`` C-contiguous float64 (rows, cols), finite, below 9e9 in
    magnitude -> CSV bytes), or None when no C compiler builds it (a warning, once per
    compiler setting and process)."""
    return _formatter(tuple(compiler_command()))


@functools.cache
def _formatter(command: tuple[str, ...]) -> Callable[[np.ndarray], bytes] | None:
    if not command or shutil.which(command[0]) is None:
        return _fallback(f"no C compiler '{command[0] if command else ''}' found (set CC)")
    try:
        _, library = load_library(_build(list(command)), lambda: _build(list(command)), NAME)
    except (OSError, RcmKinError) as exc:
        return _fallback(f"the CSV formatter was not built ({exc})")
    function = getattr(library, NAME)
    function.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_size_t, ctypes.c_void_p)
    function.restype = ctypes.c_size_t

    def format_rows(table: np.ndarray) -> bytes:
        rows, cols = table.shape
        text = np.empty(rows * (23 * cols + 2), dtype=np.uint8)
        return text[:function(table.ctypes.data, rows, cols, text.ctypes.data)].tobytes()
    return format_rows


def _fallback(reason: str) -> None:
    warn(f"{reason}: CSV tables are formatted by NumPy, slower", CompilerFallbackWarning)
    return None


def _build(command: list[str]) -> Path:
    """The cached shared library, compiled first if absent (:func:`build_library`), keyed by the
    source, the compiler command and the machine (:func:`cache_key`)."""
    return build_library(NAME, cache_key(SOURCE, " ".join(command + list(COMPILE_FLAGS))), SOURCE, command,
                         COMPILE_FLAGS)

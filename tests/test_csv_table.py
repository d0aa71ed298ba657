"""The CSV writer (compiled C formatter, NumPy fallback): Python's own formatting and integer
arithmetic as the references, and the two formatters byte for byte."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from rcm_kin.csv_native import _formatter, native_formatter
from rcm_kin.csv_table import format_rows, format_rows_numpy, write_csv_blocks
from rcm_kin.errors import CompilerFallbackWarning, RcmKinError


def test_values_read_back_within_the_rounding():
    rng = np.random.default_rng(0)
    x = np.column_stack([rng.normal(0, 50, 5000), rng.uniform(-1e-6, 1e-6, 5000), rng.normal(0, 1e6, 5000),
                         rng.integers(-10**9, 10**9, 5000).astype(float)])
    lines = format_rows(x).decode().split("\r\n")
    assert lines[-1] == "" and len(lines) == len(x) + 1
    back = np.array([[float(v) for v in line.split(",")] for line in lines[:-1]])
    # 9 decimals: within half a unit of the last place, plus the rounding of |x| * 1e9 in binary
    assert np.all(np.abs(back - x) <= 0.5e-9 + 4 * np.finfo(float).eps * np.abs(x))


def test_text_equals_pythons_repr_of_the_rounded_value():
    """Where repr is positional and no tie is near: the same characters as ``repr(round(x, 9))``."""
    values = np.array([[-30.0, 0.08, 12.533010697, -86.241590029, 0.0, 1e4, -0.5, 123456789.000000001,
                        -29.94, 7.0, 0.000123456, 3.141592653589793]])
    expect = ",".join(repr(round(float(v), 9)) for v in values[0])
    assert format_rows(values).decode() == expect + "\r\n"
    assert format_rows(np.array([[-1e-12, 4e-10, 6e-10, 1e-9]])).decode() == "0.0,0.0,0.000000001,0.000000001\r\n"


def test_blocks_make_one_file_the_csv_module_reads(tmp_path):
    blocks = [np.arange(6.0).reshape(2, 3), np.array([[1.5, -2.25, 1e3]])]
    path = write_csv_blocks(tmp_path / "t.csv", ["a", "b", "c"], iter(blocks))
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows == [["a", "b", "c"], ["0.0", "1.0", "2.0"], ["3.0", "4.0", "5.0"], ["1.5", "-2.25", "1000.0"]]


def test_refuses_what_it_cannot_write(tmp_path):
    for bad in (np.array([[np.nan]]), np.array([[1e10]]), np.zeros(3), np.zeros((2, 0))):
        for formatter in (format_rows, format_rows_numpy):
            with pytest.raises(RcmKinError):
                formatter(bad)
    with pytest.raises(RcmKinError, match="does not fit the 2 columns"):
        write_csv_blocks(tmp_path / "t.csv", ["a", "b"], [np.zeros((1, 3))])


def reference_text(x: float) -> str:
    """The rule of the module written with Python integers: n = round(|x| * 1e9) (the same binary
    product, rounded half to even like rint), its integer part, '.', its 9 decimals without
    trailing zeros (one kept), '-' when negative and not rounded to zero."""
    n = round(abs(x) * 1e9)
    text = f"{n // 10**9}.{n % 10**9:09d}".rstrip("0")
    return ("-" if x < 0 and n else "") + text + ("0" if text.endswith(".") else "")


def awkward_table(rows: int, seed: int) -> np.ndarray:
    """Columns that exercise every branch: signs, -0.0 and tiny negatives (written 0.0), exact
    halves of the last decimal (ties), whole numbers, up to 10 integer digits, 0..9 decimals."""
    rng = np.random.default_rng(seed)
    decimals = rng.integers(0, 10, rows)
    return np.column_stack([rng.normal(0, 50, rows), rng.uniform(-1e-6, 1e-6, rows), rng.normal(0, 1e6, rows),
                            rng.integers(-10**9, 10**9, rows).astype(float), rng.uniform(-8.9e9, 8.9e9, rows),
                            np.round(rng.normal(0, 10, rows) * 10.0**decimals) / 10.0**decimals,
                            np.full(rows, -0.0), rng.integers(-3, 4, rows) * 5e-10, rng.integers(-3, 4, rows) * 1e-12])


def test_both_formatters_write_pythons_integer_rule_exactly():
    x = awkward_table(3000, 2)
    expect = "".join(",".join(reference_text(float(v)) for v in row) + "\r\n" for row in x).encode()
    assert format_rows_numpy(x) == expect
    assert format_rows(x) == expect


def test_compiled_formatter_equals_the_numpy_one_byte_for_byte():
    native = native_formatter()
    if native is None:
        pytest.skip("no C compiler: the NumPy formatter is the one used (test_without_a_compiler...)")
    for seed in range(3):
        x = awkward_table(20000, seed)
        assert native(np.ascontiguousarray(x)) == format_rows_numpy(x)
    assert format_rows(np.zeros((0, 3))) == b""


def test_without_a_compiler_numpy_formats_after_one_warning(monkeypatch, capsys, recwarn):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    _formatter.cache_clear()
    assert native_formatter() is None
    assert [str(w.message).split(":")[0] for w in recwarn] == ["no C compiler '/nonexistent/cc' found (set CC)"]
    assert recwarn[0].category is CompilerFallbackWarning
    recwarn.clear()
    x = awkward_table(500, 5)
    assert format_rows(x) == format_rows_numpy(x)
    assert not recwarn.list                              # said once per process
    assert capsys.readouterr() == ("", "")               # through warnings, never printed

"""The vectorised CSV writer: Python's own formatting as the reference."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from rcm_kin.csv_table import format_rows, write_csv_blocks
from rcm_kin.errors import RcmKinError


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
    for bad in (np.array([[np.nan]]), np.array([[1e10]]), np.zeros(3)):
        with pytest.raises(RcmKinError):
            format_rows(bad)
    with pytest.raises(RcmKinError, match="does not fit the 2 columns"):
        write_csv_blocks(tmp_path / "t.csv", ["a", "b"], [np.zeros((1, 3))])

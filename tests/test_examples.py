"""The scripts in examples/ run as a user runs them (``python examples/x.py OUT_DIR``): each
exits 0 within its time and writes what it says it writes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rcm_kin.control.schedule_file import read_schedule_file

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run_example(name: str, out: Path) -> str:
    done = subprocess.run([sys.executable, str(EXAMPLES / name), str(out)], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_every_example_is_tested():
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == ["linear_model.py", "meshcat_view.py", "torque_map.py",
                                                             "tuned_gains.py"]


def test_torque_map_example(tmp_path):
    out = run_example("torque_map.py", tmp_path / "maps")
    assert "PWM" in out
    csv = tmp_path / "maps" / "torque_map.csv"
    header = csv.read_text().splitlines()[0].split(",")
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    arrays = np.load(tmp_path / "maps" / "torque_map.npz")
    assert table.shape == (61 * 61, len(header)) and np.all(np.isfinite(table))
    assert sorted(arrays.files) == sorted(header)
    assert np.allclose(arrays["pwm_pitch"], table[:, header.index("pwm_pitch")], atol=1e-9)


def test_linear_model_example(tmp_path):
    out = run_example("linear_model.py", tmp_path / "linear")
    assert "poles" in out
    model = json.loads((tmp_path / "linear" / "linear_model.json").read_text())
    assert np.shape(model["A"]) == (6, 6) and np.shape(model["B"]) == (6, 3)


def test_meshcat_view_example(tmp_path):
    pytest.importorskip("meshcat")
    run_example("meshcat_view.py", tmp_path / "view")
    page = (tmp_path / "view" / "psm.html").read_text()
    assert page.lstrip().lower().startswith("<!doctype html") or "<html" in page[:1000].lower()
    assert "psm" in page


def test_tuned_gains_example(tmp_path):
    """The small tuning writes a schedule the simulator reads back with the law it was tuned for."""
    out = run_example("tuned_gains.py", tmp_path / "tuned")
    assert "thesis law" in out and "this tuning" in out
    loaded = read_schedule_file(tmp_path / "tuned" / "gains.json")
    assert loaded.flags == {"scheduled": True, "gravity": True, "track_velocity": True, "friction": True}
    assert "rcm_control_law" in (tmp_path / "tuned" / "gain_schedule.h").read_text()


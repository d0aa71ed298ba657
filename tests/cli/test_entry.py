"""The ``rcm-kin`` console command: :func:`rcm_kin.cli.run` is what the installed script and
``python -m rcm_kin.cli`` call; it runs :func:`rcm_kin.cli.main`, freezes the heap and exits with
main's status. A process that calls ``main`` itself keeps its garbage collector as it was."""

from __future__ import annotations

import gc
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import rcm_kin.cli

ROOT = Path(__file__).resolve().parents[2]


def test_the_console_script_is_run():
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    module, name = scripts["rcm-kin"].split(":")
    assert (module, name) == ("rcm_kin.cli", "run")


@pytest.mark.parametrize("status", [0, 2, 130])
def test_run_exits_with_mains_status_after_freezing(monkeypatch, status):
    calls = []
    monkeypatch.setattr(rcm_kin.cli, "main", lambda: calls.append("main") or status)
    monkeypatch.setattr(gc, "freeze", lambda: calls.append("freeze"))
    with pytest.raises(SystemExit) as stop:
        rcm_kin.cli.run()
    assert stop.value.code == status
    assert calls == ["main", "freeze"]


def test_main_leaves_the_collector_alone():
    frozen = gc.get_freeze_count()
    assert rcm_kin.cli.main(["info", "psm"]) == 0
    assert gc.get_freeze_count() == frozen


def test_python_m_writes_its_files_output_and_status(tmp_path):
    """Freezing before the shutdown loses nothing a command writes: its tables are whole on disk,
    the JSON whole on stdout, a user error one line with status 2."""
    out = tmp_path / "maps"
    run = subprocess.run([sys.executable, "-m", "rcm_kin.cli", "torque-map", "psm", "--roll=-10:10:5",
                          "--pitch=-10:10:3", "--no-figures", "--out", str(out)], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    rows = (out / "torque_map.csv").read_text().splitlines()
    assert len(rows) == 1 + 5 * 3 and all(row.count(",") == rows[0].count(",") for row in rows)
    ok = subprocess.run([sys.executable, "-m", "rcm_kin.cli", "fk", "psm", "0", "0", "0.1", "--json"],
                        capture_output=True, text=True, timeout=120)
    assert ok.returncode == 0 and ok.stdout.startswith("{") and ok.stdout.rstrip().endswith("}")
    bad = subprocess.run([sys.executable, "-m", "rcm_kin.cli", "fk", "psm", "0", "0", "9"],
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and bad.stderr.startswith("error: ")

"""What a command's outputs are owed (README, "Bad input: the contract"): files in an output folder
that rcm-kin did not write are not replaced without ``--force``; one folder serves one run at a
time; SIGTERM and Ctrl-C end a run with one ``error:`` line, no file under a final name written
after the signal, no unfinished temporary, no worker process left and no traceback (Dask's workers
included)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rcm_kin.atomic import MANIFEST, PARTIAL, claim
from rcm_kin.cli import main

SRC = Path(__file__).resolve().parents[2] / "src"
ENV = {**os.environ, "PYTHONPATH": str(SRC), "OPENBLAS_NUM_THREADS": "1"}


def run(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_a_folder_output_keeps_the_users_files(capsys, tmp_path):
    out = tmp_path / "maps"
    assert run(capsys, "torque-map", "psm", "--out", str(out), "--no-figures")[0] == 0
    assert run(capsys, "torque-map", "psm", "--out", str(out), "--no-figures")[0] == 0    # its own files
    (out / "torque_map.csv").write_text("my notes\n")
    status, _, err = run(capsys, "torque-map", "psm", "--out", str(out), "--no-figures")
    assert status == 2 and err.count("\n") == 1 and "rcm-kin did not write it" in err and "--force" in err
    assert (out / "torque_map.csv").read_text() == "my notes\n"
    assert run(capsys, "torque-map", "psm", "--out", str(out), "--no-figures", "--force")[0] == 0
    assert (out / "torque_map.csv").read_text().startswith("roll")


def test_a_folder_in_use_by_another_run_is_refused(capsys, tmp_path):
    out = tmp_path / "gains"
    with claim(out, folder=True):          # another run holds it (a separate lock, as another process's)
        status, _, err = run(capsys, "schedule", "psm", "--out", str(out))
    assert status == 2 and err.startswith("error: another run is writing to") and err.count("\n") == 1
    assert not out.exists()           # nothing written: the folder the other claim made is removed with it


def test_the_report_lists_its_files_not_the_manifest(capsys, tmp_path, monkeypatch):
    """The manifest is the run's bookkeeping, not one of the report's files (``--json`` "files")."""
    import json

    import rcm_kin.report as report
    from rcm_kin.atomic import write_text

    def fake_report(out, data, points, progress=False):
        return write_text(Path(out) / "index.html", "<html></html>")

    monkeypatch.setattr(report, "write_report", fake_report)
    status, out, _ = run(capsys, "report", "--out", str(tmp_path / "r"), "--json")
    assert status == 0 and json.loads(out)["files"] == ["index.html"]
    assert (tmp_path / "r" / MANIFEST).exists()


def _stopped(argv, sig, ready, after: float, group: bool = False, seconds: float = 60):
    """Run ``rcm-kin argv`` in a new process group, send ``sig`` (to the group when ``group``, as Ctrl-C
    does) ``after`` seconds after ``ready`` appears (a path: e.g. the output folder the run claims when
    it begins; or a test of the run's process id); (status, stderr, seconds to stop, the group's id)."""
    child = subprocess.Popen([sys.executable, "-m", "rcm_kin.cli", *argv], stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, env=ENV, start_new_session=True)
    appeared = ready if callable(ready) else lambda pid: ready.exists()
    try:
        start = time.monotonic()
        while not appeared(child.pid) and time.monotonic() - start < seconds and child.poll() is None:
            time.sleep(0.02)
        time.sleep(after)
        if child.poll() is not None:
            pytest.fail(f"the run ended before the signal: {child.stderr.read().decode()[-300:]}")
        stopped = time.monotonic()
        os.killpg(child.pid, sig) if group else child.send_signal(sig)
        err = child.stderr.read()
        child.wait(timeout=30)
        return child.returncode, err.decode(), time.monotonic() - stopped, child.pid
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)


def _errors_only(stderr: str) -> list[str]:
    """The lines of stderr that are not a progress bar's."""
    return [line for line in stderr.replace("\r", "\n").splitlines() if line.strip() and "|" not in line]


def _processes_in_group(pgid: int) -> list[str]:
    found = subprocess.run(["ps", "-eo", "pgid=,pid=,comm="], capture_output=True, text=True).stdout
    return [line for line in found.splitlines() if line.split()[0] == str(pgid)]


@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_stopped_torque_map_leaves_no_file(tmp_path, sig, status):
    """The issue's case: a 1001 x 1001 map killed mid-write left a complete-looking CSV."""
    out = tmp_path / "maps"
    code, stderr, seconds, _ = _stopped(["torque-map", "psm", "--roll=-30:30:1001", "--pitch=-30:30:1001",
                                      "--out", str(out), "--no-figures"], sig, out, 0.3)
    assert code == status and seconds < 10
    assert _errors_only(stderr) == ([f"error: {'terminated (SIGTERM)' if sig == signal.SIGTERM else 'interrupted'}"
                                     + (": nothing written under a final name after the signal"
                                        if sig == signal.SIGTERM else "")])
    left = sorted(p.name for p in out.iterdir()) if out.exists() else []      # a folder left empty is removed
    assert "torque_map.csv" not in left and not any(PARTIAL in name for name in left)


@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_torque_map_stopped_while_its_figures_are_drawn_leaves_no_partial_file_nor_process(tmp_path, sig, status):
    """The figures are drawn in three processes (rcm_kin.plotting.draw_apart): SIGTERM to the run, or
    Ctrl-C to its whole process group, stops them all with one line; a figure is there whole or not at all."""
    out = tmp_path / "maps"

    def drawing(pid: int) -> bool:       # the figures' processes forked, or (one core) a figure begun
        return len(_processes_in_group(pid)) > 1 or (out.exists() and any(
            PARTIAL in p.name and p.suffix == ".png" for p in out.iterdir()))

    # the signal lands while the figures are drawn (0.3-0.5 s on two cores), a few hundredths after they begin
    code, stderr, seconds, group = _stopped(["torque-map", "psm", "--roll=-30:30:301", "--pitch=-30:30:301", "--out",
                                             str(out)], sig, drawing, 0.05, group=sig == signal.SIGINT)
    assert code == status and seconds < 10, stderr[-2000:]
    assert _errors_only(stderr) == ([f"error: {'terminated (SIGTERM)' if sig == signal.SIGTERM else 'interrupted'}"
                                     + (": nothing written under a final name after the signal"
                                        if sig == signal.SIGTERM else "")])
    deadline = time.monotonic() + 10
    while _processes_in_group(group) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _processes_in_group(group) == []
    left = sorted(p.name for p in out.iterdir()) if out.exists() else []
    assert not any(PARTIAL in name for name in left), left
    for name in left:
        if name.endswith(".png"):                  # whole: PNG's end chunk is there
            assert (out / name).read_bytes().endswith(b"IEND\xaeB`\x82"), name


@pytest.mark.slow
@pytest.mark.parametrize("samples, after", [(64, 1.5), (400, 6.0)], ids=["process pool", "Dask cluster"])
@pytest.mark.parametrize("sig, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_stopped_monte_carlo_stops_its_workers_quietly(tmp_path, sig, status, samples, after):
    """Ctrl-C reaches the whole process group, the pool's or Dask's workers included: one line, no
    traceback, and no process of the run left behind (a small run on forked processes, a large one
    on an embedded Dask cluster)."""
    out = tmp_path / "mc"
    # 30 s runs: a sample takes about 0.13 s of a core, so the signal lands mid-run (the default 6 s
    # sinusoid's 64 samples end in about 1.5 s now, and a signal in the interpreter's exit kills it)
    code, stderr, seconds, group = _stopped(["robustness", "psm", "--controller", "p", "--experiment", "sine",
                                             "--duration", "30", "--samples", str(samples), "--workers", "2",
                                             "--out", str(out)], sig, out, after, group=sig == signal.SIGINT)
    assert code == status and seconds < 15, stderr[-2000:]
    assert len(_errors_only(stderr)) == 1 and _errors_only(stderr)[0].startswith("error: "), stderr[-2000:]
    assert "Traceback" not in stderr
    deadline = time.monotonic() + 10
    while _processes_in_group(group) and time.monotonic() - deadline < 0:
        time.sleep(0.2)
    assert _processes_in_group(group) == []

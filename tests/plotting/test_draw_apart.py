"""Two groups of figures at once (:func:`rcm_kin.plotting.draw_apart` on :func:`rcm_kin.apart.run_apart`):
the forked part runs in another process and its result, warnings and errors come back here (an error
as one line); a stopped run leaves no process; ``torque-map``'s figures drawn apart are the bytes drawn
in one process, and a figure that fails in the child is the command's one-line error."""

from __future__ import annotations

import gc
import os
import signal
import threading
import time
import warnings

import numpy as np
import pytest
from tqdm import tqdm

from rcm_kin import apart
from rcm_kin import plotting as figures
from rcm_kin.atomic import MANIFEST, PARTIAL
from rcm_kin.cli import main
from rcm_kin.errors import RcmKinError, RcmKinWarning
from rcm_kin.model import load_robot
from rcm_kin.parallel import machine_workers
from rcm_kin.statics import maps

two_cores = pytest.mark.skipif(apart.cores() < 2, reason="one core: run_apart runs both parts here")


@pytest.fixture(autouse=True)
def only_this_thread():
    """run_apart forks only while no other thread runs. An earlier test's progress bar leaves tqdm's
    monitor thread behind (it lives as long as the process, as in a user's session with a bar
    shown); it is stopped here by tqdm's own ``exit``. Any other thread fails the test's
    precondition by name rather than silently running both parts here."""
    monitor = getattr(tqdm, "monitor", None)
    if monitor is not None:
        monitor.exit()
        tqdm.monitor = None
    others = [t.name for t in threading.enumerate() if t is not threading.main_thread()]
    assert not others, f"threads other than this test's: {others}"


def test_cores_is_the_twin_of_machine_workers():
    assert apart.cores() == machine_workers()


@two_cores
def test_the_forked_part_runs_in_another_process_at_the_same_time(tmp_path):
    started = tmp_path / "child started"

    def forked():
        started.write_text("")
        return os.getpid()

    def here():
        deadline = time.monotonic() + 20            # the child starts while this part still runs
        while not started.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        return started.exists(), os.getpid()

    child, (overlapped, parent) = apart.run_apart(forked, here)
    assert parent == os.getpid() and child != parent and overlapped


def test_without_fork_both_run_here_one_after_the_other():
    order = []
    result = apart.run_apart(lambda: order.append("forked") or os.getpid(), lambda: order.append("here") or 7,
                             fork=False)
    assert result == (os.getpid(), 7) and order == ["forked", "here"]


def _pids() -> tuple:
    return apart.run_apart(os.getpid, os.getpid)


@two_cores
def test_in_a_pool_worker_both_run_in_the_worker():
    """The report draws the torque map in its pool's workers: no child of a worker (the pool has the
    cores; a worker the pool stops would leave it behind)."""
    from rcm_kin.parallel import process_pool

    with process_pool(1) as pool:
        worker, (forked, here) = pool.submit(os.getpid).result(), pool.submit(_pids).result()
    assert forked == here == worker != os.getpid()


def test_while_another_thread_runs_both_run_here():
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert apart.run_apart(os.getpid, os.getpid) == (os.getpid(), os.getpid())
    finally:
        stop.set()
        other.join()


@pytest.mark.parametrize("enabled", [True, False])
def test_the_collector_is_paused_while_the_block_runs_and_only_then(enabled):
    before = gc.isenabled()
    (gc.enable if enabled else gc.disable)()
    try:
        with apart.paused_collector():
            inside = gc.isenabled()
        after = gc.isenabled()
    finally:
        (gc.enable if before else gc.disable)()
    assert inside is False and after is enabled


def test_draw_apart_pauses_the_collector(monkeypatch):
    monkeypatch.setattr(figures, "run_apart", lambda forked, here, fork, what: (forked(), here()))
    assert figures.draw_apart(gc.isenabled, lambda: 2) == (False, 2) and gc.isenabled()


@two_cores
def test_the_childs_warnings_are_raised_here():
    def forked():
        warnings.warn("a warning from the child", RcmKinWarning)
        return 1

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert apart.run_apart(forked, lambda: 2) == (1, 2)
    assert [(w.category, str(w.message)) for w in caught] == [(RcmKinWarning, "a warning from the child")]


@two_cores
def test_the_childs_rcm_kin_error_is_raised_here_as_it_was():
    def forked():
        raise RcmKinError("no figure: `dpi` too small", parameter="dpi")

    with pytest.raises(RcmKinError, match="^no figure: `dpi` too small$") as caught:
        apart.run_apart(forked, lambda: None)
    assert caught.value.parameters == ("dpi",)


@two_cores
def test_any_other_error_of_the_child_is_one_line_naming_it():
    def forked():
        raise ZeroDivisionError("division by zero\nin a figure")

    with pytest.raises(RcmKinError, match="^the forked process failed: ZeroDivisionError: division by zero in a "
                                          "figure$"):
        apart.run_apart(forked, lambda: None)


@two_cores
def test_a_child_that_dies_is_an_error_naming_how():
    with pytest.raises(RcmKinError, match=r"ended without its result \(stopped by SIGKILL\)"):
        apart.run_apart(lambda: os.kill(os.getpid(), 9), lambda: None)


@two_cores
def test_the_child_ends_on_sigint_and_sigterm_unless_they_are_ignored_here():
    def dispositions():
        return [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)]

    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)       # as in a job a shell starts in the background
    try:
        ignored, _ = apart.run_apart(dispositions, lambda: None)
    finally:
        signal.signal(signal.SIGINT, previous)
    default, _ = apart.run_apart(dispositions, lambda: None)
    assert ignored == [signal.SIG_IGN, signal.SIG_DFL] and default == [signal.SIG_DFL, signal.SIG_DFL]


@two_cores
def test_when_this_part_fails_the_child_is_ended_and_waited_for(tmp_path):
    pid_file = tmp_path / "pid"

    def forked():
        pid_file.write_text(str(os.getpid()))
        time.sleep(60)

    def here():
        deadline = time.monotonic() + 20
        while not pid_file.exists() and time.monotonic() < deadline:
            time.sleep(0.01)
        raise KeyboardInterrupt

    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        apart.run_apart(forked, here)
    assert time.monotonic() - start < 20
    with pytest.raises(ProcessLookupError):         # ended and reaped: no such process any more
        os.kill(int(pid_file.read_text()), 0)


def test_draw_apart_imports_matplotlib_before_the_fork(monkeypatch):
    seen = []
    monkeypatch.setattr(figures, "run_apart", lambda forked, here, fork, what: seen.append(fork) or (forked(), here()))
    assert figures.draw_apart(lambda: "matplotlib.figure" in __import__("sys").modules, lambda: 2) == (True, 2)
    assert seen == [True]


def small_map(out, monkeypatch, cores: int):
    """``torque-map psm`` on a small grid into ``out`` with ``cores`` cores seen (1: all figures here)."""
    monkeypatch.setattr(apart, "cores", lambda: cores)
    assert main(["torque-map", "psm", "--roll=-20:20:9", "--pitch=-20:20:7", "--out", str(out)]) == 0
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}


@two_cores
def test_the_figures_drawn_apart_are_those_drawn_in_one_process(tmp_path, monkeypatch, capsys):
    apart_files = small_map(tmp_path / "apart", monkeypatch, 2)
    here_files = small_map(tmp_path / "here", monkeypatch, 1)
    names = ["torque_map.csv", "torque_map.png", "trend_curves.png", "insertion_map.csv", "insertion_map.png"]
    assert sorted(apart_files) == sorted([*names, MANIFEST])
    assert {n: apart_files[n] for n in names} == {n: here_files[n] for n in names}
    assert f'"{names[1]}"' in apart_files[MANIFEST].decode()        # the child's files are the run's own


@two_cores
def test_a_figure_failing_in_the_child_is_the_commands_one_line_error(tmp_path, monkeypatch, capsys):
    def broken(gmap, drive, path, *args, **kwargs):
        raise np.linalg.LinAlgError("singular matrix")

    monkeypatch.setattr(maps, "effort_heatmaps", broken)
    out = tmp_path / "maps"
    assert main(["torque-map", "psm", "--roll=-20:20:9", "--pitch=-20:20:7", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err == "error: the process drawing the figures failed: LinAlgError: singular matrix\n"
    left = sorted(p.name for p in out.iterdir())
    assert "torque_map.png" not in left and not any(PARTIAL in name for name in left)


@two_cores
def test_torque_maps_three_figures_are_drawn_in_three_processes(tmp_path, monkeypatch):
    pids = tmp_path / "pids"
    pids.mkdir()
    for name in ("effort_heatmaps", "thesis_trend_curves", "insertion_curves"):
        def drawn(*args, _draw=getattr(maps, name), _name=name, **kwargs):
            (pids / _name).write_text(str(os.getpid()))
            return _draw(*args, **kwargs)
        monkeypatch.setattr(maps, name, drawn)
    small_map(tmp_path / "maps", monkeypatch, 2)
    drawn_by = {p.name: int(p.read_text()) for p in pids.iterdir()}
    assert len(drawn_by) == 3 and len(set(drawn_by.values())) == 3
    assert drawn_by["insertion_curves"] == os.getpid()


@two_cores
def test_the_trend_figure_failing_in_the_second_child_is_the_commands_one_line_error(tmp_path, monkeypatch, capsys):
    def broken(gmap, path, *args, **kwargs):
        raise ValueError("no trend")

    monkeypatch.setattr(maps, "thesis_trend_curves", broken)
    out = tmp_path / "maps"
    assert main(["torque-map", "psm", "--roll=-20:20:9", "--pitch=-20:20:7", "--out", str(out)]) == 2
    assert capsys.readouterr().err == "error: the process drawing the figures failed: ValueError: no trend\n"
    left = sorted(p.name for p in out.iterdir())
    assert "trend_curves.png" not in left and not any(PARTIAL in name for name in left)


def test_the_gravity_maps_progress_bar_leaves_no_thread_that_would_stop_the_fork():
    """tqdm starts a monitor thread with a bar; run_apart does not fork while another thread runs."""
    robot = load_robot("psm")
    poses = np.zeros((5000, 3))
    poses[:, 2] = 0.1
    maps.driven_gravity(robot, maps.map_drive(robot, None), poses, progress=True, block=1000)
    assert tqdm.monitor is None or not tqdm.monitor.is_alive()
    assert threading.active_count() == 1

"""Files written whole or not at all (rcm_kin.atomic): a write that raises or is interrupted leaves
no file under the final name and no temporary, a file already there is kept as it was, a process
killed mid-write never leaves a final-looking file, and a link out of the output's folder is
refused. What a plain write gives (permissions, content) is the reference, made with ``open``."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rcm_kin.atomic import MANIFEST, PARTIAL, atomic_open, atomic_path, claim, stop_writes, write_bytes, write_text
from rcm_kin.csv_table import write_csv_blocks
from rcm_kin.errors import RcmKinError

SRC = Path(__file__).resolve().parents[1] / "src"


def test_a_complete_write_gives_the_file_a_plain_write_gives(tmp_path):
    plain = tmp_path / "plain.txt"
    with open(plain, "w", newline="") as fh:
        fh.write("a,b\r\n1,2\n")
    written = write_text(tmp_path / "atomic.txt", "a,b\r\n1,2\n", newline="")
    assert written.read_bytes() == plain.read_bytes()
    assert stat.S_IMODE(written.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)   # the umask's mode
    assert sorted(p.name for p in tmp_path.iterdir()) == ["atomic.txt", "plain.txt"]      # no temporary left


def test_a_writer_raising_half_way_leaves_no_file(tmp_path):
    final = tmp_path / "table.csv"
    with pytest.raises(RuntimeError, match="half-way"):
        with atomic_open(final, "w") as fh:
            fh.write("x,y\n1,2\n")
            fh.flush()
            assert not final.exists() and len(list(tmp_path.iterdir())) == 1     # the temporary, not the file
            raise RuntimeError("half-way")
    assert list(tmp_path.iterdir()) == []


def test_a_keyboard_interrupt_mid_write_leaves_no_file(tmp_path):
    """The library's CSV writer interrupted between two blocks (what Ctrl-C does)."""
    final = tmp_path / "map.csv"

    def blocks():
        yield np.zeros((3, 2))
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_csv_blocks(final, ["a", "b"], blocks())
    assert list(tmp_path.iterdir()) == []


def test_a_failed_rewrite_keeps_the_existing_file(tmp_path):
    final = tmp_path / "params.toml"
    final.write_text("robot = \"psm\"\n")
    final.chmod(0o640)
    with pytest.raises(RcmKinError, match="does not fit"):
        write_csv_blocks(final, ["a", "b"], [np.zeros((2, 2)), np.zeros((2, 3))])   # the second block is bad
    with pytest.raises(SystemExit):
        with atomic_path(final) as temporary:
            temporary.write_text("half")
            raise SystemExit(1)
    assert final.read_text() == "robot = \"psm\"\n" and list(tmp_path.iterdir()) == [final]
    write_bytes(final, b"new\n")                                 # a rewrite that completes keeps the mode
    assert final.read_bytes() == b"new\n" and stat.S_IMODE(final.stat().st_mode) == 0o640


def test_a_library_writing_by_path_gets_the_final_suffix(tmp_path):
    """np.savetxt compresses a ``.gz`` name: the temporary keeps the suffix, so the file is the same."""
    final = tmp_path / "rows.csv.gz"
    with atomic_path(final) as temporary:
        assert temporary.parent == tmp_path and temporary.suffix == ".gz" and PARTIAL in temporary.name
        np.savetxt(temporary, np.eye(2), delimiter=",")
    np.savetxt(tmp_path / "plain.csv.gz", np.eye(2), delimiter=",")
    assert np.array_equal(np.loadtxt(final, delimiter=","), np.eye(2))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plain.csv.gz", "rows.csv.gz"]


def test_a_link_out_of_the_folder_is_refused(tmp_path):
    outside, folder = tmp_path / "notes.txt", tmp_path / "out"
    outside.write_text("my notes\n")
    folder.mkdir()
    (folder / "torque_map.csv").symlink_to(Path("..") / "notes.txt")
    with pytest.raises(RcmKinError, match="outside its folder") as caught:
        write_text(folder / "torque_map.csv", "a,b\n")
    assert "\n" not in str(caught.value)
    assert outside.read_text() == "my notes\n" and (folder / "torque_map.csv").is_symlink()
    assert sorted(p.name for p in folder.iterdir()) == ["torque_map.csv"]


def test_a_link_inside_the_folder_is_written_through(tmp_path):
    (tmp_path / "latest.csv").symlink_to("run_3.csv")
    write_text(tmp_path / "latest.csv", "a\n")
    assert (tmp_path / "latest.csv").is_symlink() and (tmp_path / "run_3.csv").read_text() == "a\n"


def test_a_missing_folder_names_the_final_file(tmp_path):
    with pytest.raises(FileNotFoundError) as caught:
        write_text(tmp_path / "nowhere" / "x.json", "{}")
    assert caught.value.filename == str(tmp_path / "nowhere" / "x.json")


CHILD = """
import sys, time
from rcm_kin.atomic import atomic_open
with atomic_open(sys.argv[1], "w") as fh:
    fh.write("x,y\\n" + "1,2\\n" * 1000)
    fh.flush()
    print("writing", flush=True)
    time.sleep(60)
"""


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_process_stopped_mid_write_leaves_no_final_file(tmp_path, signum):
    """SIGINT (Ctrl-C) cleans up: nothing is left. SIGTERM kills outright here (no handler yet):
    what is left is only the temporary, whose name says it is partial, never the final name."""
    final = tmp_path / "torque_map.csv"
    env = {**os.environ, "PYTHONPATH": str(SRC), "OPENBLAS_NUM_THREADS": "1"}
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(final)], stdout=subprocess.PIPE,
                             stderr=subprocess.DEVNULL, text=True, env=env)
    try:
        assert child.stdout.readline() == "writing\n"
        child.send_signal(signum)
        child.wait(timeout=30)
    finally:
        child.kill()
        child.wait()
    assert child.returncode != 0 and not final.exists()
    left = [p.name for p in tmp_path.iterdir()]
    assert left == [] if signum == signal.SIGINT else all(PARTIAL in name for name in left)


# ---- owned outputs: claims on a folder or a file (what the command line takes for each run) ----

def test_a_claimed_folder_replaces_only_its_own_files(tmp_path):
    """Our own earlier output is replaced; a user's file, or ours changed since, is not (without force)."""
    folder = tmp_path / "maps"
    with claim(folder, folder=True):
        write_text(folder / "map.csv", "ours\n")
    with claim(folder, folder=True):             # a second run: its own earlier file, unchanged
        write_text(folder / "map.csv", "ours again\n")
    assert (folder / "map.csv").read_text() == "ours again\n"
    (folder / "notes.txt").write_text("the user's")
    with claim(folder, folder=True), pytest.raises(RcmKinError, match="did not write it"):
        write_text(folder / "notes.txt", "ours")
    assert (folder / "notes.txt").read_text() == "the user's"
    (folder / "map.csv").write_text("edited by hand, longer than before\n")
    with claim(folder, folder=True), pytest.raises(RcmKinError, match="changed since"):
        write_text(folder / "map.csv", "ours")
    with claim(folder, folder=True, force=True):
        write_text(folder / "notes.txt", "ours")
    assert (folder / "notes.txt").read_text() == "ours"
    # the edited map is the user's now: no longer in the manifest (a later run refuses it too)
    assert set(json.loads((folder / MANIFEST).read_text())["files"]) == {"notes.txt"}


def test_a_claimed_folder_is_locked_against_a_second_run(tmp_path):
    """A second claim on the folder (another process, as a second command would) is refused at once."""
    folder = tmp_path / "out"
    code = ("import sys\nfrom rcm_kin.atomic import claim\nfrom rcm_kin.errors import RcmKinError\n"
            "try:\n    with claim(sys.argv[1], folder=True): pass\n"
            "except RcmKinError as e:\n    print(e); sys.exit(2)\n")
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    with claim(folder, folder=True):
        held = subprocess.run([sys.executable, "-c", code, str(folder)], capture_output=True, text=True, env=env)
    free = subprocess.run([sys.executable, "-c", code, str(folder)], capture_output=True, text=True, env=env)
    assert held.returncode == 2 and "another run is writing to" in held.stdout
    assert free.returncode == 0


def test_a_claimed_file_that_appears_meanwhile_is_not_replaced(tmp_path):
    """Two runs with the same new output: the one finishing second is refused, the first's result kept."""
    out = tmp_path / "same.toml"
    with claim(out, folder=False):
        out.write_text("the other run's result\n")           # another run finished first
        with pytest.raises(RcmKinError, match="written by another run"):
            write_text(out, "this run's result\n")
    assert out.read_text() == "the other run's result\n"
    assert [p.name for p in tmp_path.iterdir()] == ["same.toml"]        # no temporary left
    with claim(out, folder=False, force=True):
        write_text(out, "forced\n")
    assert out.read_text() == "forced\n"


def test_a_claim_clears_its_own_unfinished_writes_and_nobody_elses(tmp_path):
    """A worker stopped outright leaves its temporary (reserved, never committed): the claim removes
    it at its end, and leaves alone a temporary of anyone else (another run's, in a subfolder)."""
    import rcm_kin.atomic as atomic

    folder = tmp_path / "report"
    (folder / "sub").mkdir(parents=True)
    foreign = folder / "sub" / f".figure.0a1b2c3d{PARTIAL}.png"
    foreign.write_bytes(b"another run's, still being written")
    with claim(folder, folder=True):
        stopped = atomic._reserve(folder / "sub" / "figure.png")      # a worker killed before its rename
        assert stopped.exists()
    assert not stopped.exists() and foreign.exists()


def test_a_link_out_of_a_claimed_folder_is_refused_at_any_depth(tmp_path):
    """A subfolder that is a link out of the claimed folder: no write goes through it."""
    folder, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "precious.txt").write_text("the user's")
    folder.mkdir()
    (folder / "figs").symlink_to(elsewhere)
    with claim(folder, folder=True), pytest.raises(RcmKinError, match="leads out of the output folder"):
        write_text(folder / "figs" / "precious.txt", "overwritten")
    assert (elsewhere / "precious.txt").read_text() == "the user's"
    assert not any(PARTIAL in p.name for p in elsewhere.iterdir())


def test_a_file_changed_by_someone_else_during_a_run_stays_theirs(tmp_path):
    """The manifest takes what the run committed (its forked workers' too, by the journal), not
    every file that changed meanwhile: a user's edit during the run is refused by the next run."""
    folder = tmp_path / "out"
    with claim(folder, folder=True):
        write_text(folder / "map.csv", "ours\n")
        (folder / "notes.txt").write_text("the user's, written while the run worked")
        if os.fork() == 0:                          # a forked worker commits a file of the run
            try:
                write_text(folder / "worker.csv", "a worker's\n")
            finally:
                os._exit(0)
        os.wait()
    assert set(json.loads((folder / MANIFEST).read_text())["files"]) == {"map.csv", "worker.csv"}
    with claim(folder, folder=True), pytest.raises(RcmKinError, match="did not write it"):
        write_text(folder / "notes.txt", "replaced")
    assert (folder / "notes.txt").read_text() == "the user's, written while the run worked"


def test_no_write_lands_after_stop_writes(tmp_path, monkeypatch):
    monkeypatch.setattr("rcm_kin.atomic._STOPPED", [])
    stop_writes("the run was terminated (SIGTERM)")
    with pytest.raises(RcmKinError, match="not written: the run was terminated"):
        write_text(tmp_path / "late.csv", "x\n")
    assert list(tmp_path.iterdir()) == []

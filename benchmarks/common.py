"""Timing helpers for the benchmark scripts: best-of-repeats wall-clock time per call."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# the timed processes' bytecode, kept between runs (Python checks each file against its source):
# with PYTHONPYCACHEPREFIX set, Python reads bytecode only there, so a new folder would compile
# every module, Pinocchio's and matplotlib's too, in the first run
PYCACHE = str(Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rcm-kin" / "benchmark-bytecode")


def child_env(src: str, **extra: str) -> dict[str, str]:
    """The environment of a timed fresh process: ``src`` first on the path, one BLAS thread, and
    bytecode kept (under :data:`PYCACHE`) as an installed copy has it: ``pip install .``
    compiles it, while an editable checkout under ``PYTHONDONTWRITEBYTECODE`` compiles every imported
    module on every start (about 0.1 s of rcm-kin's)."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
    return {**env, "PYTHONPATH": src, "OPENBLAS_NUM_THREADS": "1", "PYTHONPYCACHEPREFIX": PYCACHE, **extra}


def fresh_run(args: list[str], src: str, cwd: str | None = None) -> tuple[float, float, bytes]:
    """Wall and CPU seconds (user + system, its child processes included) of ``python args`` in a
    new process (:func:`child_env`, in ``cwd``), and its standard output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *args], env=child_env(src), cwd=cwd, check=True, stdout=subprocess.PIPE,
                          stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime, done.stdout

def per_call(fn, calls: int, repeats: int = 5) -> float:
    """Best of ``repeats`` mean times of ``calls`` calls of ``fn()`` (seconds per call)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - start) / calls)
    return best


def best_of(fn, repeats: int = 3) -> float:
    """Best wall-clock seconds of one ``fn()`` call over ``repeats``."""
    return per_call(fn, 1, repeats)


def report(rows: list[tuple[str, float]]) -> None:
    width = max(len(name) for name, _ in rows)
    for name, seconds in rows:
        print(f"{name:{width}}  {seconds * 1e6:10.1f} us/call")

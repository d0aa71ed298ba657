"""Timing helpers for the benchmark scripts: best-of-repeats wall-clock time per call."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

PYCACHE = tempfile.mkdtemp(prefix="rcm-kin-bench-pyc-")   # this run's bytecode, removed at its end
atexit.register(shutil.rmtree, PYCACHE, True)


def child_env(src: str, **extra: str) -> dict[str, str]:
    """The environment of a timed fresh process: ``src`` first on the path, one BLAS thread, and
    bytecode kept (under :data:`PYCACHE`) as an installed copy has it: ``pip install .``
    compiles it, while an editable checkout under ``PYTHONDONTWRITEBYTECODE`` compiles every imported
    module on every start (about 0.1 s of rcm-kin's)."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
    return {**env, "PYTHONPATH": src, "OPENBLAS_NUM_THREADS": "1", "PYTHONPYCACHEPREFIX": PYCACHE, **extra}


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

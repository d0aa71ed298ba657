"""Timing helpers for the benchmark scripts: best-of-repeats wall-clock time per call."""

from __future__ import annotations

import os
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


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

"""The fit on every log with its leave-one-log-out cross-validation, on a pool of processes.

One fit on all ``n`` logs; with cross-validation ``n`` folds, each searched from scratch on all
logs but one (nothing fitted on the left-out log seeds it); with ``inner`` also, per fold ``k``,
the fits on all but ``k`` and ``j`` for each ``j != k``, polished by least squares from fold
``k``'s estimate (nothing from log ``k`` enters them either: the parameter sets a band for log
``k`` may use). Every fit is an independent task with its own seed, so the results do not depend
on how many processes run them (``workers``). Beside them: the ranges over which the parameters
the logs do not determine keep the fit as good (:func:`undetermined_ranges`).
"""

from __future__ import annotations

import os
from concurrent.futures import FIRST_COMPLETED, Future, wait
from dataclasses import dataclass, replace

import numpy as np

from rcm_kin.dynamics.stick_slip import AxisFriction, AxisPlant
from rcm_kin.identification.drive_train import (
    BOUNDS,
    AxisLog,
    LogCheck,
    Search,
    bound_violation,
    check_log,
    fit_friction,
    polish,
    predict_log,
    residuals,
)
from rcm_kin.parallel import process_pool

INNER_POLISH = 10      # least-squares evaluations of an inner fold's polish (it starts next to its optimum)
RANGE_POINTS = 12      # grid points of an undetermined parameter's scan
RANGE_WITHIN = 0.02    # relative rise of the total cost that bounds an undetermined parameter's range


@dataclass(frozen=True)
class CrossValidated:
    """The fit on every log and, with cross-validation, per left-out log its check, its fold's
    parameters and the inner folds' (fitted on all but that log and one other, in log order)."""

    friction: AxisFriction
    standard_errors: np.ndarray
    checks: tuple[LogCheck, ...] = ()
    folds: tuple[AxisFriction, ...] = ()
    inner: tuple[tuple[AxisFriction, ...], ...] = ()


def default_workers() -> int:
    """Processes for the folds: two where the machine has them."""
    return max(1, min(2, os.cpu_count() or 1))


def task_count(logs: int, cv: bool, inner: bool) -> int:
    """Fits :func:`fit_with_cv` runs on ``logs`` logs (each one progress step)."""
    return 1 + (logs + (logs * (logs - 1) if inner else 0) if cv else 0)


def _fit_task(search, plants, logs, seed, generations, bounds):
    return fit_friction(search, plants, logs, seed=seed, generations=generations, speed_bounds=bounds)


def _inner_task(search, plants, logs, start: AxisFriction, bounds) -> AxisFriction:
    """``start`` polished by least squares on ``logs`` (the bounds kept)."""
    residual = lambda x: residuals(search.friction(x), plants, logs)  # noqa: E731
    x0 = search.start(start)
    violation = bound_violation(search, bounds) if bounds else None
    return search.friction(polish(search, residual, x0, float(np.sum(residual(x0) ** 2)), violation, INNER_POLISH))


class _Serial:
    """The executor's interface run in this process, task by task (one worker)."""

    def submit(self, fn, *args) -> Future:
        future = Future()
        future.set_result(fn(*args))
        return future

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        return None


def fit_with_cv(search: Search, plants: list[AxisPlant], logs: list[AxisLog], seed: int = 0,
                generations: tuple[int, int] = (100, 100), speed_bounds=(), cv: bool = False, inner: bool = False,
                workers: int | None = None, progress=None) -> CrossValidated:
    """The fit on every log (``generations[0]`` of evolution) and, with ``cv``, the leave-one-out
    folds (``generations[1]`` each) and with ``inner`` their inner folds, on ``workers`` processes
    (default :func:`default_workers`); ``progress()`` once per finished fit."""
    n, workers = len(logs), workers or default_workers()
    tick = progress or (lambda: None)
    subset = lambda drop: ([plants[i] for i in range(n) if i not in drop],  # noqa: E731
                           [logs[i] for i in range(n) if i not in drop])
    with (process_pool(workers, fork=False) if workers > 1 else _Serial()) as pool:
        pending = {pool.submit(_fit_task, search, plants, logs, seed, generations[0], speed_bounds): ("all", None)}
        if cv:
            pending.update({pool.submit(_fit_task, search, *subset({k}), seed, generations[1], speed_bounds):
                            ("fold", k) for k in range(n)})
        done, folds, inners = {}, {}, {}
        while pending:
            finished, _ = wait(list(pending), return_when=FIRST_COMPLETED)
            for future in finished:
                kind, key = pending.pop(future)
                done[(kind, key)] = future.result()
                tick()
                if kind == "fold" and inner:
                    folds[key] = done[(kind, key)][0]
                    pending.update({pool.submit(_inner_task, search, *subset({key, j}), folds[key], speed_bounds):
                                    ("inner", (key, j)) for j in range(n) if j != key})
    friction, sigma = done[("all", None)]
    if not cv:
        return CrossValidated(friction, sigma)
    fold_sets = tuple(done[("fold", k)][0] for k in range(n))
    checks = tuple(check_log(log.name, log.measured, predict_log(f, p, log), log.period)
                   for f, p, log in zip(fold_sets, plants, logs))
    inners = tuple(tuple(done[("inner", (k, j))] for j in range(n) if j != k) for k in range(n)) if inner else ()
    return CrossValidated(friction, sigma, checks, fold_sets, inners)


def undetermined_ranges(friction: AxisFriction, plants: list[AxisPlant], logs: list[AxisLog], names,
                        points: int = RANGE_POINTS, within: float = RANGE_WITHIN) -> dict[str, tuple[float, float]]:
    """Per parameter of ``names``: scanned over its bounds (:data:`BOUNDS`; a
    log grid of ``points`` where it is searched on a log scale, else even) with the others held at
    ``friction``, the interval around the estimate (SI) over which the total cost (the sum of
    squares of :func:`residuals`) stays within ``within`` of the best seen."""
    out = {}
    for name in names:
        lo, hi = BOUNDS[name][:2]
        grid = np.geomspace(lo, hi, points) if len(BOUNDS[name]) == 3 else np.linspace(lo, hi, points)
        value = getattr(friction, name)
        grid = np.unique(np.r_[grid, value])
        cost = np.array([np.sum(residuals(replace(friction, **{name: float(v)}), plants, logs) ** 2) for v in grid])
        good = cost <= (1.0 + within) * cost.min()
        k = int(np.flatnonzero(grid == value)[0])
        a, b = k, k
        while a > 0 and good[a - 1]:
            a -= 1
        while b < grid.size - 1 and good[b + 1]:
            b += 1
        out[name] = (float(grid[a]), float(grid[b]))
    return out

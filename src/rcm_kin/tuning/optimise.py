"""The search: SciPy's differential evolution over a :class:`~rcm_kin.tuning.design.DesignSpace`,
each candidate simulated on every draw (:mod:`rcm_kin.tuning.objective`), seeded, with a progress
bar and a time budget.

:func:`tune` returns the best design found within ``budget_s`` (the search stops at the first
generation that ends past it, or when the population has converged); the thesis law on the same
draws is the baseline of every score. Candidates are judged on a coarse stability grid (the draw
set's ``points``); :func:`~rcm_kin.tuning.study.design_study` checks the winner on the full
41 x 41 grid.
"""

from __future__ import annotations

import multiprocessing
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import differential_evolution
from tqdm import tqdm

from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.errors import RcmKinError
from rcm_kin.parallel import check_workers, quiet_worker
from rcm_kin.simulation.controllers import TUNED, StateFeedbackController, ThesisController
from rcm_kin.tuning.design import DesignSpace, bounds_excess, pose_gains, tuned_schedule
from rcm_kin.tuning.draws import DrawSet
from rcm_kin.tuning.objective import Outcomes, evaluate, score

_SHARED: dict = {}          # what forked workers inherit: the score function (and what it reads)


def tuned_controller(schedule: GainSchedule, name: str = TUNED) -> StateFeedbackController:
    """The firmware law the tuning designs (:mod:`rcm_kin.tuning.design`) with ``schedule``'s tables:
    scheduled at the measured pose, velocity error, gravity and friction feedforward."""
    return StateFeedbackController(schedule, scheduled=True, gravity=True, track_velocity=True, friction=True,
                                   name=name)


def loop_radius(values: dict[str, float], draws: DrawSet) -> float:
    """The largest frozen-gain loop spectral radius of the design ``values`` over every pose of
    every draw's grid."""
    worst = 0.0
    for d in draws.draws:
        gains = pose_gains(values, d.loops.roll_deg, d.loops.pitch_deg)
        worst = max(worst, float(d.loops.spectral_radius(gains).max()))
    return worst


@dataclass(frozen=True)
class Candidate:
    """One judged design: its values, outcomes on the draws, frozen-loop radius and score."""

    values: dict[str, float]
    outcomes: Outcomes
    radius: float
    score: float


def judge(values: dict[str, float], base: GainSchedule, draws: DrawSet, baseline: Outcomes) -> Candidate:
    """The design ``values`` on ``draws`` against ``baseline`` (the thesis law's outcomes)."""
    radius = loop_radius(values, draws)
    outcomes = evaluate(tuned_controller(tuned_schedule(base, values)), draws)
    return Candidate(values, outcomes, radius, score(outcomes, baseline, radius, bounds_excess(values)))


@dataclass(frozen=True)
class Minimum:
    """What :func:`minimise` found: the best point of the unit box, its value, the generations'
    best values, the evaluations, wall time (s) and why the search stopped."""

    x: np.ndarray
    fun: float
    history: tuple[float, ...]
    evaluations: int
    wall_s: float
    stopped: str                  # "converged", "generations" or "time budget"


def minimise(score, dimensions: int, seed: int = 0, budget_s: float = 240.0, popsize: int = 5,
             start: tuple[np.ndarray, ...] = (), workers: int = 1, label: str = "tune",
             progress: bool = False, tol: float = 1e-3, generations: int | None = None) -> Minimum:
    """Minimise ``score(x) -> float`` over the unit box ``[0, 1]^dimensions``: SciPy's differential
    evolution (``popsize x dimensions`` members, a Latin hypercube whose first members are the
    points ``start``, seed ``seed``, no gradient polish), stopped at the first generation that ends
    past ``budget_s`` seconds, after ``generations`` generations when given (a stop that does not
    depend on the machine's speed: the same seed then gives the same result anywhere), or on
    convergence (relative spread ``tol``); ``workers`` > 1 scores each
    generation on that many forked processes (``score`` and what it reads inherited, not pickled).
    A progress bar (``label``) when ``progress``."""
    if not (np.isfinite(budget_s) and budget_s > 0):
        raise RcmKinError(f"the time budget is a positive number of seconds, got {budget_s}", parameter="budget_s")
    check_workers(workers)
    if generations is not None and not 1 <= generations <= 100_000:
        raise RcmKinError(f"generations is 1 to 100000, got {generations}", parameter="generations")
    if not 2 <= popsize <= 100 or popsize * dimensions < 5:
        raise RcmKinError(f"popsize is 2 to 100 members per dimension, and at least 5 members in all (SciPy's "
                          f"least), got {popsize} x {dimensions}", parameter="popsize")
    rng = np.random.default_rng(seed)
    members = popsize * dimensions
    init = rng.random((members, dimensions))
    for j in range(dimensions):            # Latin hypercube: one member per stratum of each coordinate
        init[:, j] = (rng.permutation(members) + init[:, j]) / members
    for k, point in enumerate(start[:members]):
        init[k] = np.clip(point, 0, 1)
    started, history, stopped = time.perf_counter(), [], ["converged"]
    bar = tqdm(desc=label, unit="gen", disable=not progress, leave=False)

    def callback(intermediate_result):
        history.append(float(intermediate_result.fun))
        bar.update(1)
        bar.set_postfix(best=f"{intermediate_result.fun:.4g}")
        if generations is not None and len(history) >= generations:
            stopped[0] = "generations"
            return True
        if time.perf_counter() - started > budget_s:
            stopped[0] = "time budget"
            return True
        return False

    _SHARED["score"] = score
    pool = multiprocessing.get_context("fork").Pool(workers, initializer=quiet_worker) if workers > 1 else None
    mapper = (lambda function, points: pool.map(_shared_score, list(points))) if pool else map
    try:
        result = differential_evolution(_shared_score, [(0.0, 1.0)] * dimensions, init=init, seed=seed,
                                        maxiter=100_000, tol=tol, polish=False, callback=callback,
                                        updating="deferred", workers=mapper)
    finally:
        bar.close()
        if pool:
            pool.terminate()
        _SHARED.clear()
    return Minimum(np.asarray(result.x), float(result.fun), tuple(history), int(result.nfev),
                   time.perf_counter() - started, stopped[0])


def _shared_score(x: np.ndarray) -> float:
    return float(_SHARED["score"](x))


@dataclass(frozen=True)
class Search:
    """What :func:`tune` found: the best candidate, the space, the baseline's outcomes (the thesis
    law on the same draws), the search (:class:`Minimum`) and closed-loop runs per second of CPU."""

    best: Candidate
    space: DesignSpace
    baseline: Outcomes
    minimum: Minimum
    runs_per_s: float


def tune(base: GainSchedule, draws: DrawSet, space: DesignSpace, seed: int = 0, budget_s: float = 240.0,
         popsize: int = 5, start: tuple[dict[str, float], ...] = (), workers: int = 1,
         progress: bool = False, generations: int | None = None, held: dict[str, float] | None = None) -> Search:
    """The design of ``space`` that minimises :func:`~rcm_kin.tuning.objective.score` on ``draws``
    against the thesis law (:func:`minimise`; ``start``: designs in the first generation; ``held``:
    the values of a design's parameters ``space`` does not search, kept as they are)."""
    baseline = evaluate(ThesisController(), draws)
    clock = time.process_time()
    held = dict(held or {})

    def score(unit: np.ndarray) -> float:
        return judge({**held, **space.values(unit)}, base, draws, baseline).score

    minimum = minimise(score, len(space.parameters), seed, budget_s, popsize, tuple(space.unit(d) for d in start),
                       workers, f"tune {space.kind}", progress, generations=generations)
    cpu = time.process_time() - clock
    best = judge({**held, **space.values(minimum.x)}, base, draws, baseline)
    runs = minimum.evaluations * len(draws) * len(draws.references)
    rate = runs / (minimum.wall_s * workers) if workers > 1 else runs / max(cpu, 1e-9)
    return Search(best, space, baseline, minimum, rate)

"""Identification of the drive-train model (:mod:`rcm_kin.dynamics.stick_slip`) from logs.

Each open-loop step log of one axis is simulated from rest at its measured angle under its
recorded PWM (held per sample, as the driver holds it), the other axes held where the log
measured them. A closed-loop log is simulated with the controller it ran in the loop, read
back from the log (:mod:`rcm_kin.identification.recorded_law`), under its own excitation. The
residual of a log is the simulated minus the measured angle divided by the
measured travel's spread, so the sum of squares is ``sum_logs (1 - fit_percent / 100)^2``: every
log counts as much as any other, however far it moved.

The friction makes the output a non-smooth function of the parameters (a stop moves by a
whole step when a parameter crosses a threshold), so a gradient method alone ends in the first
local minimum: a differential-evolution search over the bounded (log-scaled where the range
spans decades) parameters comes first, then ``least_squares`` polishes; standard errors come
from a finite-difference Jacobian at the result (local, optimistic) and, with cross-validation,
from the spread over the leave-one-out folds.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np
from scipy.optimize import NonlinearConstraint, differential_evolution, least_squares

from rcm_kin.dynamics.axis_friction import DISCRETE
from rcm_kin.dynamics.stick_slip import (
    NAMES,
    TERM_PARAMETERS,
    TERMS,
    AxisFriction,
    AxisPlant,
    rest_angle,
    rest_state,
    simulate_axis,
    simulate_axis_closed,
)
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import ENCODER_COUNT, HOME_INSERTION, PITCH_REST_DEG, PWM_LIMIT
from rcm_kin.identification.log_checks import LogCheck, check_log, fit_percent, stick_time  # noqa: F401 (re-exported)
from rcm_kin.identification.recorded_law import RecordedLaw, recover_law
from rcm_kin.identification.records import resample, tick_period
from rcm_kin.identification.telemetry import TelemetryLog, load_telemetry, step_index

PERIOD = 1e-3          # s: the logs are resampled to this grid (PWM held, angle interpolated)
AFTER_STEP = 2.5       # s of each log used after the step
# Bounds of the identified parameters (SI); "log" ones are searched on a log scale.
BOUNDS = {
    "extra_inertia": (0.0, 3.0), "viscous": (0.0, 30.0), "coulomb": (0.0, 3.0), "static": (0.0, 3.0),
    "stribeck_velocity": (1e-3, 1.0, "log"), "presliding_stiffness": (1.0, 1e3, "log"),
    "presliding_slope": (-8.0, 8.0), "presliding_force": (0.05, 5.0, "log"),
    "cable_stiffness": (5.0, 1e4, "log"), "cable_damping": (0.0, 30.0), "motor_coulomb": (0.0, 1.0),
    "motor_viscous": (0.0, 10.0),
}
DEFAULT_TERMS = ("viscous", "presliding")
PENALTY = 100.0        # weight of a bound's relative excess beside the residuals (each log's about 1)


@dataclass(frozen=True)
class AxisLog:
    """One log of one axis on a uniform grid: a step from the sample before the step, or a
    closed-loop record from a rest with the law that ran and its excitation."""

    name: str
    joint: str
    period: float            # s
    pwm: np.ndarray          # (n,) counts, held over each period
    measured: np.ndarray     # (n,) rad, the logged angle
    pose: np.ndarray         # (3,) driven joints (rad, rad, m) where the record starts
    law: RecordedLaw | None = None          # closed loop: the controller in the loop
    excitation: np.ndarray | None = None    # (n,) counts added to the law's PWM (closed loop)

    @cached_property
    def spread(self) -> float:
        """The norm of the measured angle about its mean (rad): what :func:`residuals` divides by."""
        return np.linalg.norm(self.measured - self.measured.mean())

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.pwm.size) * self.period

    @property
    def operating_point(self) -> tuple[float, float]:
        """(roll, pitch) in degrees where the step started."""
        return float(np.degrees(self.pose[0])), float(np.degrees(self.pose[1]))


def whole_log(source: str | Path | TelemetryLog, joint: str, period: float | None = PERIOD) -> AxisLog:
    """All of ``joint``'s record in the log at ``source`` (a path, or the log already read) on a
    ``period`` s grid (the PWM held, the angle interpolated), or with ``period`` None the logged
    samples themselves as controller ticks at their mean interval (a closed-loop log: the firmware
    acted once per logged sample; its time stamps are whole milliseconds, so intervals read 2 or
    3 ms around a 2.4 ms loop). From its first sample (taken at rest); the other axis held at its
    mean logged angle (when not logged: the roll at 0, the pitch resting on its lower stop,
    :data:`~rcm_kin.hardware.PITCH_REST_DEG`: see :mod:`rcm_kin.identification.log_catalog`)."""
    log = source if isinstance(source, TelemetryLog) else load_telemetry(source)
    if period is None:
        log.require(joint)
        u, y, period = log.pwm[joint], log.position[joint], tick_period(log)
    else:
        u, y, period = resample(log, joint, period)
    pose = np.array([0.0, np.radians(PITCH_REST_DEG), HOME_INSERTION])
    for k, other in enumerate(("roll", "pitch")):
        if other in log.position and other != joint:
            pose[k] = np.radians(np.mean(log.position[other]))
    pose[("roll", "pitch").index(joint)] = np.radians(y[0])
    return AxisLog(log.path.name, joint, period, u, np.radians(y), pose)


def _span(record: AxisLog, k0: int, k1: int, name: str) -> AxisLog:
    """Samples ``k0:k1`` of ``record``, its pose taken at ``k0``."""
    pose = record.pose.copy()
    pose[("roll", "pitch").index(record.joint)] = record.measured[k0]
    excitation = None if record.excitation is None else record.excitation[k0:k1]
    return AxisLog(name, record.joint, record.period, record.pwm[k0:k1], record.measured[k0:k1], pose,
                   record.law, excitation)


def axis_log(path: str | Path, joint: str, after: float = AFTER_STEP) -> AxisLog:
    """The step of ``joint`` in the telemetry log at ``path``: from the sample before the step
    (the first PWM change above 0.1 count, the thesis's trimming) for ``after`` s."""
    record = whole_log(path, joint)
    start = step_index(record.pwm) - 1
    stop = min(record.pwm.size, start + int(round(after / record.period)) + 1)
    if stop - start < 50:
        raise RcmKinError(f"{record.name}: only {stop - start} samples after the {joint} step")
    return _span(record, start, stop, record.name)


def closed_loop_log(path: str | Path, joint: str, start: float = 0.0, duration: float | None = None,
                    min_rest: float = 0.05) -> AxisLog:
    """``duration`` s of a closed-loop log of ``joint``, its samples as the controller's ticks
    (:func:`whole_log` with no resampling), from its first rest (the angle unchanged for at least
    ``min_rest`` s) after ``start`` s, with the law that ran (:func:`recover_law`, on the same ticks)
    and its excitation. A log whose law is not recovered is a clear error."""
    log = load_telemetry(path)
    law = recover_law(log, joint, float(PWM_LIMIT[("roll", "pitch").index(joint)]))
    name = Path(path).name
    if law.problem():
        raise RcmKinError(f"{name}: cannot simulate the {joint} in its loop: {law.problem()}; only logs run under "
                          "a linear law plus a binary excitation (the PRBS experiments) can be")
    record = whole_log(log, joint, period=None)
    record = replace(record, law=law, excitation=law.excitation(record.measured, record.pwm, record.period))
    still = np.r_[False, np.diff(record.measured) == 0.0]
    run = np.zeros(still.size, dtype=int)
    for k in range(1, still.size):
        run[k] = run[k - 1] + 1 if still[k] else 0
    resting = run >= int(round(min_rest / record.period))
    first = np.flatnonzero(resting & (record.time >= start))
    if first.size == 0:
        raise RcmKinError(f"{name}: the {joint} never rests for {min_rest} s after {start} s; the simulation in the "
                          "loop starts from a rest: give a log in which the joint holds still for a moment")
    k0 = int(first[0])
    k1 = record.pwm.size if duration is None else min(record.pwm.size, k0 + int(round(duration / record.period)))
    return _span(record, k0, k1, f"{name}@{record.time[k0]:.1f}s")


def predict_log(friction: AxisFriction, plant: AxisPlant, log: AxisLog, preload: float = 0.0) -> np.ndarray:
    """Predicted measured angle (rad) over ``log``: from rest at its first angle under its first
    PWM, then under its recorded PWM (a step) or under its recorded law and excitation (closed
    loop, :func:`simulate_axis_closed`). The rest is taken as the static equilibrium the log shows:
    the rigid-body gravity is shifted by the constant that makes the first PWM hold the link there
    (:func:`at_rest`), so the model's holding error (the calibration's, 1-2 PWM on roll) does not
    load the presliding spring or the friction before the step (what the thesis's trimming
    assumes too). Sample convention: ``measured[k]`` is the angle at ``t_k``, and ``pwm[k]`` is
    held from ``t_k``; the prediction at ``t_k`` is the state after ``pwm[0..k-1]``. A closed-loop
    record starts at a rest under friction, where the PWM need not balance gravity: there the
    shift makes the record's mean PWM hold its mean angle (the loop hovers about its holding
    point; data README: "the mean PWM is close to the pitch holding effort"). ``preload`` in [-1, 1]:
    the presliding state the approach to the first rest left (:func:`rest_state`; 0: relaxed)."""
    if log.law is not None:
        plant, _ = at_rest(friction, plant, float(np.mean(log.measured)), float(np.mean(log.pwm)))
        state = rest_state(friction, plant, log.measured[0], log.pwm[0], preload)
        count = np.radians(ENCODER_COUNT[("roll", "pitch").index(log.joint)])
        return simulate_axis_closed(friction, plant, log.law.vector(), log.excitation, log.period, state, count)[0]
    plant, state = at_rest(friction, plant, log.measured[0], log.pwm[0], preload=preload)
    out = simulate_axis(friction, plant, log.pwm[:-1], log.period, state)
    return np.concatenate(([log.measured[0]], out))


def at_rest(friction: AxisFriction, plant: AxisPlant, angle: float, pwm: float,
            preload: float = 0.0) -> tuple[AxisPlant, np.ndarray]:
    """``plant`` with its gravity shifted so that ``pwm`` holds the axis at rest with the measured
    (motor-side) angle ``angle`` (rad), and that rest state (:func:`rest_state`: the link behind
    the cable's stretch, the presliding spring relaxed). With ``preload`` in [-1, 1] the spring
    carries ``preload`` F_p of the holding torque, the state a previous approach left, and the
    gravity is shifted by that much less: the rest stays a static equilibrium (the spring's force
    and the shifted gravity balance the motor torque), so the preload is also a statement about the
    gravity at the rest (which the holding calibration bounds only to its band; not enforced here)."""
    if not -1.0 <= preload <= 1.0:
        raise RcmKinError(f"the presliding preload is a fraction of the slip force in [-1, 1], got {preload!r}",
                          parameter="preload")
    unbalanced = plant.input_gain * pwm - np.interp(rest_angle(friction, plant, angle, pwm), plant.grid, plant.gravity)
    carried = preload * friction.presliding_force if friction.presliding_stiffness > 0 else 0.0
    plant = replace(plant, gravity=plant.gravity + (unbalanced - carried))
    return plant, rest_state(friction, plant, angle, pwm)


def _logged(name: str) -> bool:
    """Whether the parameter ``name`` is searched on a log scale."""
    return len(BOUNDS[name]) == 3


@dataclass(frozen=True)
class Search:
    """Which parameters are free, and how they map to the search space."""

    base: AxisFriction
    free: tuple[str, ...]

    def bounds(self) -> list[tuple[float, float]]:
        return [tuple(np.log(BOUNDS[n][:2])) if _logged(n) else BOUNDS[n] for n in self.free]

    def friction(self, x) -> AxisFriction:
        values = {n: (float(np.exp(v)) if _logged(n) else float(v)) for n, v in zip(self.free, x)}
        return replace(self.base, **values)

    def start(self, friction: AxisFriction) -> np.ndarray:
        """``friction``'s free parameters in the search coordinates (inside the bounds)."""
        lo, hi = np.array(self.bounds()).T
        x = [np.log(max(getattr(friction, n), BOUNDS[n][0])) if _logged(n) else getattr(friction, n)
             for n in self.free]
        return np.clip(np.array(x, dtype=float), lo, hi)


def search_for(terms, elements: float = 1.0) -> Search:
    """The free parameters of a model with ``terms`` on (see :data:`TERMS`) and a presliding spring
    of ``elements`` Maxwell-slip elements (a model choice, never searched: :data:`DISCRETE`)."""
    unknown = set(terms) - set(TERMS)
    if unknown:
        raise RcmKinError(f"unknown model term(s) {', '.join(sorted(unknown))}; the terms are {', '.join(TERMS)}")
    off = {n for t in TERMS if t not in terms for n in TERM_PARAMETERS[t]}
    free = tuple(n for n in NAMES if n not in off and n not in DISCRETE)
    return Search(AxisFriction(presliding_elements=elements), free)


def residuals(friction: AxisFriction, plants: list[AxisPlant], logs: list[AxisLog]) -> np.ndarray:
    """Per log, (predicted - measured) / spread of the measured angle, stacked."""
    out = []
    for plant, log in zip(plants, logs):
        predicted = predict_log(friction, plant, log)
        out.append((predicted - log.measured) / log.spread)
    return np.concatenate(out)


def fit_friction(search: Search, plants: list[AxisPlant], logs: list[AxisLog], seed: int = 0,
                 generations: int = 100, progress=None, speed_bounds=()) -> tuple[AxisFriction, np.ndarray]:
    """Shared parameters over ``logs``: evolution then least squares, subject to ``speed_bounds``
    (:class:`~rcm_kin.identification.speed_bounds.SpeedBound`: the friction at each bound's speed
    at most its limit). Returns the estimate and the standard errors of the free parameters (in
    their own units, NaN where unidentifiable)."""
    if not logs:
        raise RcmKinError("identification needs at least one step log")
    objective = lambda x: float(np.sum(residuals(search.friction(x), plants, logs) ** 2))  # noqa: E731
    violation = bound_violation(search, speed_bounds)
    constraints = NonlinearConstraint(violation, -np.inf, 0.0) if speed_bounds else ()
    evolved = differential_evolution(objective, search.bounds(), seed=seed, maxiter=generations, popsize=8,
                                     tol=1e-6, polish=False, constraints=constraints,
                                     callback=_generation_callback(progress) if progress else None)
    residual = lambda x: residuals(search.friction(x), plants, logs)  # noqa: E731
    best = polish(search, residual, evolved.x, evolved.fun, violation)
    return search.friction(best), _standard_errors(search, residual, best)


def polish(search: Search, residual, x0: np.ndarray, cost0: float, violation=None, max_nfev: int = 60) -> np.ndarray:
    """``least_squares`` on ``residual`` from ``x0`` (sum of squares ``cost0``), kept only if better.
    With ``violation`` (relative excess over each bound, <= 0 where satisfied) the bounds enter as
    a penalty residual, and the polished point is pulled back along the segment from ``x0``
    (feasible) to the last feasible point, so the result satisfies every bound: a polish that
    ends on a bound's far side lands on the bound."""
    lo, hi = np.array(search.bounds()).T
    if violation is None or np.size(violation(x0)) == 0:
        polished = least_squares(residual, x0, bounds=(lo, hi), diff_step=1e-4, max_nfev=max_nfev)
        return polished.x if polished.cost * 2 <= cost0 else x0
    penalised = lambda x: np.r_[residual(x), PENALTY * np.maximum(violation(x), 0.0)]  # noqa: E731
    x = least_squares(penalised, x0, bounds=(lo, hi), diff_step=1e-4, max_nfev=max_nfev).x
    if np.max(violation(x)) > 0.0 and np.max(violation(x0)) <= 0.0:
        inside, outside = 0.0, 1.0
        for _ in range(40):               # bisection on the segment: feasible at ``inside``
            middle = 0.5 * (inside + outside)
            inside, outside = (middle, outside) if np.max(violation(x0 + middle * (x - x0))) <= 0 else (inside, middle)
        x = x0 + inside * (x - x0)
    excess, excess0 = np.max(violation(x)), np.max(violation(x0))
    if (excess <= 0.0) != (excess0 <= 0.0):          # the feasible one, else the better one
        return x if excess <= 0.0 else x0
    if excess > 0.0:
        return x if excess < excess0 else x0
    return x if float(np.sum(residual(x) ** 2)) <= cost0 else x0


def bound_violation(search: Search, speed_bounds):
    """Per bound, ``value / limit - 1`` of the parameters ``x`` (search coordinates): <= 0 satisfied."""
    for b in speed_bounds:
        if b.max_force <= 0.0:
            raise RcmKinError(f"the {b.name} bound leaves no room for friction ({b.max_force:.3g} N m at "
                              f"{b.speed:.3g} rad/s: {b.source})")
    return lambda x: np.array([b.value(search.friction(x)) / b.max_force - 1.0 for b in speed_bounds])


def _generation_callback(progress):
    """``differential_evolution``'s callback calling ``progress()`` once per generation. It returns
    None whatever ``progress`` returns: scipy halts the search on a true return, and a progress
    bar's ``update()`` returns True whenever it redraws."""
    def callback(*args, **kwargs) -> None:
        progress()
    return callback


def _jacobian(search: Search, function, x: np.ndarray, step: float = 1e-2) -> np.ndarray:
    """Derivative of ``function`` in the search coordinates by differences of ``step`` (1 % for
    the log-scaled parameters): wide enough to see through the friction's small
    discontinuities; central inside the bounds, one-sided at them (never outside the box)."""
    lo, hi = np.array(search.bounds()).T
    J = []
    for k in range(x.size):
        up, down = x.copy(), x.copy()
        up[k], down[k] = min(x[k] + step, hi[k]), max(x[k] - step, lo[k])
        J.append((function(up) - function(down)) / (up[k] - down[k]))
    return np.column_stack(J)


def _sigma(search: Search, x: np.ndarray, information: np.ndarray, variance: float) -> np.ndarray:
    """``sqrt(diag(variance (J^T J)^-1))`` mapped to the parameters' units (log-scaled ones through
    ``d p = p d log p``); NaN for a parameter the data do not move."""
    sigma = np.full(x.size, np.nan)
    seen = np.diag(information) > 0
    if seen.any():
        cov = np.linalg.pinv(information[np.ix_(seen, seen)]) * variance
        sigma[seen] = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return sigma * np.array([np.exp(v) if _logged(n) else 1.0 for n, v in zip(search.free, x)])


def _standard_errors(search: Search, residual, x) -> np.ndarray:
    """Gauss-Newton standard errors with the residual variance estimated from the fit. Local and
    optimistic: the samples of a log are far from independent, and the model's own error, not
    noise, dominates the residual (the leave-one-out spread is the honest figure)."""
    r = residual(x)
    J = _jacobian(search, residual, x)
    return _sigma(search, x, J.T @ J, (r @ r) / max(r.size - x.size, 1))


def leave_one_out(search: Search, plants: list[AxisPlant], logs: list[AxisLog], seed: int = 0,
                  generations: int = 100, progress=None, speed_bounds=()) -> tuple[list[LogCheck], list[AxisFriction]]:
    """Each log predicted by the model fitted on all the others, each fold searched from scratch
    (nothing fitted on the left-out log seeds it); the checks, and the parameters of each fold.
    ``progress()``: once per generation."""
    checks, folds = [], []
    for k, log in enumerate(logs):
        rest = [i for i in range(len(logs)) if i != k]
        friction, _ = fit_friction(search, [plants[i] for i in rest], [logs[i] for i in rest], seed=seed,
                                   generations=generations, progress=progress, speed_bounds=speed_bounds)
        checks.append(check_log(log.name, log.measured, predict_log(friction, plants[k], log), log.period))
        folds.append(friction)
    return checks, folds


def jackknife_errors(folds: list[AxisFriction], names) -> dict[str, float]:
    """Leave-one-out (jackknife) standard errors of the parameters ``names`` over the folds:
    ``sqrt((n - 1) / n sum (p_i - mean p)^2)``, the spread the choice of logs causes."""
    n = len(folds)
    values = np.array([[getattr(f, name) for name in names] for f in folds])
    spread = np.sqrt((n - 1) / n * np.sum((values - values.mean(axis=0)) ** 2, axis=0))
    return dict(zip(names, map(float, spread)))


def predicted_standard_errors(friction: AxisFriction, plants: list[AxisPlant], logs: list[AxisLog],
                              noise: float) -> dict[str, float]:
    """Gauss-Newton standard errors of the free parameters of ``friction``'s own terms
    (:func:`terms_of`) at ``friction`` if ``logs`` were measured with white noise of ``noise`` rad
    RMS on every angle sample (assumed, not estimated): ``sqrt(diag(noise^2 (J^T J)^-1))``, ``J``
    the Jacobian of the predicted angles. For an experiment not run yet, ``logs`` carry the
    model's own prediction (:mod:`rcm_kin.identification.excitation`)."""
    search = search_for(terms_of(friction), friction.presliding_elements)
    x = search.start(friction)
    angles = lambda x: np.concatenate([predict_log(search.friction(x), p, log)  # noqa: E731
                                       for p, log in zip(plants, logs)])
    J = _jacobian(search, angles, x)
    return dict(zip(search.free, map(float, _sigma(search, x, J.T @ J, noise**2))))


def terms_of(friction: AxisFriction) -> tuple[str, ...]:
    """The terms a parameter set has on: viscous friction, static friction above the sliding level,
    a presliding spring, a compliant cable."""
    on = {"viscous": friction.viscous > 0, "stiction": friction.static > friction.coulomb,
          "presliding": friction.presliding_stiffness > 0, "two_mass": friction.cable_stiffness > 0}
    return tuple(t for t in TERMS if on[t])

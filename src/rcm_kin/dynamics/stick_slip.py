"""One driven axis with friction that really sticks: the drive-train model identified on the logs.

Per driven joint (joint-referred SI: rad, N m, kg m^2), with the encoder on the motor:

    motor:  J_m  w' = k_u u - (k_e + b_m) w - f_m - tau_c                (drive side)
    cable:  tau_c = k_c (theta - q) + d_c (w - v)                         (capstan compliance)
    link:   (M_ii(q) + J_x) v' = tau_c - g_i(q) - b v - f_l - tau_p      (link side)
    presliding spring: tau_p = sum_i k_p(q) / N (q - z_i), |k_p / N (q - z_i)| <= F_i, z_i moves at its bound
    measured angle: theta (motor angle / gear ratio)

- ``k_u``, ``k_e`` (back-EMF damping) and ``J_m`` (reflected rotor inertia) are the drive's. A
  driver dead-band is not in the family: the steps and PRBS logs never cross zero PWM (they
  hold at -5 to -110 counts), and in the one log that starts at zero (the pitch ramp) a
  dead-band cannot be told from the static friction and gravity the ramp must overcome.
- ``f_l``, ``f_m``: set-valued friction. At rest a side stays at rest while the force on it is
  within the static friction ``F_s``; sliding, ``f = sign(v) (F_c + (F_s - F_c) exp(-(v/v_s)^2))``
  (Stribeck) plus viscous ``b v``. The motor side has Coulomb and viscous friction, no stiction.
- ``tau_p``: a Maxwell-slip (Iwan) spring of N elasto-plastic elements in parallel
  (``presliding_elements``): total stiffness ``k_p(q) = k_p0 exp(s q)`` split equally, element i
  (1..N) anchored at ``z_i``, which follows the axis only while the element slips at
  ``F_i = F_p 2 i / (N (N + 1))`` (the ``F_i`` sum to ``F_p``, the whole spring's saturation
  force), so the spring pulls back towards where the last slips ended. N = 1 is one elasto-plastic
  spring; larger N soften it in N steps (the Masing hysteresis loop of :func:`slip_elements`).
  This is what the roll steps show: each behaves like a spring anchored at the angle where it
  started (held there, the spring relaxed, or preloaded by the approach: :func:`rest_state`).
- ``g_i``, ``M_ii``: gravity and inertia of the closed chain along this axis (the rigid-body
  model, tabulated over the axis angle).

Every term can be switched off (:data:`TERMS`); with the cable rigid (``cable_stiffness`` 0,
the default) motor and link are one body and their frictions add.

Integration: time stepping with the friction solved implicitly (Moreau's scheme): each step ``h`` the
velocity update ``(J + h B) v+ = J v + h F - h f`` takes the friction force ``f`` from its set (the
cable's force implicit in both sides' velocities, solved by a few block Gauss-Seidel sweeps, so a stiff
cable tends to the rigid drive), so a side that would cross zero velocity within the step stops exactly,
and a side at rest stays at rest while ``|J v + h F| <= h F_s``. Unlike a smoothed (tanh) law this
really sticks, and unlike Karnopp's model it needs no stick band; unlike LuGre it adds no stiff bristle
state. Its error is first order in ``h`` (a stop is found within one step); the tests check a block
under Coulomb friction against its exact stopping time and position.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numba
import numpy as np

from rcm_kin import firmware_rules
from rcm_kin.dynamics.axis_friction import (
    COUPLING_SWEEPS,
    MAX_ELEMENTS,
    STATE_SIZE,
    AxisFriction,
    substep_count,
)
from rcm_kin.errors import RcmKinError, as_numbers
from rcm_kin.firmware_rules import quantise, saturate
from rcm_kin.hardware import DRIVER_PWM_RANGE

if TYPE_CHECKING:
    from rcm_kin.dynamics.state_space import DrivenDynamics

TERMS = ("viscous", "stiction", "presliding", "two_mass")
NAMES = tuple(f.name for f in fields(AxisFriction))
TERM_PARAMETERS = {   # what switching a term off zeroes
    "viscous": ("viscous",),            # off: sliding friction flat in speed (Coulomb level)
    "stiction": ("static", "stribeck_velocity"),
    "presliding": ("presliding_stiffness", "presliding_slope", "presliding_force"),
    "two_mass": ("cable_stiffness", "cable_damping", "motor_coulomb", "motor_viscous"),
}


@dataclass(frozen=True)
class AxisPlant:
    """What the rigid-body model and the drive give one axis at a held pose of the others."""

    input_gain: float          # k_u: N m per PWM count, hardware sign included
    back_emf: float            # k_t^2 N^2 / R: N m s/rad
    rotor_inertia: float       # N^2 J_rotor: kg m^2
    grid: np.ndarray           # (n,) uniform axis angles, rad
    gravity: np.ndarray        # (n,) g_i over the grid, N m
    inertia: np.ndarray        # (n,) M_ii over the grid (rotor excluded), kg m^2


@numba.njit(cache=True)
def _same(a, b):
    """Whether the floats ``a`` and ``b`` have the same bits (NaN never): equal, zeros of the same sign."""
    return a == b and np.copysign(1.0, a) == np.copysign(1.0, b)


@numba.njit(cache=True)
def _implicit_friction(v, J, h, F, B, static, coulomb, stribeck):
    """v after a step of ``J v' = F - B v - f`` with ``f`` from the friction set (implicit)."""
    p = J * v + h * F
    static = max(static, coulomb)
    if v == 0.0:
        if abs(p) <= h * static:
            return 0.0
        return (p - h * coulomb * np.sign(p)) / (J + h * B)
    # without stiction (static at the Coulomb level, as the motor side always is) the Stribeck term is 0 * exp(...) =
    # +0.0 for every finite speed: added as that constant, the exponential is not computed (the same bits)
    f = coulomb + ((static - coulomb) * np.exp(-(v / stribeck) ** 2) if static != coulomb else 0.0)
    new = (p - h * f * np.sign(v)) / (J + h * B)
    return 0.0 if new * v <= 0.0 else new


@numba.njit(cache=True)
def force_unit(force, n):
    """The slip force (N m) of the first of ``n`` Maxwell-slip elements whose slip forces sum to
    ``force``: element i (1..n) slips at ``i force_unit = force 2 i / (n (n + 1))``."""
    return force * (2.0 / (n * (n + 1)))


@numba.njit(cache=True)
def elements_of(th):
    """The presliding element count of the parameter vector ``th`` (:meth:`AxisFriction.vector`,
    clamped to 1..MAX_ELEMENTS) and their :func:`force_unit`: once per run, so that the substeps
    divide by nothing."""
    n = min(max(int(th[12]), 1), MAX_ELEMENTS)
    return n, force_unit(th[7], n)


@numba.njit(cache=True)
def slip_elements(q, anchors, k_each, unit, n):
    """The slip of a Maxwell-slip spring at the axis angle ``q`` (rad): each of its first ``n``
    ``anchors`` (rad, in place) moved just enough that its element (stiffness ``k_each`` N m/rad)
    carries at most its slip force, element i (0-based) ``(i + 1) unit`` N m (:func:`force_unit`).
    Returns the spring's force ``sum_i k_each (q - z_i)`` (N m) after the slip."""
    total = 0.0
    for i in range(n):
        bound = unit * (i + 1)
        if k_each * (q - anchors[i]) > bound:
            anchors[i] = q - bound / k_each
        elif k_each * (q - anchors[i]) < -bound:
            anchors[i] = q + bound / k_each
        total += k_each * (q - anchors[i])
    return total


@numba.njit(cache=True)
def _substep(state, th, n, unit, pwm, gravity, inertia, ku, kemf, Jm, h):
    """Advance ``state = [theta, w, q, v, z_1 .. z_MAX_ELEMENTS]`` by ``h`` with ``pwm`` held (in place);
    ``n, unit``: :func:`elements_of` ``th``."""
    Jx, b, Fc, Fs, vs, kp0, sp = th[0], th[1], th[2], th[3], th[4], th[5], th[6]
    kc, dc, Fcm, bm = th[8], th[9], th[10], th[11]   # th[7], the slip force, in ``unit``
    q = state[2]
    # kp, the implicit step's stiffness (h kp below), is the total of all the elements, the slipping ones
    # too: the sticking ones are what the implicit term needs (stability of the stiff spring), and a
    # slipping element's force stays at its bound while it slips on, so counting it errs by at most
    # h k_i |v| within the step (first order, the scheme's own), corrected by the slip at the step's end;
    # it needs no guess of the direction of motion and keeps N = 1 today's elasto-plastic step exactly
    kp = kp0 * np.exp(sp * q) if kp0 > 0.0 else 0.0
    k_each = kp / n
    spring = k_each * (q - state[4])
    for i in range(1, n):
        spring += k_each * (q - state[4 + i])
    if kc > 0.0:   # two masses, the cable implicit in both velocities: block Gauss-Seidel sweeps
        stretch, coupling = kc * (state[0] - q), dc + h * kc
        # a sweep's w depends on v alone and its v on w alone: once either repeats (the same bits), every
        # further sweep repeats too, so the sweeps stop there with the values all COUPLING_SWEEPS give
        w, v = state[1], state[3]
        for sweep in range(COUPLING_SWEEPS):
            w_new = _implicit_friction(state[1], Jm, h, ku * pwm - stretch + coupling * v, kemf + bm + coupling,
                                       Fcm, Fcm, 1.0)
            if sweep > 0 and _same(w_new, w):
                break
            w = w_new
            v_new = _implicit_friction(state[3], inertia + Jx, h, stretch + coupling * w - gravity - spring,
                                       b + coupling + h * kp, Fs, Fc, vs)
            if sweep > 0 and _same(v_new, v):
                break
            v = v_new
        state[1], state[3] = w, v
        state[0] += h * w
    else:          # rigid drive: one body, frictions added
        F = ku * pwm - gravity - spring
        state[3] = _implicit_friction(state[3], inertia + Jx + Jm, h, F, b + bm + kemf + h * kp,
                                      Fs + Fcm, Fc + Fcm, vs)
        state[1] = state[3]
    state[2] += h * state[3]
    if kc <= 0.0:
        state[0] = state[2]
    if kp > 0.0:   # the presliding elements slip at their bounds
        slip_elements(state[2], state[4:], k_each, unit, n)


@numba.njit(cache=True)
def _lookup2(x, grid, table1, table2):
    """Linear interpolation of two tables on a uniform grid at ``x``, held at the end values outside it (as
    np.interp)."""
    x = min(max(x, grid[0]), grid[-1])
    step = grid[1] - grid[0]
    i = min(max(int((x - grid[0]) / step), 0), grid.size - 2)
    w = (x - grid[i]) / step
    return table1[i] * (1.0 - w) + table1[i + 1] * w, table2[i] * (1.0 - w) + table2[i + 1] * w


@numba.njit(cache=True)
def _step_period(state, th, n, unit, pwm, grid, gtab, Mtab, ku, kemf, Jm, h, substeps):
    for _ in range(substeps):
        gravity, inertia = _lookup2(state[2], grid, gtab, Mtab)
        _substep(state, th, n, unit, pwm, gravity, inertia, ku, kemf, Jm, h)


@numba.njit(cache=True, nogil=True)   # nogil: prediction bands simulate their members on threads
def _run(th, ku, kemf, Jm, grid, gtab, Mtab, pwm, state, period, substeps):
    """Measured angle (rad) after each held PWM sample of ``pwm``, from ``state`` (in place). A period is
    a function of the state and its PWM alone: one that left the state as it was (the same bits: the axis
    at rest, held by its friction) leaves it so again under the same PWM, and is not computed again."""
    out = np.empty(pwm.size)
    h = period / substeps
    n, unit = elements_of(th)
    before = np.empty(state.size)
    still = False
    for k in range(pwm.size):
        if not (still and _same(pwm[k], pwm[k - 1])):
            before[:] = state
            _step_period(state, th, n, unit, pwm[k], grid, gtab, Mtab, ku, kemf, Jm, h, substeps)
            still = True
            for i in range(state.size):
                still = still and _same(state[i], before[i])
        out[k] = state[0]
    return out


# the firmware's rules compiled from their one statement; the closed-loop run inlines them, so it is
# built in a closure over their source's hash (numba's cache keys a function on its own file only)
_quantise, _saturate = numba.njit(cache=True)(quantise), numba.njit(cache=True)(saturate)
RULES = hashlib.sha256(Path(firmware_rules.__file__).read_bytes()).hexdigest()


def _keyed_run_closed(rules: str):
    """:func:`simulate_axis_closed`'s kernel, compiled in a closure over ``rules`` (:data:`RULES`)."""

    @numba.njit(cache=True, nogil=True)
    def run_closed(th, ku, kemf, Jm, grid, gtab, Mtab, law, excitation, state, period, substeps, count):
        """Measured angle (rad) at each sample under ``pwm_k = saturate(law[0] + law[1] y_k + law[2] (y_k -
        y_k-1) / period + excitation_k, law[3])`` with ``y`` the angle the encoder reads (``quantise``:
        whole ``count``s, rad, from the start; 0: exact), from ``state`` at rest (in place); the PWM
        applied at each sample is returned too."""
        out, applied = np.empty(excitation.size), np.empty(excitation.size)
        if len(rules) == 0:            # the closure's key (never empty)
            return out, applied
        h = period / substeps
        n, unit = elements_of(th)
        origin = state[0]
        previous = origin
        for k in range(excitation.size):
            y = _quantise(state[0], count, 0.0, origin)
            u = _saturate(law[0] + law[1] * y + law[2] * (y - previous) / period + excitation[k], law[3], False)
            previous = y
            out[k], applied[k] = y, u
            _step_period(state, th, n, unit, u, grid, gtab, Mtab, ku, kemf, Jm, h, substeps)
        return out, applied

    return run_closed


_run_closed = _keyed_run_closed(RULES)


@numba.njit(cache=True)
def advance(th, ku, kemf, Jm, gravity, inertia, pwm, state, period, substeps):
    """One axis's ``state`` over ``period`` s in ``substeps`` with ``pwm``, ``gravity`` and ``inertia``
    held (in place). The compiled closed loop has its declared C twin (:mod:`rcm_kin.simulation.kernel`)."""
    h = period / substeps
    n, unit = elements_of(th)
    for _ in range(substeps):
        _substep(state, th, n, unit, pwm, gravity, inertia, ku, kemf, Jm, h)


def advance_axis(friction_vector: np.ndarray, input_gain: float, back_emf: float, rotor_inertia: float,
                 gravity: float, inertia: float, pwm: float, state: np.ndarray, period: float) -> None:
    """Advance one axis's ``state`` (in place) over ``period`` s with ``pwm`` held and the
    rigid-body ``gravity`` (N m, bias forces included) and link ``inertia`` (kg m^2) frozen over
    the period: the closed-loop simulator's plant step. ``friction_vector``: :meth:`AxisFriction.vector`."""
    substeps = substep_count(period)
    advance(friction_vector, input_gain, back_emf, rotor_inertia, gravity, inertia, pwm, _checked(state), period,
            substeps)


def virgin_offsets(force: float, k_each: float, slip: float, n: int) -> np.ndarray:
    """Each element's stretch ``q - z_i`` (rad, (n,)) where a Maxwell-slip spring of ``n`` elements
    (each ``k_each`` N m/rad, slipping at i :func:`force_unit` of ``slip`` N m) loaded from relaxed
    along its virgin (Masing) curve carries ``force`` N m (``|force| <= slip``): the displacement
    ``d`` with ``sum_i min(k_each |d|, F_i) = |force|``, element i stretched ``sign(force) min(|d|,
    F_i / k_each)``."""
    unit = float(force_unit(slip, n))
    target, carried, d = abs(force), 0.0, 0.0
    for j in range(n):   # elements j.. still elastic between the slips of j - 1 and j
        d = (target - carried) / ((n - j) * k_each)
        if d <= unit * (j + 1) / k_each or j == n - 1:
            break
        carried += unit * (j + 1)
    sign = 1.0 if force > 0 else -1.0 if force < 0 else 0.0
    return np.array([sign * min(d, unit * (i + 1) / k_each) for i in range(n)])


def rest_angle(friction: AxisFriction, plant: AxisPlant, angle: float, pwm: float) -> float:
    """The link angle (rad) of :func:`rest_state`: behind the measured ``angle`` by the cable's stretch
    under ``pwm``."""
    return angle - (plant.input_gain * pwm / friction.cable_stiffness if friction.cable_stiffness > 0 else 0.0)


def rest_state(friction: AxisFriction, plant: AxisPlant, angle: float, pwm: float,
               preload: float = 0.0) -> np.ndarray:
    """``[theta, w, q, v, z_1 .. z_MAX_ELEMENTS]`` (:data:`STATE_SIZE`) at rest with the measured angle
    ``angle`` (rad) under ``pwm``, in the static equilibrium the axis came to rest in: the cable
    carries the motor torque, and what the rigid-body gravity leaves unbalanced (``load``) loads the
    presliding spring, with the presliding state a previous approach left: the spring carries
    ``clip(load + preload F_p, -F_p, F_p)`` (``preload`` in [-1, 1]; 0: the load alone), its anchors
    on the virgin curve that carries it (:func:`virgin_offsets`; unused anchors at ``q``). Any rest is
    left to the friction, which holds it within the static friction."""
    if not -1.0 <= preload <= 1.0:
        raise RcmKinError(f"the presliding preload is a fraction of the slip force in [-1, 1], got {preload!r}",
                          parameter="preload")
    torque = plant.input_gain * pwm
    q = rest_angle(friction, plant, angle, pwm)
    state = np.full(STATE_SIZE, q)
    state[0], state[1], state[3] = angle, 0.0, 0.0
    if friction.presliding_stiffness > 0:
        n = int(friction.presliding_elements)
        k = friction.presliding_stiffness * np.exp(friction.presliding_slope * q)
        load = torque - np.interp(q, plant.grid, plant.gravity)
        slip = friction.presliding_force
        state[4:4 + n] = q - virgin_offsets(min(max(load + preload * slip, -slip), slip), k / n, slip, n)
    return state


def _checked(state: np.ndarray) -> np.ndarray:
    """``state`` as the kernels advance it in place: :data:`STATE_SIZE` contiguous floats."""
    if not (isinstance(state, np.ndarray) and state.shape == (STATE_SIZE,) and state.dtype == np.float64
            and state.flags.c_contiguous and state.flags.writeable):
        raise RcmKinError(f"an axis state is a writable float array of {STATE_SIZE} ([theta, w, q, v, z_1 .. "
                          f"z_{MAX_ELEMENTS}], rest_state), got {getattr(state, 'shape', type(state).__name__)}",
                          parameter="state")
    return state


def simulate_axis(friction: AxisFriction, plant: AxisPlant, pwm: np.ndarray, period: float,
                  state: np.ndarray) -> np.ndarray:
    """Measured angle (rad) after each of ``pwm``'s samples (counts, within the driver's
    +-:data:`~rcm_kin.hardware.DRIVER_PWM_RANGE`), each held for ``period`` s, from ``state``
    (see :func:`rest_state`; advanced in place)."""
    substeps = substep_count(_checked_period(period))
    return _run(friction.vector(), plant.input_gain, plant.back_emf, plant.rotor_inertia, plant.grid,
                plant.gravity, plant.inertia, _checked_pwm(pwm), _checked(state), period, substeps)


def _checked_pwm(pwm) -> np.ndarray:
    """``pwm`` as a 1-D float array of finite counts within the driver's range, or an RcmKinError."""
    pwm = as_numbers(pwm, "pwm", "PWM counts")
    if pwm.ndim != 1 or not np.all(np.isfinite(pwm)) or np.any(np.abs(pwm) > DRIVER_PWM_RANGE):
        largest = np.nanmax(np.abs(pwm), initial=0)
        raise RcmKinError(f"`pwm` must be a 1-D series of finite counts within +-{DRIVER_PWM_RANGE:.0f} (the "
                          f"8-bit driver's range), got shape {pwm.shape}, largest {largest:g}", parameter="pwm")
    return pwm


def _checked_period(period) -> float:
    if isinstance(period, bool) or not isinstance(period, (int, float, np.number)) or not 0 < period <= 1.0:
        raise RcmKinError(f"`period` is the PWM's hold time, 0 to 1 s, got {period!r}", parameter="period")
    return float(period)


def simulate_axis_closed(friction: AxisFriction, plant: AxisPlant, law: np.ndarray, excitation: np.ndarray,
                         period: float, state: np.ndarray, count: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The axis under a linear feedback law sampled every ``period`` s: at sample k the PWM
    ``clip(law[0] + law[1] y_k + law[2] (y_k - y_k-1) / period + excitation[k], +-law[3])`` (counts,
    :func:`rcm_kin.firmware_rules.saturate`; ``y`` the measured angle, rad, in whole encoder
    ``count``s (rad) from the start, as the firmware reads it, :func:`rcm_kin.firmware_rules.quantise`
    from the starting angle; 0: exact; the first difference taken from rest) is held for one period.
    Returns the measured angle at each sample (before its PWM acts) and the PWM applied, from
    ``state`` (advanced in place)."""
    substeps = substep_count(period)
    return _run_closed(friction.vector(), plant.input_gain, plant.back_emf, plant.rotor_inertia, plant.grid,
                       plant.gravity, plant.inertia, np.asarray(law, dtype=float),
                       np.asarray(excitation, dtype=float), _checked(state), period, substeps, count)


def axis_plant(model: "DrivenDynamics", joint: str, pose, span: float = np.radians(45.0),
               points: int = 181) -> AxisPlant:
    """The rigid-body model along ``joint`` with the other driven joints held at ``pose``
    (rad, rad, m): gravity and inertia tabulated over ``+-span`` rad (rotor inertia apart).
    ``model`` is built without identified extras (extra inertia, viscous friction 0), which
    :class:`AxisFriction` carries."""
    i = model.joints.index(joint)
    grid = np.linspace(-span, span, points)
    poses = np.repeat(np.asarray(pose, dtype=float)[None, :], points, axis=0)
    poses[:, i] = grid
    gravity = np.array(model.gravity.map(points)(poses.T))[i]
    inertia = np.array([float(model.mass_matrix(p)[i, i]) for p in poses]) - model.drive.reflected_inertia[i]
    return AxisPlant(float(model.drive.input_gain[i]), float(model.drive.damping[i]),
                     float(model.drive.reflected_inertia[i]), grid, gravity, inertia)

"""One driven axis with friction that really sticks: the drive-train model identified on the logs.

Per driven joint (joint-referred SI: rad, N m, kg m^2), with the encoder on the motor:

    motor:  J_m  w' = k_u u - (k_e + b_m) w - f_m - tau_c                (drive side)
    cable:  tau_c = k_c (theta - q) + d_c (w - v)                         (capstan compliance)
    link:   (M_ii(q) + J_x) v' = tau_c - g_i(q) - b v - f_l - tau_p      (link side)
    presliding spring: tau_p = k_p(q) (q - z), |tau_p| <= F_p, z moves when the bound is hit
    measured angle: theta (motor angle / gear ratio)

- ``k_u``, ``k_e`` (back-EMF damping) and ``J_m`` (reflected rotor inertia) are the drive's. A
  driver dead-band is not in the family: the steps and PRBS logs never cross zero PWM (they
  hold at -5 to -110 counts), and in the one log that starts at zero (the pitch ramp) a
  dead-band cannot be told from the static friction and gravity the ramp must overcome.
- ``f_l``, ``f_m``: set-valued friction. At rest a side stays at rest while the force on it is
  within the static friction ``F_s``; sliding, ``f = sign(v) (F_c + (F_s - F_c) exp(-(v/v_s)^2))``
  (Stribeck) plus viscous ``b v``. The motor side has Coulomb and viscous friction, no stiction.
- ``tau_p``: an elasto-plastic (Maxwell-slip) spring: stiffness ``k_p(q) = k_p0 exp(s q)``
  anchored at ``z``, which follows the axis only while the spring slips at ``F_p``, so the
  spring pulls back towards where the last slip ended. This is what the roll steps show: each
  behaves like a spring anchored at the angle where it started (held there, the spring relaxed).
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
from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.firmware_rules import quantise, saturate

if TYPE_CHECKING:
    from rcm_kin.dynamics.state_space import DrivenDynamics

TERMS = ("viscous", "stiction", "presliding", "two_mass")
SUBSTEP = 2.5e-4   # s: integration step
COUPLING_SWEEPS = 4   # block Gauss-Seidel sweeps of the motor-cable-link step: each contracts the coupling
                      # error by h^2 k_c / (J_m + h^2 k_c) x h^2 k_c / M (< 0.03 up to k_c = 1e6 N m/rad)


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
def _lookup(x, grid, table):
    """Linear interpolation on a uniform grid, held at the end values outside it (as np.interp)."""
    x = min(max(x, grid[0]), grid[-1])
    step = grid[1] - grid[0]
    i = min(max(int((x - grid[0]) / step), 0), grid.size - 2)
    w = (x - grid[i]) / step
    return table[i] * (1.0 - w) + table[i + 1] * w


@numba.njit(cache=True)
def _implicit_friction(v, J, h, F, B, static, coulomb, stribeck):
    """v after a step of ``J v' = F - B v - f`` with ``f`` from the friction set (implicit)."""
    p = J * v + h * F
    static = max(static, coulomb)
    if v == 0.0:
        if abs(p) <= h * static:
            return 0.0
        return (p - h * coulomb * np.sign(p)) / (J + h * B)
    f = coulomb + (static - coulomb) * np.exp(-(v / stribeck) ** 2)
    new = (p - h * f * np.sign(v)) / (J + h * B)
    return 0.0 if new * v <= 0.0 else new


@numba.njit(cache=True)
def _substep(state, th, pwm, gravity, inertia, ku, kemf, Jm, h):
    """Advance ``state = [theta, w, q, v, z]`` by ``h`` with ``pwm`` held (in place)."""
    Jx, b, Fc, Fs, vs, kp0, sp, Fp, kc, dc, Fcm, bm = th[0], th[1], th[2], th[3], th[4], th[5], th[6], \
        th[7], th[8], th[9], th[10], th[11]
    q = state[2]
    kp = kp0 * np.exp(sp * q) if kp0 > 0.0 else 0.0
    spring = kp * (q - state[4])
    if kc > 0.0:   # two masses, the cable implicit in both velocities: block Gauss-Seidel sweeps
        stretch, coupling = kc * (state[0] - q), dc + h * kc
        w, v = state[1], state[3]
        for _ in range(COUPLING_SWEEPS):
            w = _implicit_friction(state[1], Jm, h, ku * pwm - stretch + coupling * v, kemf + bm + coupling,
                                   Fcm, Fcm, 1.0)
            v = _implicit_friction(state[3], inertia + Jx, h, stretch + coupling * w - gravity - spring,
                                   b + coupling + h * kp, Fs, Fc, vs)
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
    if kp > 0.0:   # the presliding spring slips at its bound
        if kp * (state[2] - state[4]) > Fp:
            state[4] = state[2] - Fp / kp
        elif kp * (state[2] - state[4]) < -Fp:
            state[4] = state[2] + Fp / kp


@numba.njit(cache=True)
def _step_period(state, th, pwm, grid, gtab, Mtab, ku, kemf, Jm, h, substeps):
    for _ in range(substeps):
        _substep(state, th, pwm, _lookup(state[2], grid, gtab), _lookup(state[2], grid, Mtab), ku, kemf, Jm, h)


@numba.njit(cache=True)
def _run(th, ku, kemf, Jm, grid, gtab, Mtab, pwm, state, period, substeps):
    """Measured angle (rad) after each held PWM sample of ``pwm``, from ``state`` (in place)."""
    out = np.empty(pwm.size)
    h = period / substeps
    for k in range(pwm.size):
        _step_period(state, th, pwm[k], grid, gtab, Mtab, ku, kemf, Jm, h, substeps)
        out[k] = state[0]
    return out


# the firmware's rules compiled from their one statement; the closed-loop run inlines them, so it is
# built in a closure over their source's hash (numba's cache keys a function on its own file only)
_quantise, _saturate = numba.njit(cache=True)(quantise), numba.njit(cache=True)(saturate)
RULES = hashlib.sha256(Path(firmware_rules.__file__).read_bytes()).hexdigest()


def _keyed_run_closed(rules: str):
    """:func:`simulate_axis_closed`'s kernel, compiled in a closure over ``rules`` (:data:`RULES`)."""

    @numba.njit(cache=True)
    def run_closed(th, ku, kemf, Jm, grid, gtab, Mtab, law, excitation, state, period, substeps, count):
        """Measured angle (rad) at each sample under ``pwm_k = saturate(law[0] + law[1] y_k + law[2] (y_k -
        y_k-1) / period + excitation_k, law[3])`` with ``y`` the angle the encoder reads (``quantise``:
        whole ``count``s, rad, from the start; 0: exact), from ``state`` at rest (in place); the PWM
        applied at each sample is returned too."""
        out, applied = np.empty(excitation.size), np.empty(excitation.size)
        if len(rules) == 0:            # the closure's key (never empty)
            return out, applied
        h = period / substeps
        origin = state[0]
        previous = origin
        for k in range(excitation.size):
            y = _quantise(state[0], count, 0.0, origin)
            u = _saturate(law[0] + law[1] * y + law[2] * (y - previous) / period + excitation[k], law[3], False)
            previous = y
            out[k], applied[k] = y, u
            _step_period(state, th, u, grid, gtab, Mtab, ku, kemf, Jm, h, substeps)
        return out, applied

    return run_closed


_run_closed = _keyed_run_closed(RULES)


@numba.njit(cache=True)
def advance(th, ku, kemf, Jm, gravity, inertia, pwm, state, period, substeps):
    h = period / substeps
    for _ in range(substeps):
        _substep(state, th, pwm, gravity, inertia, ku, kemf, Jm, h)


def substep_count(period: float) -> int:
    """Integration substeps (each at most :data:`SUBSTEP` s) in one ``period`` s."""
    return max(1, int(np.ceil(period / SUBSTEP - 1e-9)))


def advance_axis(friction_vector: np.ndarray, input_gain: float, back_emf: float, rotor_inertia: float,
                 gravity: float, inertia: float, pwm: float, state: np.ndarray, period: float) -> None:
    """Advance one axis's ``state`` (in place) over ``period`` s with ``pwm`` held and the
    rigid-body ``gravity`` (N m, bias forces included) and link ``inertia`` (kg m^2) frozen over
    the period: the closed-loop simulator's plant step. ``friction_vector``: :meth:`AxisFriction.vector`."""
    substeps = substep_count(period)
    advance(friction_vector, input_gain, back_emf, rotor_inertia, gravity, inertia, pwm, state, period, substeps)


def rest_state(friction: AxisFriction, plant: AxisPlant, angle: float, pwm: float) -> np.ndarray:
    """``[theta, w, q, v, z]`` at rest with the measured angle ``angle`` (rad) under ``pwm``, in the
    static equilibrium the axis came to rest in: the cable carries the motor torque, and what the
    rigid-body gravity leaves unbalanced loads the presliding spring (up to its slip force; any
    rest is left to the friction, which holds it within the static friction)."""
    torque = plant.input_gain * pwm
    stretch = torque / friction.cable_stiffness if friction.cable_stiffness > 0 else 0.0
    q = angle - stretch
    anchor = q
    if friction.presliding_stiffness > 0:
        k = friction.presliding_stiffness * np.exp(friction.presliding_slope * q)
        load = torque - np.interp(q, plant.grid, plant.gravity)
        anchor = q - np.clip(load, -friction.presliding_force, friction.presliding_force) / k
    return np.array([angle, 0.0, q, 0.0, anchor])


def simulate_axis(friction: AxisFriction, plant: AxisPlant, pwm: np.ndarray, period: float,
                  state: np.ndarray) -> np.ndarray:
    """Measured angle (rad) after each of ``pwm``'s samples, each held for ``period`` s, from
    ``state`` (see :func:`rest_state`; advanced in place)."""
    substeps = substep_count(period)
    return _run(friction.vector(), plant.input_gain, plant.back_emf, plant.rotor_inertia, plant.grid,
                plant.gravity, plant.inertia, np.asarray(pwm, dtype=float), state, period, substeps)


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
                       np.asarray(excitation, dtype=float), state, period, substeps, count)


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

"""The stick-slip kernel's shortcuts give the same bits as the kernel without them.

The reference below is the kernel as it was before the shortcuts (the Stribeck exponential computed
when multiplied by 0, the grid cell found once per table, every coupling sweep run, every period
integrated), kept here verbatim and compiled by numba the same way. The shipped kernels
(``simulate_axis``, ``simulate_axis_closed``'s period, ``advance_axis``) must give the same floats, bit
for bit, over parameter sets with and without each term, sticking and sliding.
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numba
import numpy as np
import pytest

from rcm_kin.dynamics.axis_friction import COUPLING_SWEEPS, substep_count
from rcm_kin.dynamics.stick_slip import (
    AxisFriction,
    AxisPlant,
    advance_axis,
    elements_of,
    rest_state,
    simulate_axis,
    slip_elements,
)


@numba.njit
def reference_lookup(x, grid, table):
    x = min(max(x, grid[0]), grid[-1])
    step = grid[1] - grid[0]
    i = min(max(int((x - grid[0]) / step), 0), grid.size - 2)
    w = (x - grid[i]) / step
    return table[i] * (1.0 - w) + table[i + 1] * w


@numba.njit
def reference_implicit_friction(v, J, h, F, B, static, coulomb, stribeck):
    p = J * v + h * F
    static = max(static, coulomb)
    if v == 0.0:
        if abs(p) <= h * static:
            return 0.0
        return (p - h * coulomb * np.sign(p)) / (J + h * B)
    f = coulomb + (static - coulomb) * np.exp(-(v / stribeck) ** 2)
    new = (p - h * f * np.sign(v)) / (J + h * B)
    return 0.0 if new * v <= 0.0 else new


@numba.njit
def reference_substep(state, th, n, unit, pwm, gravity, inertia, ku, kemf, Jm, h):
    Jx, b, Fc, Fs, vs, kp0, sp = th[0], th[1], th[2], th[3], th[4], th[5], th[6]
    kc, dc, Fcm, bm = th[8], th[9], th[10], th[11]
    q = state[2]
    kp = kp0 * np.exp(sp * q) if kp0 > 0.0 else 0.0
    k_each = kp / n
    spring = k_each * (q - state[4])
    for i in range(1, n):
        spring += k_each * (q - state[4 + i])
    if kc > 0.0:
        stretch, coupling = kc * (state[0] - q), dc + h * kc
        w, v = state[1], state[3]
        for _ in range(COUPLING_SWEEPS):
            w = reference_implicit_friction(state[1], Jm, h, ku * pwm - stretch + coupling * v, kemf + bm + coupling,
                                            Fcm, Fcm, 1.0)
            v = reference_implicit_friction(state[3], inertia + Jx, h, stretch + coupling * w - gravity - spring,
                                            b + coupling + h * kp, Fs, Fc, vs)
        state[1], state[3] = w, v
        state[0] += h * w
    else:
        F = ku * pwm - gravity - spring
        state[3] = reference_implicit_friction(state[3], inertia + Jx + Jm, h, F, b + bm + kemf + h * kp,
                                               Fs + Fcm, Fc + Fcm, vs)
        state[1] = state[3]
    state[2] += h * state[3]
    if kc <= 0.0:
        state[0] = state[2]
    if kp > 0.0:
        slip_elements(state[2], state[4:], k_each, unit, n)


@numba.njit
def reference_run(th, ku, kemf, Jm, grid, gtab, Mtab, pwm, state, period, substeps):
    out = np.empty(pwm.size)
    h = period / substeps
    n, unit = elements_of(th)
    for k in range(pwm.size):
        for _ in range(substeps):
            reference_substep(state, th, n, unit, pwm[k], reference_lookup(state[2], grid, gtab),
                              reference_lookup(state[2], grid, Mtab), ku, kemf, Jm, h)
        out[k] = state[0]
    return out


def plant() -> AxisPlant:
    """A roll-like axis: gravity and inertia varying over the grid, a drive with back-EMF and a rotor."""
    grid = np.linspace(-np.pi / 4, np.pi / 4, 181)
    return AxisPlant(-0.06, 0.05, 0.003, grid, 0.6 * np.sin(grid + 0.3), 0.02 + 0.004 * np.cos(grid))


def frictions() -> list[AxisFriction]:
    """Parameter sets with each term on and off (stiction, presliding with 1-4 elements, a compliant
    cable), drawn within the identification's bounds, and a few hand-picked ones that stick."""
    rng = np.random.default_rng(30)
    out = [AxisFriction(coulomb=0.3, presliding_stiffness=40.0, presliding_slope=5.0, presliding_force=1.2,
                        cable_stiffness=170.0, cable_damping=26.0, motor_coulomb=0.001, motor_viscous=1.3),
           AxisFriction(coulomb=2.5, static=3.0, cable_stiffness=50.0, motor_coulomb=0.5),    # sticks hard
           AxisFriction(viscous=2.0, coulomb=0.2, static=0.4, stribeck_velocity=0.05)]        # rigid, Stribeck
    for k in range(12):
        out.append(AxisFriction(
            extra_inertia=rng.uniform(0, 0.5), viscous=rng.uniform(0, 5) * (k % 2), coulomb=rng.uniform(0, 1),
            static=rng.uniform(0, 1.5) * (k % 3 == 0), stribeck_velocity=np.exp(rng.uniform(-6, 0)),
            presliding_stiffness=np.exp(rng.uniform(0, 7)) * (k % 4 != 3), presliding_slope=rng.uniform(-8, 8),
            presliding_force=np.exp(rng.uniform(-3, 1.6)), cable_stiffness=np.exp(rng.uniform(1.6, 9)) * (k % 2),
            cable_damping=rng.uniform(0, 30), motor_coulomb=rng.uniform(0, 1), motor_viscous=rng.uniform(0, 10),
            presliding_elements=float(1 + k % 4)))
    return out


def name(friction: AxisFriction) -> str:
    return f"kc{friction.cable_stiffness:.3g}_n{friction.presliding_elements:g}_Fs{friction.static:.2g}"


def pwm_series() -> np.ndarray:
    """A step held long enough to stop, a reversal, and a binary sequence: sliding, sticking, starting again."""
    rng = np.random.default_rng(7)
    return np.r_[np.full(50, -20.0), np.full(400, -45.0), np.full(300, 30.0), np.full(200, 30.0 - 1e-12),
                 rng.choice([-60.0, 15.0], 300)]


@pytest.mark.parametrize("friction", frictions(), ids=name)
def test_simulate_axis_gives_the_reference_kernels_bits(friction):
    p, pwm, period = plant(), pwm_series(), 1e-3
    start = rest_state(friction, p, 0.1, pwm[0])
    expected_state = start.copy()
    expected = reference_run(friction.vector(), p.input_gain, p.back_emf, p.rotor_inertia, p.grid, p.gravity,
                             p.inertia, pwm, expected_state, period, substep_count(period))
    state = start.copy()
    got = simulate_axis(friction, p, pwm, period, state)
    assert got.tobytes() == expected.tobytes()
    assert state.tobytes() == expected_state.tobytes()
    assert np.ptp(expected) > 0.0                  # the axis moved: the comparison saw sliding


def test_the_reference_sees_sticking_and_the_shortcut_skips_it():
    """The hard-sticking set holds still for whole periods under a held PWM (the case the kernel skips),
    and still matches the reference where it breaks away again."""
    friction, p, period = frictions()[1], plant(), 1e-3
    pwm = np.r_[np.full(100, -30.0), np.full(300, -140.0), np.full(300, 0.0)]
    start = rest_state(friction, p, 0.0, pwm[0])
    expected_state = start.copy()
    expected = reference_run(friction.vector(), p.input_gain, p.back_emf, p.rotor_inertia, p.grid, p.gravity,
                             p.inertia, pwm, expected_state, period, substep_count(period))
    assert np.sum(np.diff(expected) == 0.0) > 100 and np.ptp(expected) > 0.0
    got = simulate_axis(friction, p, pwm, period, start.copy())
    assert got.tobytes() == expected.tobytes()


@pytest.mark.parametrize("friction", frictions()[:6], ids=name)
def test_advance_axis_gives_the_reference_kernels_bits(friction):
    p, period = plant(), 2.5e-3
    state, expected = rest_state(friction, p, -0.2, -30.0), rest_state(friction, p, -0.2, -30.0)
    n, unit = elements_of(friction.vector())
    substeps = substep_count(period)
    for k, pwm in enumerate(pwm_series()[::4]):
        gravity, inertia = 0.5 + 0.01 * k, 0.021
        advance_axis(friction.vector(), p.input_gain, p.back_emf, p.rotor_inertia, gravity, inertia, pwm, state,
                     period)
        for _ in range(substeps):
            reference_substep(expected, friction.vector(), n, unit, pwm, gravity, inertia, p.input_gain, p.back_emf,
                              p.rotor_inertia, period / substeps)
        assert state.tobytes() == expected.tobytes()

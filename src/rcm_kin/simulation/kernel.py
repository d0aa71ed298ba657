"""The numba kernels of the compiled closed loop: the firmware's rules, the controller laws, the
plant step and the loop over ticks.

Each firmware rule here is the declared twin of its plain statement in :mod:`rcm_kin.firmware_rules`,
written in the same order of operations (so both engines give the same numbers; the friction
feedforward's ``tanh`` is the C library's here and NumPy's own in the readable controller, 1 ulp apart
at some arguments); ``tests/simulation/test_rules.py`` holds each twin to its statement on random
inputs. :func:`command` runs the laws of :class:`~rcm_kin.simulation.kernel_forms.LoopLaw` as the
readable controllers (:mod:`rcm_kin.simulation.controllers`) do.

The plant's CasADi functions are called through their C entry point
(``f(arg, res, iw, w, mem)``) by address (:func:`call_c`); the drive-train axes are advanced by
the stick-slip model's own kernel (:func:`rcm_kin.dynamics.stick_slip.advance`).

numba's on-disk cache keys a function on its own file only, not on the modules it inlines. What
the kernel takes from other modules' source is therefore keyed explicitly: the plant step inlines
the stick-slip kernels, and the laws test the kinds of :mod:`rcm_kin.simulation.kernel_forms`
(``P``, ``PID``, ``THESIS``, frozen into the machine code), so the laws, the plant step and the
loops over them are built in closures over :data:`SOURCES`, a hash of ``stick_slip.py``,
``kernel_forms.py`` and ``firmware_rules.py`` (numba keys cached closures on their cell contents):
a change to any of them compiles anew. The functions at this module's top level use nothing but
this file. The other modules' numbers (``hardware.INSERTION_KP``, ``loop.FIRMWARE_SCALE``) are
kernel arguments, never frozen into the cached machine code.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from rcm_kin import firmware_rules
from rcm_kin.dynamics import stick_slip
from rcm_kin.dynamics.stick_slip import STATE_SIZE, advance
from rcm_kin.simulation import kernel_forms
from rcm_kin.simulation.kernel_forms import PID, THESIS, P

DRIVE_TRAIN, SMOOTH = 0, 1                         # CompiledPlant.kind


# --- the firmware's rules: twins of rcm_kin.firmware_rules ------------------------------------

@numba.njit(cache=True)
def cell(grid, x):
    """Twin of ``firmware_rules._cell``: the cell index (largest i with grid[i] <= x, at most
    n - 2) and x clamped to the grid."""
    x = min(max(x, grid[0]), grid[-1])
    i = 0
    while i + 2 < grid.size and grid[i + 1] <= x:
        i += 1
    return i, x


@numba.njit(cache=True)
def bilinear(roll_grid, pitch_grid, table, roll, pitch, out):
    """Twin of :func:`rcm_kin.firmware_rules.bilinear` (clamped, along roll on the two pitch
    rows, then along pitch): every value of ``table[pitch][roll]`` at the pose into ``out``."""
    i, r = cell(roll_grid, roll)
    j, p = cell(pitch_grid, pitch)
    fr = (r - roll_grid[i]) / (roll_grid[i + 1] - roll_grid[i])
    fp = (p - pitch_grid[j]) / (pitch_grid[j + 1] - pitch_grid[j])
    for m in range(out.size):
        low = table[j, i, m] + (table[j, i + 1, m] - table[j, i, m]) * fr
        high = table[j + 1, i, m] + (table[j + 1, i + 1, m] - table[j + 1, i, m]) * fr
        out[m] = low + (high - low) * fp


@numba.njit(cache=True)
def integral_law(pid, with_feedforward, c1, c2, k_integral, integral, feedforward):
    """The laws the kernel integrates, at ``E = integral``: the PID's ``-(c1 + Ki E + c2)``
    (c1 = Kp e, c2 = Kd de) or the pitch's ``-(c1 + c2 + Ki E) [+ feedforward]`` (c2 = Kd v)."""
    if pid:
        return -(c1 + k_integral * integral + c2)
    u = -(c1 + c2 + k_integral * integral)
    return u + feedforward if with_feedforward else u


@numba.njit(cache=True)
def conditional_integral(integral, error, period, limit, pid, with_feedforward, c1, c2, k_integral, feedforward):
    """Twin of :func:`rcm_kin.firmware_rules.conditional_integral` with the law
    :func:`integral_law`: ``(u, integral)``."""
    candidate = integral + error * period
    u = integral_law(pid, with_feedforward, c1, c2, k_integral, candidate, feedforward)
    held = integral_law(pid, with_feedforward, c1, c2, k_integral, integral, feedforward)
    if abs(u) > limit and np.sign(u) == np.sign(u - held):
        return held, integral
    return u, candidate


@numba.njit(cache=True)
def quantise(position, count, noise, out):
    """Twin of :func:`rcm_kin.firmware_rules.quantise`, into ``out``."""
    for j in range(3):
        if count[j] == 0.0:
            out[j] = position[j]
        else:
            out[j] = (np.round(position[j] / count[j]) + noise[j]) * count[j]


@numba.njit(cache=True)
def velocity_estimate(measured, previous, filtered, period, roll_filter):
    """Twin of :func:`rcm_kin.firmware_rules.velocity_estimate`, ``filtered`` updated in place."""
    raw0 = (measured[0] - previous[0]) / period
    filtered[0] = roll_filter * filtered[0] + (1 - roll_filter) * raw0
    filtered[1] = (measured[1] - previous[1]) / period
    filtered[2] = (measured[2] - previous[2]) / period


@numba.njit(cache=True)
def saturate(command, limit, whole_counts, out):
    """Twin of :func:`rcm_kin.firmware_rules.saturate`, into ``out``."""
    for j in range(3):
        out[j] = min(max(command[j], -limit[j]), limit[j])
        if whole_counts:
            out[j] = np.trunc(out[j])


@numba.njit(cache=True)
def p_command(kp, error):
    """Twin of :func:`rcm_kin.firmware_rules.p_command`: ``-Kp e``."""
    return -kp * error


@numba.njit(cache=True)
def insertion_command(reference, measured, kp):
    """Twin of :func:`rcm_kin.firmware_rules.insertion_command`: ``Kp (r - y)`` (``kp`` counts/m)."""
    return kp * (reference - measured)


@numba.njit(cache=True)
def friction_feedforward(amplitude, ramp, rdot):
    """Twin of :meth:`rcm_kin.control.friction.FrictionCompensation.feedforward` for
    one axis: ``-F tanh(rdot / v_ramp)`` counts (``amplitude`` F, ``ramp`` v_ramp deg/s)."""
    return -amplitude * np.tanh(rdot / ramp)


SOURCES = hashlib.sha256(b"".join(Path(m.__file__).read_bytes()
                                  for m in (stick_slip, kernel_forms, firmware_rules))).hexdigest()
"""The key of the cached kernels that inline other modules' code (see the module notes)."""


# --- the controller laws ------------------------------------------------------------------------

def _keyed_laws(sources: str):
    """The laws, compiled in a closure over ``sources`` (:data:`SOURCES`): the kinds they test
    are :mod:`rcm_kin.simulation.kernel_forms`' constants, frozen into the cached code."""

    @numba.njit(cache=True)
    def gain_scheduled(kind, flags, roll_grid, pitch_grid, table, hold_table, friction, memory, measured, velocity,
                       reference, rdot, racc, period, limit, scratch, command):
        """The thesis and state-feedback laws (``ThesisController``, ``StateFeedbackController``)."""
        if len(sources) == 0:              # the closure's key (never empty)
            return
        e0, e1 = reference[0] - measured[0], reference[1] - measured[1]
        scheduled, gravity, track, compensate = flags[0], flags[1], flags[2], flags[3]
        at0, at1 = (measured[0], measured[1]) if (scheduled or kind == THESIS) else (0.0, 0.0)
        k = scratch[:7]
        bilinear(roll_grid, pitch_grid, table, at0, at1, k)
        v0, v1 = velocity[0], velocity[1]
        if kind == THESIS:
            command[0] = -(k[0] * e0 + k[1] * v0)
            command[1], memory[0] = conditional_integral(memory[0], e1, period, limit[1], False, False,
                                                         k[2] * e1, k[3] * v1, k[4], 0.0)
            return
        if track:
            v0, v1 = v0 - rdot[0], v1 - rdot[1]
        hold = scratch[7:9]
        if gravity:
            bilinear(roll_grid, pitch_grid, hold_table, reference[0], reference[1], hold)
        else:
            hold[0], hold[1] = 0.0, 0.0
        if compensate:
            hold[0] = hold[0] + friction_feedforward(friction[0], friction[2], rdot[0])
            hold[1] = hold[1] + friction_feedforward(friction[1], friction[2], rdot[1])
        command[0] = -(k[0] * e0 + k[1] * v0) + hold[0]
        feedforward = k[5] * rdot[1] + k[6] * racc[1] + hold[1]
        command[1], memory[0] = conditional_integral(memory[0], e1, period, limit[1], False, True,
                                                     k[2] * e1, k[3] * v1, k[4], feedforward)

    @numba.njit(cache=True)
    def command(kind, flags, gains, roll_grid, pitch_grid, table, hold_table, friction, memory, measured, velocity,
                reference, rdot, racc, period, limit, insertion_kp, scratch, out):
        """The controller's ``command`` (firmware units, before saturation) into ``out``; ``memory``
        updated in place; the insertion by its P loop (``insertion_kp`` counts/m)."""
        if len(sources) == 0:
            return
        e0, e1 = reference[0] - measured[0], reference[1] - measured[1]
        if kind == P:
            out[0] = p_command(gains[0], e0)
            out[1] = p_command(gains[1], e1)
        elif kind == PID:                                    # memory: integrals, previous errors
            e = (e0, e1)
            for i in range(2):
                de = 0.0 if np.isnan(memory[2 + i]) else (e[i] - memory[2 + i]) / period
                out[i], memory[i] = conditional_integral(memory[i], e[i], period, limit[i], True, False,
                                                         gains[i] * e[i], gains[4 + i] * de, gains[2 + i], 0.0)
            memory[2], memory[3] = e0, e1
        else:                                                # STATE_FEEDBACK or THESIS
            gain_scheduled(kind, flags, roll_grid, pitch_grid, table, hold_table, friction, memory, measured,
                           velocity, reference, rdot, racc, period, limit, scratch, out)
        out[2] = insertion_command(reference[2], measured[2], insertion_kp)

    return gain_scheduled, command


gain_scheduled, command = _keyed_laws(SOURCES)


# --- the plant ----------------------------------------------------------------------------------

@intrinsic
def call_c(typingctx, address, arg, res, iw, w):
    """``((int (*)(double**, double**, long long*, double*, int)) address)(arg, res, iw, w, 0)``,
    every pointer given as an integer address."""
    if not all(isinstance(t, types.Integer) for t in (address, arg, res, iw, w)):
        return None
    signature = types.int32(address, arg, res, iw, w)

    def codegen(context, builder, sig, args):
        pointer = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.IntType(32), [pointer] * 4 + [ir.IntType(32)])
        fn = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(fn, [builder.inttoptr(a, pointer) for a in args[1:]] + [ir.Constant(ir.IntType(32), 0)])
    return signature, codegen


def _keyed_plant_step(physics: str):
    """The plant step compiled in a closure over ``physics`` (:data:`SOURCES`), so numba's cache
    keys it on the drive-train model it inlines."""

    @numba.njit(cache=True)
    def plant_step(kind, x, u, addresses, parameters, friction, input_gain, damping, reflected_inertia, period,
                   substeps, buffers, arg, res, iw, w, axis):
        """One period of the plant (``DriveTrainPlant.step`` or the smooth period map) under
        ``u`` (3,), x advanced in place. Each function gets ``parameters`` in the slot after its own
        inputs (a parametric function's last input; a function without one ignores the slot)."""
        if len(physics) == 0:          # the closure's key (never empty)
            return
        if kind == SMOOTH:             # x (6,) -> period_map(x, u)
            out = buffers[18:24]
            arg[0], arg[1], arg[2], res[0] = x.ctypes.data, u.ctypes.data, parameters.ctypes.data, out.ctypes.data
            call_c(addresses[0], arg.ctypes.data, res.ctypes.data, iw.ctypes.data, w.ctypes.data)
            x[:] = out
            return
        q, v, M, h = buffers[0:3], buffers[3:6], buffers[6:15], buffers[15:18]
        for i in range(3):
            q[i], v[i] = x[6 + i], x[9 + i]
        arg[0], arg[1], res[0] = q.ctypes.data, parameters.ctypes.data, M.ctypes.data
        call_c(addresses[0], arg.ctypes.data, res.ctypes.data, iw.ctypes.data, w.ctypes.data)
        arg[0], arg[1], arg[2], res[0] = q.ctypes.data, v.ctypes.data, parameters.ctypes.data, h.ctypes.data
        call_c(addresses[1], arg.ctypes.data, res.ctypes.data, iw.ctypes.data, w.ctypes.data)
        for i in range(3):
            for r in range(STATE_SIZE):
                axis[r] = x[3 * r + i]
            advance(friction[i], input_gain[i], damping[i], reflected_inertia[i], h[i],
                    M[4 * i] - reflected_inertia[i], u[i], axis, period, substeps)
            for r in range(STATE_SIZE):
                x[3 * r + i] = axis[r]

    return plant_step


@numba.njit(cache=True)
def work_buffers(work):
    """Buffers of the plant step: q, v, M, h, x(T) values, CasADi's arg, res, iw and w (``work``
    (k, 4): each function's sizes; arg at least 3 slots, for the parameters after two inputs). (The
    axis state's buffer, of the stick-slip model's ``STATE_SIZE``, is made by the keyed loops: this
    function is keyed on this file alone.)"""
    size = np.array([3, 2, 2, 2], dtype=np.int64)
    for row in work:
        size = np.maximum(size, row)
    return (np.zeros(24), np.zeros(size[0], dtype=np.int64), np.zeros(size[1], dtype=np.int64),
            np.zeros(size[2], dtype=np.int64), np.zeros(size[3]))


plant_step = _keyed_plant_step(SOURCES)


# --- the loops ----------------------------------------------------------------------------------

def _keyed_loops(physics: str):
    """The loops over :data:`plant_step`, keyed like it (see :func:`_keyed_plant_step`)."""

    @numba.njit(cache=True)
    def plant_steps(x, u, kind, addresses, work, parameters, friction, input_gain, damping, reflected_inertia,
                    period, substeps):
        """One plant step per row of ``u`` (n, 3), x in place."""
        if len(physics) == 0:
            return
        buffers, arg, res, iw, w = work_buffers(work)
        axis = np.zeros(STATE_SIZE)
        for k in range(u.shape[0]):
            plant_step(kind, x, u[k], addresses, parameters, friction, input_gain, damping, reflected_inertia,
                       period, substeps, buffers, arg, res, iw, w, axis)

    @numba.njit(cache=True)
    def run(first, stop, x, previous, filtered, memory, ref_fw, vel_fw, acc_fw, noise, period, limit, count,
            roll_filter, quantise_pwm, scale, insertion_kp, kind, flags, gains, roll_grid, pitch_grid, table,
            hold_table, friction_ff, plant_kind, addresses, work, parameters, friction, input_gain, damping,
            reflected_inertia, substeps, log_measured, log_position, log_command, log_pwm):
        """Ticks ``first .. stop - 1`` of ``loop.simulate`` (k < 0: settling); the loop's state
        (x, previous, filtered, memory) advanced in place, the ticks k >= 0 logged; ``scale`` (3,):
        joint units to firmware units (``loop.FIRMWARE_SCALE``), ``insertion_kp``: the insertion's
        P gain (counts/m). Returns the tick where the state stopped being finite, or ``stop``."""
        if len(physics) == 0:
            return first
        buffers, arg, res, iw, w = work_buffers(work)
        axis = np.zeros(STATE_SIZE)
        true, measured, out, u = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        rdot, racc, scratch = np.zeros(3), np.zeros(3), np.zeros(9)
        n_settle = noise.shape[0] - ref_fw.shape[0] - 1
        for k in range(first, stop):
            i = max(k, 0)
            moving = k >= 0
            for j in range(3):
                true[j] = x[j] * scale[j]
            quantise(true, count, noise[k + n_settle + 1], measured)
            velocity_estimate(measured, previous, filtered, period, roll_filter)
            for j in range(3):
                rdot[j] = vel_fw[i, j] if moving else 0.0
                racc[j] = acc_fw[i, j] if moving else 0.0
            command(kind, flags, gains, roll_grid, pitch_grid, table, hold_table, friction_ff, memory, measured,
                    filtered, ref_fw[i], rdot, racc, period, limit, insertion_kp, scratch, out)
            saturate(out, limit, quantise_pwm, u)
            if moving:
                for j in range(3):
                    log_measured[k, j], log_position[k, j] = measured[j], true[j]
                    log_command[k, j], log_pwm[k, j] = out[j], u[j]
            plant_step(plant_kind, x, u, addresses, parameters, friction, input_gain, damping, reflected_inertia,
                       period, substeps, buffers, arg, res, iw, w, axis)
            for j in range(x.size):
                if not np.isfinite(x[j]):
                    return k
            for j in range(3):
                previous[j] = measured[j]
        return stop

    return plant_steps, run


plant_steps, run = _keyed_loops(SOURCES)

"""The whole closed loop in one compiled kernel: encoders, velocity estimate, controller law,
saturation and the plant, tick after tick inside one numba function.

The readable classes stay the reference (:func:`rcm_kin.simulation.loop.simulate` with the
controllers of :mod:`rcm_kin.simulation.controllers` on
:class:`~rcm_kin.simulation.plant.DriveTrainPlant` or the smooth model's period map); this
kernel repeats their arithmetic operation for operation, and ``tests/simulation/test_compiled_loop.py``
holds it to them tick for tick.

- Plants (:class:`CompiledPlant`): the CasADi functions compiled to C
  (:func:`rcm_kin.symbolic.compiled.loaded_library`) and called from the kernel through their
  C entry point (CasADi's ``f(arg, res, iw, w, mem)``) by address: the same expression graphs,
  no table. The drive-train plant evaluates its mass matrix and bias forces once per period and
  advances the stick-slip axes with the plant's own numba kernel
  (:func:`rcm_kin.dynamics.stick_slip._advance`); the smooth plant is its RK4 period map.
- Controllers: :func:`loop_law` turns each readable controller into arrays (kind, gains, the
  gain tables on their grid); the firmware's clamped bilinear rule and the conditional
  anti-windup are written out in the same order as the reference.
- Encoder noise is drawn in Python from the run's generator in the reference's order (3 values
  for the first reading, then 3 per tick), so both paths see the same counts.

Where the model functions cannot be compiled (no C compiler, unwritable cache),
:func:`compiled_drive_train` and :func:`compiled_smooth` return None and say so once on stderr;
:mod:`rcm_kin.simulation.experiments` then runs the per-tick Python fast path
(:mod:`rcm_kin.simulation.fast_path`).

numba's on-disk cache keys a function on its own file only; the kernel below inlines the
stick-slip kernels, so it is built in a closure over a hash of ``stick_slip.py`` (numba keys
cached closures on their cell contents): a changed drive-train model compiles anew. Constants of
other modules (``hardware.INSERTION_KP``, ``loop.FIRMWARE_SCALE``) are kernel arguments, never
frozen into the cached machine code.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import sys
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numba
import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic
from tqdm import tqdm

from rcm_kin import thesis as thesis_reference
from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG
from rcm_kin.dynamics import stick_slip
from rcm_kin.dynamics.stick_slip import _advance, substep_count
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import INSERTION_KP
from rcm_kin.simulation.controllers import (Controller, Hold, PController, PIDController, StateFeedbackController,
                                            ThesisController)
from rcm_kin.simulation.fast_path import stacked
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import FIRMWARE_SCALE, SimulationResult, check_run, diverged, firmware_units
from rcm_kin.simulation.plant import DriveTrainPlant
from rcm_kin.simulation.references import Reference
from rcm_kin.symbolic.compiled import loaded_library

P, PID, STATE_FEEDBACK, THESIS = 0, 1, 2, 3        # LoopLaw.kind
DRIVE_TRAIN, SMOOTH = 0, 1                         # CompiledPlant.kind
CHUNK = 4000                                       # ticks per kernel call (the progress bar's step)


# --- CasADi's C entry point, called by address --------------------------------------------------

@dataclass(frozen=True)
class CFunction:
    """The C entry point of a compiled CasADi function with dense inputs and outputs:
    ``int f(const double** arg, double** res, long long* iw, double* w, int mem)``."""

    address: int                 # of f in the loaded library
    work: np.ndarray             # (4,) int64: sizes of arg, res, iw, w (CasADi's f_work)
    library: ctypes.CDLL         # keeps the library loaded while the address is used


def c_function(fn: ca.Function) -> CFunction | None:
    """``fn``'s C entry point (compiled, cached and loaded by :func:`loaded_library`), or None when it
    cannot be compiled. Raises :class:`RcmKinError` for sparse inputs or outputs."""
    for i in range(fn.n_in()):
        if not fn.sparsity_in(i).is_dense():
            raise RcmKinError(f"{fn.name()}: the compiled loop needs dense inputs")
    for i in range(fn.n_out()):
        if not fn.sparsity_out(i).is_dense():
            raise RcmKinError(f"{fn.name()}: the compiled loop needs dense outputs")
    found = loaded_library(fn)
    if found is None:
        return None
    path, library = found
    int_size = getattr(library, f"{fn.name()}_casadi_int_size")
    if int_size() != ctypes.sizeof(ctypes.c_longlong):
        raise RcmKinError(f"{fn.name()}: CasADi's integer type is not 64 bits in {path}")
    sizes = [ctypes.c_longlong() for _ in range(4)]
    getattr(library, f"{fn.name()}_work")(*(ctypes.byref(s) for s in sizes))
    address = ctypes.cast(getattr(library, fn.name()), ctypes.c_void_p).value
    return CFunction(address, np.array([s.value for s in sizes], dtype=np.int64), library)


@intrinsic
def _call_c(typingctx, address, arg, res, iw, w):
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


# --- the plants with their model functions compiled ---------------------------------------------

@dataclass(frozen=True)
class CompiledPlant:
    """A plant of the loop with its CasADi functions as C entry points, ``step`` and ``initial``
    as the plant's (same state layout):

    - ``DRIVE_TRAIN``: :class:`DriveTrainPlant` (x (15,)); functions: mass matrix ``q -> M``
      (3 x 3, column-major), bias ``(q, v) -> h`` (3,); the stick-slip axes by ``_advance``;
    - ``SMOOTH``: the smooth model's period map ``(x, u) -> x(T)`` (x (6,),
      :func:`rcm_kin.simulation.plant.period_map`)."""

    kind: int                    # DRIVE_TRAIN or SMOOTH
    functions: tuple[CFunction, ...]
    period: float                # s
    drive_train: DriveTrainPlant | None = None
    substeps: int = 1            # stick-slip substeps per period (stick_slip.substep_count)

    def initial(self, position) -> np.ndarray:
        if self.drive_train is not None:
            return self.drive_train.initial(position)
        return np.r_[np.asarray(position, dtype=float), np.zeros(3)]

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        state = np.array(x, dtype=float)
        _plant_steps(state, np.asarray(u, dtype=float).reshape(1, 3), *self.kernel_arguments)
        return state

    @functools.cached_property
    def kernel_arguments(self) -> tuple:
        """kind, addresses (3,), work sizes (3, 4), friction (3, n), input gain, damping, reflected
        inertia (3,) (zeros for the smooth plant), period, substeps: made once per plant."""
        addresses, work = np.zeros(3, dtype=np.int64), np.zeros((3, 4), dtype=np.int64)
        for i, fn in enumerate(self.functions):
            addresses[i], work[i] = fn.address, fn.work
        if self.drive_train is None:
            friction, gain, damping, inertia = np.zeros((3, 1)), np.zeros(3), np.zeros(3), np.zeros(3)
        else:
            d = self.drive_train.model.drive
            friction, gain, damping, inertia = (np.ascontiguousarray(a, dtype=float) for a in
                                                (self.drive_train.friction, d.input_gain, d.damping,
                                                 d.reflected_inertia))
        return self.kind, addresses, work, friction, gain, damping, inertia, float(self.period), self.substeps


@functools.cache
def _warn_fallback(reason: str) -> None:
    print(f"warning: {reason}: the closed loop runs tick by tick in Python (the fast path), slower",
          file=sys.stderr)


def compiled_drive_train(plant: DriveTrainPlant) -> CompiledPlant | None:
    """``plant`` with its rigid-body functions compiled to C, or None (one line on stderr) when
    they cannot be."""
    if plant.model.mass_matrix.size_out(0) != (3, 3) or plant.model.bias.size_out(0) != (3, 1):
        raise RcmKinError("the compiled loop is written for three driven joints")
    mass_matrix, bias = c_function(plant.model.mass_matrix), c_function(plant.model.bias)
    if mass_matrix is None or bias is None:
        _warn_fallback("no compiled model functions")
        return None
    return CompiledPlant(DRIVE_TRAIN, (mass_matrix, bias), plant.period, plant, substep_count(plant.period))


def compiled_smooth(period_map: ca.Function, period: float) -> CompiledPlant | None:
    """The smooth model's ``period_map`` ``(x (6,), u (3,)) -> x(T)`` (``period`` s) compiled to C,
    or None (one line on stderr) when it cannot be."""
    if period_map.size_in(0) != (6, 1) or period_map.size_in(1) != (3, 1) or period_map.size_out(0) != (6, 1):
        raise RcmKinError("the compiled loop is written for three driven joints: (x (6,), u (3,)) -> x (6,)")
    fn = c_function(period_map)
    if fn is None:
        _warn_fallback("no compiled model functions")
        return None
    return CompiledPlant(SMOOTH, (fn,), period)


# --- controllers as arrays ----------------------------------------------------------------------

@dataclass(frozen=True)
class LoopLaw:
    """A controller of :mod:`rcm_kin.simulation.controllers` as the kernel takes it."""

    kind: int                    # P, PID, STATE_FEEDBACK, THESIS
    flags: np.ndarray            # (4,) bool: scheduled, gravity, track_velocity, friction (state feedback)
    gains: np.ndarray            # (6,): P kp (2); PID kp (2), ki (2), kd (2)
    roll_deg: np.ndarray         # (nr,) table grid (2 zeros when unused)
    pitch_deg: np.ndarray        # (np,)
    table: np.ndarray            # (np, nr, 7): k_roll (2), k_pitch (3), ff_pitch (2) (ff zero: thesis)
    hold: np.ndarray             # (np, nr, 2): u_hold (zeros without gravity)
    friction: np.ndarray         # (3,): feedforward amplitude (roll, pitch; counts), ramp (deg/s)
    memory: np.ndarray           # the controller's initial memory


def loop_law(controller: Controller, hold: Hold | None = None) -> LoopLaw | None:
    """``controller`` as a :class:`LoopLaw` with the memory ``initial_memory(hold)``, or None for a
    controller the kernel does not know (it then runs in Python)."""
    no_grid, no_table, no_hold = np.zeros(2), np.zeros((2, 2, 7)), np.zeros((2, 2, 2))
    off, gains = np.zeros(4, dtype=bool), np.zeros(6)
    if type(controller) not in (PController, PIDController, ThesisController, StateFeedbackController):
        return None
    memory = np.asarray(controller.initial_memory(hold), dtype=float)
    if type(controller) is PController:
        gains[:2] = controller.kp
        return LoopLaw(P, off, gains, no_grid, no_grid, no_table, no_hold, np.zeros(3), memory)
    if type(controller) is PIDController:
        gains[:] = [*controller.kp, *controller.ki, *controller.kd]
        return LoopLaw(PID, off, gains, no_grid, no_grid, no_table, no_hold, np.zeros(3), memory)
    if type(controller) is ThesisController:
        table = stacked(THESIS_ROLL_DEG, THESIS_PITCH_DEG, thesis_reference.K_ROLL, thesis_reference.K_PITCH,
                        np.zeros(thesis_reference.K_ROLL.shape[:2] + (2,)))
        return LoopLaw(THESIS, off, gains, np.array(table.roll), np.array(table.pitch), table.values,
                       np.zeros(table.values.shape[:2] + (2,)), np.zeros(3), memory)
    s = controller.schedule
    if controller.friction and s.friction is None:
        raise RcmKinError("the friction-compensated controller needs a schedule with its friction feedforward")
    table = stacked(s.roll_deg, s.pitch_deg, s.k_roll, s.k_pitch, s.ff_pitch)
    hold = np.asarray(s.u_hold, dtype=float) if controller.gravity else np.zeros(table.values.shape[:2] + (2,))
    friction = np.r_[s.friction.pwm, s.friction.ramp_deg_s] if controller.friction else np.zeros(3)
    flags = np.array([controller.scheduled, controller.gravity, controller.track_velocity, controller.friction])
    return LoopLaw(STATE_FEEDBACK, flags, gains, np.array(table.roll), np.array(table.pitch), table.values,
                   np.ascontiguousarray(hold), friction.astype(float), memory)


# --- the kernel ---------------------------------------------------------------------------------

@numba.njit(cache=True)
def _cell(grid, x):
    """``gain_schedule._cell``: the cell index (largest i with grid[i] <= x, at most n - 2) and x clamped."""
    x = min(max(x, grid[0]), grid[-1])
    i = 0
    while i + 2 < grid.size and grid[i + 1] <= x:
        i += 1
    return i, x


@numba.njit(cache=True)
def _bilinear(roll_grid, pitch_grid, table, roll, pitch, out):
    """``gain_schedule.bilinear`` of every value of ``table[pitch][roll]`` into ``out``."""
    i, r = _cell(roll_grid, roll)
    j, p = _cell(pitch_grid, pitch)
    fr = (r - roll_grid[i]) / (roll_grid[i + 1] - roll_grid[i])
    fp = (p - pitch_grid[j]) / (pitch_grid[j + 1] - pitch_grid[j])
    for m in range(out.size):
        low = table[j, i, m] + (table[j, i + 1, m] - table[j, i, m]) * fr
        high = table[j + 1, i, m] + (table[j + 1, i + 1, m] - table[j + 1, i, m]) * fr
        out[m] = low + (high - low) * fp


@numba.njit(cache=True)
def _law(pid, with_feedforward, c1, c2, k_integral, integral, feedforward):
    """The integral law of the PID ``-(Kp e + Ki E + Kd de)`` (c1 = Kp e, c2 = Kd de) or of the
    pitch ``-(Kp e + Kd v + Ki E) [+ feedforward]`` (c1 = Kp e, c2 = Kd v), at ``E = integral``."""
    if pid:
        return -(c1 + k_integral * integral + c2)
    u = -(c1 + c2 + k_integral * integral)
    return u + feedforward if with_feedforward else u


@numba.njit(cache=True)
def _conditional_integral(integral, error, period, limit, pid, with_feedforward, c1, c2, k_integral, feedforward):
    """``controllers._conditional_integral`` on :func:`_law`: (u, integral)."""
    candidate = integral + error * period
    u = _law(pid, with_feedforward, c1, c2, k_integral, candidate, feedforward)
    held = _law(pid, with_feedforward, c1, c2, k_integral, integral, feedforward)
    if abs(u) > limit and np.sign(u) == np.sign(u - held):
        return held, integral
    return u, candidate


@numba.njit(cache=True)
def _command(kind, flags, gains, roll_grid, pitch_grid, table, hold_table, friction, memory, measured, velocity,
             reference, rdot, racc, period, limit, insertion_kp, scratch, command):
    """The controller's ``command`` (firmware units, before saturation) into ``command``; ``memory``
    updated in place; the insertion by its P loop (``insertion_kp`` counts/m)."""
    e0, e1 = reference[0] - measured[0], reference[1] - measured[1]
    if kind == P:
        command[0] = -gains[0] * e0
        command[1] = -gains[1] * e1
    elif kind == PID:                                    # memory: integrals, previous errors
        e = (e0, e1)
        for i in range(2):
            de = 0.0 if np.isnan(memory[2 + i]) else (e[i] - memory[2 + i]) / period
            command[i], memory[i] = _conditional_integral(memory[i], e[i], period, limit[i], True, False,
                                                          gains[i] * e[i], gains[4 + i] * de, gains[2 + i], 0.0)
        memory[2], memory[3] = e0, e1
    else:                                                # STATE_FEEDBACK or THESIS
        scheduled, gravity, track, compensate = flags[0], flags[1], flags[2], flags[3]
        at0, at1 = (measured[0], measured[1]) if (scheduled or kind == THESIS) else (0.0, 0.0)
        k = scratch[:7]
        _bilinear(roll_grid, pitch_grid, table, at0, at1, k)
        v0, v1 = velocity[0], velocity[1]
        if kind == THESIS:
            command[0] = -(k[0] * e0 + k[1] * v0)
            command[1], memory[0] = _conditional_integral(memory[0], e1, period, limit[1], False, False,
                                                          k[2] * e1, k[3] * v1, k[4], 0.0)
        else:
            if track:
                v0, v1 = v0 - rdot[0], v1 - rdot[1]
            hold = scratch[7:9]
            if gravity:
                _bilinear(roll_grid, pitch_grid, hold_table, reference[0], reference[1], hold)
            else:
                hold[0], hold[1] = 0.0, 0.0
            if compensate:
                hold[0] = hold[0] + -friction[0] * np.tanh(rdot[0] / friction[2])
                hold[1] = hold[1] + -friction[1] * np.tanh(rdot[1] / friction[2])
            command[0] = -(k[0] * e0 + k[1] * v0) + hold[0]
            feedforward = k[5] * rdot[1] + k[6] * racc[1] + hold[1]
            command[1], memory[0] = _conditional_integral(memory[0], e1, period, limit[1], False, True,
                                                          k[2] * e1, k[3] * v1, k[4], feedforward)
    command[2] = insertion_kp * (reference[2] - measured[2])


@numba.njit(cache=True)
def read_encoders(true, count, noise, out):
    """``firmware.encoder_reading`` with the noise counts already drawn and rounded (``noise``
    (3,) counts, zeros without noise): whole counts of ``true`` (firmware units) into ``out``."""
    for j in range(3):
        if count[j] == 0.0:
            out[j] = true[j]
        else:
            out[j] = (np.round(true[j] / count[j]) + noise[j]) * count[j]


def _stick_slip_source_hash() -> str:
    return hashlib.sha256(Path(stick_slip.__file__).read_bytes()).hexdigest()


def _keyed_plant_step(physics: str):
    """The plant step compiled in a closure over ``physics`` (the stick-slip source's hash), so
    numba's cache keys it on the drive-train model it inlines."""

    @numba.njit(cache=True)
    def plant_step(kind, x, u, addresses, friction, input_gain, damping, reflected_inertia, period, substeps,
                   buffers, arg, res, iw, w, axis):
        """One period of the plant (``DriveTrainPlant.step`` or the smooth period map) under
        ``u`` (3,), x advanced in place."""
        if len(physics) == 0:          # the closure's key (never empty)
            return
        if kind == SMOOTH:             # x (6,) -> period_map(x, u)
            out = buffers[18:24]
            arg[0], arg[1], res[0] = x.ctypes.data, u.ctypes.data, out.ctypes.data
            _call_c(addresses[0], arg.ctypes.data, res.ctypes.data, iw.ctypes.data, w.ctypes.data)
            x[:] = out
            return
        q, v, M, h = buffers[0:3], buffers[3:6], buffers[6:15], buffers[15:18]
        for i in range(3):
            q[i], v[i] = x[6 + i], x[9 + i]
        arg[0], res[0] = q.ctypes.data, M.ctypes.data
        _call_c(addresses[0], arg.ctypes.data, res.ctypes.data, iw.ctypes.data, w.ctypes.data)
        arg[0], arg[1], res[0] = q.ctypes.data, v.ctypes.data, h.ctypes.data
        _call_c(addresses[1], arg.ctypes.data, res.ctypes.data, iw.ctypes.data, w.ctypes.data)
        for i in range(3):
            for r in range(5):
                axis[r] = x[3 * r + i]
            _advance(friction[i], input_gain[i], damping[i], reflected_inertia[i], h[i],
                     M[4 * i] - reflected_inertia[i], u[i], axis, period, substeps)
            for r in range(5):
                x[3 * r + i] = axis[r]

    return plant_step


_PHYSICS = _stick_slip_source_hash()
_plant_step = _keyed_plant_step(_PHYSICS)


@numba.njit(cache=True)
def _work_buffers(work):
    """Buffers of the plant step: q, v, M, h, x(T) values, CasADi's arg, res, iw and w (``work``
    (k, 4): each function's sizes), one axis state."""
    size = np.full(4, 2, dtype=np.int64)
    for row in work:
        size = np.maximum(size, row)
    return (np.zeros(24), np.zeros(size[0], dtype=np.int64), np.zeros(size[1], dtype=np.int64),
            np.zeros(size[2], dtype=np.int64), np.zeros(size[3]), np.zeros(5))


def _keyed_loops(physics: str):
    """The loops over :data:`_plant_step`, keyed like it (see :func:`_keyed_plant_step`)."""

    @numba.njit(cache=True)
    def plant_steps(x, u, kind, addresses, work, friction, input_gain, damping, reflected_inertia, period,
                    substeps):
        """One plant step per row of ``u`` (n, 3), x in place."""
        if len(physics) == 0:
            return
        buffers, arg, res, iw, w, axis = _work_buffers(work)
        for k in range(u.shape[0]):
            _plant_step(kind, x, u[k], addresses, friction, input_gain, damping, reflected_inertia, period,
                        substeps, buffers, arg, res, iw, w, axis)

    @numba.njit(cache=True)
    def run(first, stop, x, previous, filtered, memory, ref_fw, vel_fw, acc_fw, noise, period, limit, count,
            roll_filter, quantise, scale, insertion_kp, kind, flags, gains, roll_grid, pitch_grid, table,
            hold_table, friction_ff, plant_kind, addresses, work, friction, input_gain, damping, reflected_inertia,
            substeps, log_measured, log_position, log_command, log_pwm):
        """Ticks ``first .. stop - 1`` of ``loop.simulate`` (k < 0: settling); the loop's state
        (x, previous, filtered, memory) advanced in place, the ticks k >= 0 logged; ``scale`` (3,):
        joint units to firmware units (``loop.FIRMWARE_SCALE``), ``insertion_kp``: the insertion's
        P gain (counts/m). Returns the tick where the state stopped being finite, or ``stop``."""
        if len(physics) == 0:
            return first
        buffers, arg, res, iw, w, axis = _work_buffers(work)
        true, measured, command, u = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
        rdot, racc, scratch = np.zeros(3), np.zeros(3), np.zeros(9)
        n_settle = noise.shape[0] - ref_fw.shape[0] - 1
        for k in range(first, stop):
            i = max(k, 0)
            moving = k >= 0
            for j in range(3):
                true[j] = x[j] * scale[j]
            read_encoders(true, count, noise[k + n_settle + 1], measured)
            raw0 = (measured[0] - previous[0]) / period
            filtered[0] = roll_filter * filtered[0] + (1 - roll_filter) * raw0
            filtered[1] = (measured[1] - previous[1]) / period
            filtered[2] = (measured[2] - previous[2]) / period
            for j in range(3):
                rdot[j] = vel_fw[i, j] if moving else 0.0
                racc[j] = acc_fw[i, j] if moving else 0.0
            _command(kind, flags, gains, roll_grid, pitch_grid, table, hold_table, friction_ff, memory, measured,
                     filtered, ref_fw[i], rdot, racc, period, limit, insertion_kp, scratch, command)
            for j in range(3):
                u[j] = min(max(command[j], -limit[j]), limit[j])
                if quantise:
                    u[j] = np.trunc(u[j])
            if moving:
                for j in range(3):
                    log_measured[k, j], log_position[k, j] = measured[j], true[j]
                    log_command[k, j], log_pwm[k, j] = command[j], u[j]
            _plant_step(plant_kind, x, u, addresses, friction, input_gain, damping, reflected_inertia, period,
                        substeps, buffers, arg, res, iw, w, axis)
            for j in range(x.size):
                if not np.isfinite(x[j]):
                    return k
            for j in range(3):
                previous[j] = measured[j]
        return stop

    return plant_steps, run


_plant_steps, _run = _keyed_loops(_PHYSICS)


def simulate_compiled(plant: CompiledPlant, law: LoopLaw, name: str, reference: Reference,
                      settings: FirmwareSettings | None = None, seed: int = 0, settle: float = 1.0,
                      progress: bool = False) -> SimulationResult:
    """:func:`rcm_kin.simulation.loop.simulate` of the controller ``law`` (called ``name``) on
    ``plant``, from rest at the first reference pose, in the compiled kernel: the same result."""
    settings = settings or FirmwareSettings()
    check_run(reference, settings, settle)
    if not np.isclose(plant.period, settings.period, rtol=1e-12):
        raise RcmKinError(f"the plant steps {plant.period} s, the controller {settings.period} s")
    rng = np.random.default_rng(seed)
    n_settle, n = int(round(settle / settings.period)), reference.time.size
    noise = np.zeros((n_settle + n + 1, 3))
    if settings.noise_counts:       # the reference's draws in its order, 3 per reading (one bulk draw fills
        noise = np.round(rng.normal(0.0, settings.noise_counts, noise.shape))   # row by row: tests hold it)
    x = plant.initial(reference.position[0])
    ref_fw, vel_fw, acc_fw = (np.ascontiguousarray(firmware_units(a)) for a in
                              (reference.position, reference.velocity, reference.acceleration))
    count = np.asarray(settings.encoder_count, dtype=float)
    limit = np.asarray(settings.pwm_limit, dtype=float)
    previous = np.empty(3)
    read_encoders(firmware_units(x[:3]), count, noise[0], previous)
    filtered, memory = np.zeros(3), np.array(law.memory, dtype=float)
    logs = [np.empty((n, 3)) for _ in range(4)]
    ticks = tqdm(total=n_settle + n, desc=f"simulate {name}", unit="tick", disable=not progress, leave=False)
    with ticks:
        for first in range(-n_settle, n, CHUNK):
            stop = min(first + CHUNK, n)
            end = _run(first, stop, x, previous, filtered, memory, ref_fw, vel_fw, acc_fw, noise, settings.period,
                       limit, count, settings.roll_filter, settings.quantise_pwm, FIRMWARE_SCALE, INSERTION_KP,
                       law.kind, law.flags, law.gains,
                       law.roll_deg, law.pitch_deg, law.table, law.hold, law.friction,
                       *plant.kernel_arguments[:-2], plant.substeps, *logs)   # the period given above
            if end != stop:
                raise diverged(end, settings.period, name)
            ticks.update(stop - first)
    return SimulationResult(name, reference.time, ref_fw, *logs, settings)

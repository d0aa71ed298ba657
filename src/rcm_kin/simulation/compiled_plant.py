"""The plants of the loop with their CasADi functions compiled to C, as the kernel takes them.

:class:`CompiledPlant` is the kernel form of a plant (``Plant.kernel_plant()``,
:mod:`rcm_kin.simulation.plant`): the CasADi functions compiled to C
(:func:`rcm_kin.symbolic.compiled.loaded_library`) and called from the kernel through their C
entry point (CasADi's ``f(arg, res, iw, w, mem)``) by address: the same expression graphs, no
table. The drive-train plant evaluates its mass matrix and bias forces once per period and
advances the stick-slip axes with the kernel's C twin of the model's numba kernel; the smooth
plant is its RK4 period map. Where the functions or the kernel cannot be compiled (no C compiler,
unwritable cache), :func:`compiled_drive_train` and :func:`compiled_smooth` return None.
"""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from rcm_kin.dynamics.axis_friction import substep_count
from rcm_kin.errors import RcmKinError
from rcm_kin.simulation.kernel import DRIVE_TRAIN, SMOOTH, available, plant_steps
from rcm_kin.symbolic.compiled import loaded_library

if TYPE_CHECKING:
    from rcm_kin.simulation.plant import DriveTrainPlant


@dataclass(frozen=True)
class CFunction:
    """The C entry point of a compiled CasADi function with dense inputs and outputs:
    ``int f(const double** arg, double** res, long long* iw, double* w, int mem)``."""

    address: int                 # of f in the loaded library
    work: np.ndarray             # (4,) int64: sizes of arg, res, iw, w (CasADi's f_work)
    library: ctypes.CDLL         # keeps the library loaded while the address is used
    inputs: tuple[int, ...] = ()     # values of each input (dense)
    outputs: tuple[int, ...] = ()    # values of each output (dense)


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
    return CFunction(address, np.array([s.value for s in sizes], dtype=np.int64), library,
                     tuple(fn.nnz_in(i) for i in range(fn.n_in())), tuple(fn.nnz_out(i) for i in range(fn.n_out())))


PLANT_SHAPES = {DRIVE_TRAIN: (((3,), (9,)), ((3, 3), (3,))),     # kind -> per function: (inputs, outputs)
                SMOOTH: (((6, 3), (6,)),)}                       # (before any parameters input)


@dataclass(frozen=True)
class CompiledPlant:
    """A plant of the loop with its CasADi functions as C entry points, ``step`` and ``initial``
    as the plant's (same state layout):

    - ``DRIVE_TRAIN``: :class:`~rcm_kin.simulation.plant.DriveTrainPlant` (x (3 STATE_SIZE,)); functions:
      mass matrix ``q -> M`` (3 x 3, column-major), bias ``(q, v) -> h`` (3,); the stick-slip axes
      by the kernel's twin of :func:`rcm_kin.dynamics.stick_slip.advance`;
    - ``SMOOTH``: the smooth model's period map ``(x, u) -> x(T)`` (x (6,),
      :func:`rcm_kin.simulation.plant.period_map`)."""

    kind: int                    # DRIVE_TRAIN or SMOOTH
    functions: tuple[CFunction, ...]
    period: float                # s
    drive_train: DriveTrainPlant | None = None
    substeps: int = 1            # stick-slip substeps per period (stick_slip.substep_count)
    parameters: np.ndarray = field(default_factory=lambda: np.zeros(0))   # of parametric functions (their
                                 # last input, :mod:`rcm_kin.dynamics.parametric`); empty: none

    def __post_init__(self):
        """The C kernel reads what the functions' shapes say without bounds checks: refuse here a
        plant whose functions, parameters or drive train do not fit its kind."""
        shapes = PLANT_SHAPES.get(self.kind)
        if shapes is None or len(self.functions) != len(shapes) or not all(
                isinstance(f, CFunction) and f.address for f in self.functions):
            raise RcmKinError(f"a compiled plant of kind {self.kind} needs {len(shapes or ())} C functions "
                              "(c_function)", parameter="functions")
        parameters = np.asarray(self.parameters, dtype=float)
        for fn, (inputs, outputs) in zip(self.functions, shapes):
            extra = fn.inputs[len(inputs):]
            if fn.inputs[:len(inputs)] != inputs or fn.outputs != outputs or len(extra) > 1:
                raise RcmKinError(f"a compiled plant's function takes {inputs} values and gives {outputs}, got "
                                  f"{fn.inputs} and {fn.outputs}", parameter="functions")
            if parameters.shape != ((extra[0],) if extra else (0,)):
                raise RcmKinError(f"the plant's functions take {extra[0] if extra else 0} parameters, got "
                                  f"{parameters.size}", parameter="parameters")
        if (self.kind == DRIVE_TRAIN) != (self.drive_train is not None):
            raise RcmKinError("a drive-train plant, and only one, carries its DriveTrainPlant", parameter="drive_train")

    def initial(self, position) -> np.ndarray:
        if self.drive_train is not None:
            return self.drive_train.initial(position)
        return np.r_[np.asarray(position, dtype=float), np.zeros(3)]

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        state = np.array(x, dtype=float)
        plant_steps(state, np.asarray(u, dtype=float).reshape(1, 3), *self.kernel_arguments)
        return state

    def kernel_plant(self) -> CompiledPlant:
        """Its own kernel form (the :class:`~rcm_kin.simulation.plant.Plant` protocol)."""
        return self

    @functools.cached_property
    def kernel_arguments(self) -> tuple:
        """kind, addresses (3,), work sizes (3, 4), parameters, friction (3, n), input gain, damping,
        reflected inertia (3,) (zeros for the smooth plant), period, substeps: made once per plant."""
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
        parameters = np.ascontiguousarray(self.parameters, dtype=float)
        return (self.kind, addresses, work, parameters, friction, gain, damping, inertia, float(self.period),
                self.substeps)


def compiled_drive_train(plant: DriveTrainPlant) -> CompiledPlant | None:
    """``plant`` with its rigid-body functions compiled to C, or None when they or the kernel
    (:mod:`rcm_kin.simulation.kernel`) cannot be (the compiled functions say so once, with a
    warning: :mod:`rcm_kin.symbolic.compiled`)."""
    if plant.model.mass_matrix.size_out(0) != (3, 3) or plant.model.bias.size_out(0) != (3, 1):
        raise RcmKinError("the compiled loop is written for three driven joints")
    mass_matrix, bias = c_function(plant.model.mass_matrix), c_function(plant.model.bias)
    if mass_matrix is None or bias is None or not available():
        return None
    return CompiledPlant(DRIVE_TRAIN, (mass_matrix, bias), plant.period, plant, substep_count(plant.period))


def compiled_smooth(period_map: ca.Function, period: float) -> CompiledPlant | None:
    """The smooth model's ``period_map`` ``(x (6,), u (3,)) -> x(T)`` (``period`` s) compiled to C,
    or None when it cannot be."""
    if period_map.size_in(0) != (6, 1) or period_map.size_in(1) != (3, 1) or period_map.size_out(0) != (6, 1):
        raise RcmKinError("the compiled loop is written for three driven joints: (x (6,), u (3,)) -> x (6,)")
    fn = c_function(period_map)
    return None if fn is None or not available() else CompiledPlant(SMOOTH, (fn,), period)

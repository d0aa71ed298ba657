"""A compiled CasADi function at many points in one C loop, written in place.

:func:`compiled_points` compiles a function like :func:`~rcm_kin.symbolic.compiled.compiled` and
returns a :class:`CompiledPoints`: called with row-per-point arrays it evaluates every point by
one C loop (a small driver library, built once per machine and cached beside the compiled
functions) calling the compiled function's own C entry point, into the caller's output arrays.
The numbers are those of the compiled function, bit for bit (the same machine code); what goes
is the per-point work of a CasADi ``map`` over an external function (about a third of the time
of a small function) and building a map of N points (about as long as evaluating it).

Where the function runs interpreted (no C compiler) or the driver is not built, the points go
through CasADi maps (:func:`~rcm_kin.symbolic.compiled.map_points_into`), the same numbers.
The C call releases the GIL.
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Sequence

import casadi as ca
import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.symbolic.compiled import (
    COMPILE_FLAGS,
    build_library,
    cache_key,
    check_point_arrays,
    compiled_and_library,
    compiler_command,
    load_library,
    map_points_into,
)

DRIVER_NAME = "rcm_points"
DRIVER = r"""
typedef long long int casadi_int;
typedef int (*casadi_function)(const double **arg, double **res, casadi_int *iw, double *w, int mem);

/* f (CasADi's C interface) at n points: input i of point k at x[i] + k * nx[i], output i at
 * y[i] + k * ny[i]; arg, res, iw, w: f's work arrays (f_work sizes). 0, or 1 if f failed. */
int rcm_points(void *f, casadi_int n, casadi_int n_in, const double **x, const casadi_int *nx,
               casadi_int n_out, double **y, const casadi_int *ny,
               const double **arg, double **res, casadi_int *iw, double *w)
{
    casadi_function fn = (casadi_function) f;
    for (casadi_int k = 0; k < n; ++k) {
        for (casadi_int i = 0; i < n_in; ++i) {
            arg[i] = x[i] + k * nx[i];
        }
        for (casadi_int i = 0; i < n_out; ++i) {
            res[i] = y[i] + k * ny[i];
        }
        if (fn(arg, res, iw, w, 0)) {
            return 1;
        }
    }
    return 0;
}
"""


class CompiledPoints:
    """A compiled function evaluated at many points: ``points(args, outs)`` writes the outputs of
    every point into ``outs`` (see :meth:`__call__`). :attr:`function` is the compiled CasADi
    function itself (for single calls and everything else)."""

    def __init__(self, fn: ca.Function):
        self.function, library = compiled_and_library(fn)
        self._entry = None if library is None else _entry(library, fn.name(), fn)

    def __call__(self, args: Sequence[np.ndarray], outs: Sequence[np.ndarray]) -> None:
        """Evaluate at N points: ``args`` (N, nnz_in_i) and ``outs`` (N, nnz_out_i) C-contiguous
        float64 arrays, one row per point (dense inputs; the outputs' nonzeros, column-major)."""
        fn = self.function
        if self._entry is None:
            map_points_into(fn, args, outs)
            return
        n = check_point_arrays(fn, args, outs)
        address, driver, sizes = self._entry
        pointers = (ctypes.c_void_p * max(1, len(args)))(*[a.ctypes.data for a in args])
        results = (ctypes.c_void_p * max(1, len(outs)))(*[o.ctypes.data for o in outs])
        width_in = (ctypes.c_longlong * max(1, len(args)))(*[a.shape[1] for a in args])
        width_out = (ctypes.c_longlong * max(1, len(outs)))(*[o.shape[1] for o in outs])
        sz_arg, sz_res, sz_iw, sz_w = sizes
        work = (ctypes.c_void_p * sz_arg)(), (ctypes.c_void_p * sz_res)(), (ctypes.c_longlong * sz_iw)(), \
            (ctypes.c_double * sz_w)()
        if driver(address, n, len(args), pointers, width_in, len(outs), results, width_out, *work):
            raise RcmKinError(f"the compiled {fn.name()} failed at a point")


def compiled_points(fn: ca.Function) -> CompiledPoints:
    """``fn`` compiled (:func:`~rcm_kin.symbolic.compiled.compiled`) and evaluated at many points
    in one C loop: a :class:`CompiledPoints`."""
    return CompiledPoints(fn)


def _entry(library: ctypes.CDLL, name: str, fn: ca.Function):
    """(address of ``name``, the driver, work sizes) of a compiled function's library; None when the
    driver is not built or the library is not CasADi's C interface with 8-byte integers."""
    driver = _driver(tuple(compiler_command()))
    try:
        if driver is None or library[f"{name}_casadi_int_size"]() != 8:
            return None
        work = library[f"{name}_work"]
    except AttributeError:
        return None
    sizes = [ctypes.c_longlong() for _ in range(4)]
    work.argtypes = [ctypes.POINTER(ctypes.c_longlong)] * 4
    if work(*sizes) != 0:
        return None
    sz_arg, sz_res, sz_iw, sz_w = (max(1, s.value) for s in sizes)
    if sz_arg < fn.n_in() or sz_res < fn.n_out():
        return None
    return ctypes.cast(library[name], ctypes.c_void_p).value, driver, (sz_arg, sz_res, sz_iw, sz_w)


@functools.cache
def _driver(command: tuple[str, ...]):
    """The driver's C function (ctypes), built and loaded once per compiler command; None when it
    cannot be built (the maps of :func:`map_points_into` do the work then)."""
    def build():
        return build_library(DRIVER_NAME, cache_key(DRIVER, " ".join(command + COMPILE_FLAGS)), DRIVER,
                             list(command))
    try:
        found = load_library(build(), build, DRIVER_NAME)
    except (OSError, RcmKinError):
        return None
    if found is None:
        return None
    function = found[1][DRIVER_NAME]
    pointer, integers = ctypes.c_void_p, ctypes.POINTER(ctypes.c_longlong)
    function.argtypes = (pointer, ctypes.c_longlong, ctypes.c_longlong, pointer, integers, ctypes.c_longlong,
                         pointer, integers, pointer, pointer, pointer, pointer)
    function.restype = ctypes.c_int
    return function

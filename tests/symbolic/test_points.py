"""Many points of a compiled function: the C loop (symbolic.points) and the kept CasADi maps
(compiled.map_points_into) give the compiled function's own numbers bit for bit, in place."""

from __future__ import annotations

import importlib
import os
import shutil
import warnings

import casadi as ca
import numpy as np
import pytest

from rcm_kin.errors import RcmKinError
from rcm_kin.symbolic.points import compiled_points

comp = importlib.import_module("rcm_kin.symbolic.compiled")

needs_compiler = pytest.mark.skipif(shutil.which(os.environ.get("CC") or "cc") is None,
                                    reason="no C compiler (CC hidden): the fallback run")


def two_in_two_out() -> ca.Function:
    """A function of two inputs with two dense outputs, transcendental (rounding differs if evaluated
    by other code)."""
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    y = ca.vertcat(ca.sin(x[0]) * ca.cos(x[1]) + p[0] * x[2], ca.exp(-x[2] ** 2) / (1 + p[1] ** 2))
    z = ca.vertcat(x[0] * x[1] * x[2], ca.atan2(x[1], p[0] + 2), ca.sqrt(1 + x[0] ** 2), p[1] - x[0])
    return ca.Function("points_test", [x, p], [y, z], ["x", "p"], ["y", "z"])


def random_points(n, seed=3):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2, 2, (n, 3)), rng.uniform(-1, 1, (n, 2))


def point_by_point(fn, X, P):
    """The reference: one CasADi call per point (the compiled external function, its own entry)."""
    outs = [fn.call([x, p]) for x, p in zip(X, P)]
    return [np.array([np.array(o[i]).ravel() for o in outs]) for i in range(fn.n_out())]


@needs_compiler
@pytest.mark.parametrize("n", [0, 1, 37, 5000])
def test_c_loop_equals_the_compiled_function_point_by_point(n):
    points = compiled_points(two_in_two_out())
    assert points._entry is not None                  # the C loop, not the maps
    X, P = random_points(n)
    Y, Z = np.full((n, 2), np.nan), np.full((n, 4), np.nan)
    points([X, P], [Y, Z])
    if n:
        y, z = point_by_point(points.function, X, P)
        assert Y.tobytes() == y.tobytes() and Z.tobytes() == z.tobytes()
        (y2, z2) = comp.map_points(points.function, X, P)
        assert Y.tobytes() == y2.tobytes() and Z.tobytes() == z2.tobytes()
        # and the interpreted SX function, to rounding
        yi, zi = point_by_point(two_in_two_out(), X[:5], P[:5])
        np.testing.assert_allclose(Y[:5], yi, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(Z[:5], zi, rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize("chunk", [1, 4, 16, 4096])
def test_kept_maps_equal_map_points_with_any_remainder(chunk):
    """37 points: chunks of ``chunk`` and power-of-two remainders, written in place."""
    fn = comp.compiled(two_in_two_out())
    X, P = random_points(37, seed=chunk)
    Y, Z = np.full((37, 2), np.nan), np.full((37, 4), np.nan)
    comp.map_points_into(fn, [X, P], [Y, Z], chunk=chunk)
    y, z = comp.map_points(fn, X, P)
    assert Y.tobytes() == y.tobytes() and Z.tobytes() == z.tobytes()


def test_wrong_arrays_are_one_line_errors():
    fn = two_in_two_out()
    points = compiled_points(fn)
    X, P = random_points(10)
    Y, Z = np.empty((10, 2)), np.empty((10, 4))
    for args, outs, message in (([X], [Y, Z], "takes 2 inputs and gives 2 outputs"),
                                ([X, P[:9]], [Y, Z], r"input 1 needs a C-contiguous float64 array \(10, 2\)"),
                                ([X[:, :2], P], [Y, Z], r"input 0 needs .* \(10, 3\)"),
                                ([np.asfortranarray(X), P], [Y, Z], "input 0 needs a C-contiguous"),
                                ([X, P], [Y.astype(np.float32), Z], "output 0 needs"),
                                ([X, P], [Y, Z[:, :3]], r"output 1 needs .* \(10, 4\)")):
        for call in (lambda: points(args, outs), lambda: comp.map_points_into(fn, args, outs)):
            with pytest.raises(RcmKinError, match=message):
                call()
    with pytest.raises(RcmKinError, match="chunk must be at least 1"):
        comp.map_points_into(fn, [X, P], [Y, Z], chunk=0)


def test_without_a_compiler_the_maps_give_the_same_numbers(monkeypatch):
    fn = two_in_two_out()
    X, P = random_points(23)
    monkeypatch.setenv("CC", "no-such-compiler-rcm-kin")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        points = compiled_points(fn)
    assert points._entry is None and points.function.is_a("SXFunction")
    Y, Z = np.empty((23, 2)), np.empty((23, 4))
    points([X, P], [Y, Z])
    y, z = comp.map_points(fn, X, P)
    assert Y.tobytes() == y.tobytes() and Z.tobytes() == z.tobytes()

"""The SX Cholesky inverse (symbolic.linalg) against LAPACK's inverse on random symmetric positive
definite matrices, and NaN where a matrix is not positive definite."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from rcm_kin.symbolic.linalg import cholesky_lower, spd_inverse


def spd(n: int, condition: float, rng) -> np.ndarray:
    """A random symmetric positive definite (n, n) of the given condition number."""
    Q, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (Q * np.geomspace(1.0, 1.0 / condition, n)) @ Q.T


@pytest.mark.parametrize("n", [1, 3, 7])
@pytest.mark.parametrize("condition", [1.0, 1e4, 1e8])
def test_inverse_equals_lapack_to_condition_times_rounding(n, condition):
    rng = np.random.default_rng(n)
    M = ca.SX.sym("M", n, n)
    inverse = ca.Function("inv", [M], [spd_inverse(M), ca.vertcat(*[ca.horzcat(*r) for r in cholesky_lower(M)])])
    for _ in range(5):
        A = spd(n, condition, rng)
        got, L = (np.array(x) for x in inverse(A))
        want = np.linalg.inv(A)
        assert np.abs(got - want).max() <= 50 * condition * np.finfo(float).eps * np.abs(want).max()
        np.testing.assert_array_equal(got, got.T)                       # exactly symmetric
        np.testing.assert_allclose(L, np.linalg.cholesky(A), rtol=0, atol=1e-13 * np.sqrt(condition))


def test_structural_zeros_stay_out_and_indefinite_is_nan():
    M = ca.SX.sym("m", 3)
    block = ca.blockcat([[M[0], 0, 0], [0, M[1], M[2]], [0, M[2], M[1]]])
    inverse = spd_inverse(block)
    assert inverse[0, 1].is_zero() and inverse[0, 2].is_zero()        # block diagonal stays so
    f = ca.Function("f", [M], [inverse])
    np.testing.assert_allclose(np.array(f([2.0, 3.0, 1.0])), np.linalg.inv([[2, 0, 0], [0, 3, 1], [0, 1, 3]]),
                               rtol=1e-15, atol=1e-16)
    assert np.isnan(np.array(f([2.0, 1.0, 3.0]))).any()                # eigenvalues 4, -2: not definite

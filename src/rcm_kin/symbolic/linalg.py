"""Small dense linear algebra written out as CasADi SX operations, to be compiled with a model.

:func:`spd_inverse` inverts a symmetric positive definite matrix (a mass matrix) through its
Cholesky factor, as plain arithmetic: no branches, no pivoting, so that the inverse compiles into the
same C function as the matrix and costs a few hundred operations a point instead of a LAPACK call.
"""

from __future__ import annotations

import casadi as ca


def cholesky_lower(M: ca.SX) -> list[list[ca.SX]]:
    """The lower Cholesky factor ``L`` (``M = L L^T``) of a symmetric positive definite ``M`` (n, n),
    as rows of SX scalars (zeros above the diagonal). Reads ``M``'s lower triangle only. A matrix
    that is not positive definite gives NaN (or inf) from the point of the first failing pivot."""
    n = M.size1()
    L = [[ca.SX(0)] * n for _ in range(n)]
    for j in range(n):
        pivot = M[j, j]
        for k in range(j):
            pivot = pivot - L[j][k] * L[j][k]
        L[j][j] = ca.sqrt(pivot)
        for i in range(j + 1, n):
            s = M[i, j]
            for k in range(j):
                s = s - L[i][k] * L[j][k]
            L[i][j] = s / L[j][j]
    return L


def spd_inverse(M: ca.SX) -> ca.SX:
    """``M^-1`` of a symmetric positive definite ``M`` (n, n) as ``L^-T L^-1`` (:func:`cholesky_lower`,
    ``L^-1`` by forward substitution): exactly symmetric, backward stable (errors of the order of
    the condition number times the rounding unit, as LAPACK's LU inverse). Structural zeros of ``M``
    stay out of the operations where the factor keeps them."""
    n = M.size1()
    L = cholesky_lower(M)
    inverse = [[ca.SX(0)] * n for _ in range(n)]          # L^-1, lower triangular
    for c in range(n):
        for i in range(c, n):
            s = ca.SX(1.0 if i == c else 0.0)
            for k in range(c, i):
                s = s - L[i][k] * inverse[k][c]
            inverse[i][c] = s / L[i][i]
    Li = ca.vertcat(*[ca.horzcat(*row) for row in inverse])
    return ca.mtimes(Li.T, Li)

"""Control-barrier-function safety filters for ``xdot = f(x) + G(x) u``.

- :func:`safety_control` is Wieland and Allgower's ``k0`` (thesis eq. 3.6):
  ``k0 = -(LfB + sqrt(LfB^2 + kappa^2 |LgB|^2)) / |LgB|^2 * LgB^T``, which gives
  ``Bdot = LfB + LgB k0 = -sqrt(LfB^2 + kappa^2 |LgB|^2) <= 0``.
- :func:`blend_weight` is the smooth bump ``sigma`` (eq. 3.5): 0 for ``B <= -eps``, 1 for
  ``B >= 0``, ``-2 (B/eps)^3 - 3 (B/eps)^2 + 1`` between, and the control is
  ``u = sigma k0 + (1 - sigma) u_nominal`` (eq. 3.4).
- :func:`cbf_qp` is the modern alternative: the input nearest to the nominal one with
  ``LfB_i + LgB_i u <= -alpha B_i`` for every barrier and ``|u| <= u_max``, a small QP solved
  exactly by DAQP's dual active-set method; a scenario builds its fixed part once
  (:func:`cbf_qp_problem`) and adds each step's data (:func:`solve_cbf_qp`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import daqp
import numpy as np
from scipy import sparse

from rcm_kin.errors import RcmKinError
from rcm_kin.safety.barriers import Barrier

LGB_ZERO = 1e-12     # |LgB|^2 below this: the barrier cannot be acted on here (k0 = 0)
PRIMAL_TOL = 1e-12   # DAQP: a constraint violated by more than this (inputs' units, rows normalised)
                     # enters the active set
DAQP_INF = 1e30      # DAQP reads a bound at or beyond this as none
DAQP_OPTIMAL, DAQP_INFEASIBLE = 1, -1   # DAQP exit flags


@dataclass(frozen=True)
class BarrierTerms:
    value: float          # B(x)
    lf: float             # L_f B(x)
    lg: np.ndarray        # L_G B(x), (m,)


def barrier_terms(barrier: Barrier, x: np.ndarray, f: np.ndarray, G: np.ndarray) -> BarrierTerms:
    """``B``, ``L_f B = dB/dx f`` and ``L_G B = dB/dx G`` at ``x``."""
    grad = barrier.gradient(x)
    return BarrierTerms(barrier.value(x), float(grad @ f), grad @ G)


def safety_control(terms: BarrierTerms, kappa: float) -> np.ndarray:
    """``k0(x)``; zero where ``L_G B`` vanishes."""
    norm2 = float(terms.lg @ terms.lg)
    if norm2 < LGB_ZERO:
        return np.zeros_like(terms.lg)
    return -(terms.lf + np.sqrt(terms.lf**2 + kappa**2 * norm2)) / norm2 * terms.lg


def blend_weight(value: float, eps: float) -> float:
    """``sigma(B)``: 0 in the safe interior, 1 on and beyond the boundary, C1 between."""
    if eps <= 0:
        raise RcmKinError(f"the transition band width eps must be positive, got {eps}")
    if value <= -eps:
        return 0.0
    if value >= 0:
        return 1.0
    s = value / eps
    return float(-2 * s**3 - 3 * s**2 + 1)


def blended_control(u_nominal: np.ndarray, terms: BarrierTerms, kappa: float, eps: float) -> tuple[np.ndarray, float]:
    """``(u, sigma)`` of the thesis's blend for one barrier."""
    sigma = blend_weight(terms.value, eps)
    return sigma * safety_control(terms, kappa) + (1 - sigma) * u_nominal, sigma


@dataclass(frozen=True)
class CbfQp:
    """The fixed part of a scenario's CBF-QP, in DAQP's form (``min u^T H u / 2 + f^T u`` s.t.
    ``lower <= u <= upper`` for the box, then ``A u <= upper`` for the barrier rows):
    ``inputs`` inputs, ``barriers`` barrier rows, the box ``|u| <= u_max``, the Hessian of
    ``|u - u_nominal|^2``. :func:`solve_cbf_qp` adds each step's data; nothing here changes
    between steps, so a step solved on it is, bit for bit, :func:`cbf_qp` on that step's data."""

    inputs: int
    barriers: int
    u_max: np.ndarray       # (inputs,), in the inputs' units
    hessian: np.ndarray     # (inputs, inputs): 2 I
    lower: np.ndarray       # (inputs + barriers,): -u_max, then none (-DAQP_INF) for the barrier rows
    sense: np.ndarray       # (inputs + barriers,) DAQP constraint types: 0, inequality, cold start


def qp_matrices(u_nominal: np.ndarray, terms: list[BarrierTerms], alpha: float, u_max: np.ndarray):
    """``(P, q, A, b)`` of ``min u^T P u / 2 + q^T u`` s.t. ``A u <= b``, the standard form any QP
    solver takes (Clarabel's, A in CSC): the barrier rows, then the box's ``+u`` and ``-u``. Up to
    the constant ``|u_nominal|^2`` this is the CBF-QP of :func:`solve_cbf_qp`; for cross-checks."""
    m = u_nominal.size
    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), (m,))
    rows = np.array([t.lg for t in terms], dtype=float).reshape(len(terms), m)
    A = sparse.csc_matrix(np.vstack([rows, np.eye(m), -np.eye(m)]))
    b = np.concatenate([[-t.lf - alpha * t.value for t in terms], u_max, u_max])
    return sparse.csc_matrix(2 * np.eye(m)), -2 * u_nominal, A, b


def cbf_qp_problem(inputs: int, barriers: int, u_max) -> CbfQp:
    """The CBF-QP structure for a scenario: ``inputs`` inputs, ``barriers`` barriers, bounds
    ``u_max`` (scalar or per input). Built once, solved each step by :func:`solve_cbf_qp`."""
    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), (inputs,)).copy()
    if not np.all(u_max >= 0):
        raise RcmKinError(f"the input bounds u_max must be non-negative, got {u_max}")
    lower = np.concatenate([-u_max, np.full(barriers, -DAQP_INF)])
    return CbfQp(inputs, barriers, u_max, 2 * np.eye(inputs), lower, np.zeros(inputs + barriers, dtype=np.intc))


def _barrier_rows(u_nominal: np.ndarray, terms: list[BarrierTerms], alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """``LgB_i u <= -LfB_i - alpha B_i`` as rows ``(k, inputs)`` and bounds ``(k,)``, each row
    scaled to unit length (the same half-space; DAQP's feasibility tolerance then is a distance
    in the inputs' units); a row ``LgB_i = 0`` stays as it is: ``0 <= bound``, met or infeasible.
    Any datum (or ``u_nominal``) NaN or inf: a clear error (one finiteness test of a sum of them,
    which also refuses data so large, beyond about 1e150, that the row norms overflow)."""
    rows = np.array([t.lg for t in terms], dtype=float).reshape(len(terms), u_nominal.size)
    bounds = np.array([-t.lf - alpha * t.value for t in terms], dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        norms = np.sqrt(np.square(rows).sum(axis=1))
        total = float(norms.sum() + bounds.sum() + u_nominal.sum())
    if not math.isfinite(total):
        raise RcmKinError("the CBF-QP data are not finite here (NaN or inf in u_nominal, B, LfB or LgB, or values "
                          "beyond about 1e150): check the state and nominal input handed to the filter (a "
                          "diverged simulation gives these)")
    norms[norms == 0] = 1.0
    return rows / norms[:, None], bounds / norms


def solve_cbf_qp(problem: CbfQp, u_nominal, terms: list[BarrierTerms], alpha: float) -> np.ndarray:
    """``argmin |u - u_nominal|^2`` s.t. ``LfB_i + LgB_i u <= -alpha B_i`` and ``|u_j| <= u_max_j``
    on the prebuilt ``problem``, solved exactly by DAQP's dual active-set method (the optimum is
    the solution of the KKT equations of its active set). Infeasible (the bounds and barriers
    conflict) or data not finite: a clear error."""
    u_nominal = np.asarray(u_nominal, dtype=float)
    m, k = problem.inputs, problem.barriers
    if u_nominal.size != m or len(terms) != k:
        raise RcmKinError(f"this CBF-QP was built for {m} inputs and {k} barriers, "
                          f"got {u_nominal.size} and {len(terms)}")
    rows, bounds = _barrier_rows(u_nominal, terms, alpha)
    u, _, exitflag, _ = daqp.solve(problem.hessian, -2 * u_nominal, rows, np.concatenate([problem.u_max, bounds]),
                                   problem.lower, problem.sense, primal_tol=PRIMAL_TOL)
    if exitflag != DAQP_OPTIMAL:
        reason = "infeasible" if exitflag == DAQP_INFEASIBLE else f"DAQP exit flag {exitflag}"
        raise RcmKinError(f"the CBF-QP has no solution here ({reason}): the input bounds cannot keep B from growing")
    return u


def cbf_qp(u_nominal: np.ndarray, terms: list[BarrierTerms], alpha: float, u_max) -> np.ndarray:
    """One CBF-QP step on its own (structure built and solved): see :func:`solve_cbf_qp`."""
    u_nominal = np.asarray(u_nominal, dtype=float)
    return solve_cbf_qp(cbf_qp_problem(u_nominal.size, len(terms), u_max), u_nominal, terms, alpha)

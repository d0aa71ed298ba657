"""Control-barrier-function safety filters for ``xdot = f(x) + G(x) u``.

- :func:`safety_control` is Wieland and Allgower's ``k0`` (thesis eq. 3.6):
  ``k0 = -(LfB + sqrt(LfB^2 + kappa^2 |LgB|^2)) / |LgB|^2 * LgB^T``, which gives
  ``Bdot = LfB + LgB k0 = -sqrt(LfB^2 + kappa^2 |LgB|^2) <= 0``.
- :func:`blend_weight` is the smooth bump ``sigma`` (eq. 3.5): 0 for ``B <= -eps``, 1 for
  ``B >= 0``, ``-2 (B/eps)^3 - 3 (B/eps)^2 + 1`` between, and the control is
  ``u = sigma k0 + (1 - sigma) u_nominal`` (eq. 3.4).
- :func:`cbf_qp` is the modern alternative: the input nearest to the nominal one with
  ``LfB_i + LgB_i u <= -alpha B_i`` for every barrier and ``|u| <= u_max`` (Clarabel QP); a
  scenario builds the problem once (:func:`cbf_qp_problem`) and updates its data each step
  (:func:`solve_cbf_qp`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from rcm_kin.errors import RcmKinError
from rcm_kin.safety.barriers import Barrier

LGB_ZERO = 1e-12     # |LgB|^2 below this: the barrier cannot be acted on here (k0 = 0)


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
    """The structure of a CBF-QP with ``inputs`` inputs and ``barriers`` barrier rows, built once
    (a Clarabel solver with fixed sparsity: the barrier rows dense, the box ``|u| <= u_max``);
    :func:`solve_cbf_qp` writes each step's data into it. Clarabel's presolve and equilibration
    are off, so that a step solved here is the same, to the last bit, as a solver built afresh
    from that step's data with these settings."""

    solver: object          # clarabel.DefaultSolver
    inputs: int
    barriers: int
    u_max: np.ndarray       # (inputs,)


def _settings():
    import clarabel

    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.presolve_enable = False        # data updates need it off (the bounds are finite: nothing to remove)
    settings.equilibrate_enable = False     # scaling fixed by the data of one step would differ from a fresh build
    return settings


def qp_data(u_nominal: np.ndarray, terms: list[BarrierTerms], alpha: float, u_max: np.ndarray):
    """The data of one step: ``q`` (m,), the nonzeros of ``A`` (column by column: the barrier
    rows, then +1 and -1 of the box) and ``b``."""
    m, k = u_nominal.size, len(terms)
    lg = np.array([t.lg for t in terms], dtype=float).reshape(k, m)
    values = np.empty((k + 2, m))
    values[:k], values[k], values[k + 1] = lg, 1.0, -1.0
    b = np.concatenate([[-t.lf - alpha * t.value for t in terms], u_max, u_max])
    return -2 * u_nominal, values.ravel(order="F"), b


def qp_matrices(u_nominal: np.ndarray, terms: list[BarrierTerms], alpha: float, u_max: np.ndarray):
    """``(P, q, A, b)`` of ``min u^T P u / 2 + q^T u`` s.t. ``A u <= b`` (Clarabel's form, A in CSC
    with every barrier entry stored, zeros included)."""
    m, k = u_nominal.size, len(terms)
    q, values, b = qp_data(u_nominal, terms, alpha, u_max)
    indices = np.concatenate([np.r_[np.arange(k), k + j, k + m + j] for j in range(m)])
    A = sparse.csc_matrix((values, indices, np.arange(m + 1) * (k + 2)), shape=(k + 2 * m, m))
    return sparse.csc_matrix(2 * np.eye(m)), q, A, b


def cbf_qp_problem(inputs: int, barriers: int, u_max) -> CbfQp:
    """The CBF-QP structure for a scenario: ``inputs`` inputs, ``barriers`` barriers, bounds
    ``u_max`` (scalar or per input). Built once, solved each step by :func:`solve_cbf_qp`."""
    import clarabel

    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), (inputs,)).copy()
    placeholder = [BarrierTerms(0.0, 0.0, np.ones(inputs))] * barriers
    P, q, A, b = qp_matrices(np.zeros(inputs), placeholder, 0.0, u_max)
    solver = clarabel.DefaultSolver(P, q, A, b, [clarabel.NonnegativeConeT(len(b))], _settings())
    return CbfQp(solver, inputs, barriers, u_max)


def solve_cbf_qp(problem: CbfQp, u_nominal, terms: list[BarrierTerms], alpha: float) -> np.ndarray:
    """``argmin |u - u_nominal|^2`` s.t. ``LfB_i + LgB_i u <= -alpha B_i`` and ``|u_j| <= u_max_j``
    on the prebuilt ``problem``. Infeasible (the bounds and barriers conflict): a clear error."""
    u_nominal = np.asarray(u_nominal, dtype=float)
    if u_nominal.size != problem.inputs or len(terms) != problem.barriers:
        raise RcmKinError(f"this CBF-QP was built for {problem.inputs} inputs and {problem.barriers} barriers, "
                          f"got {u_nominal.size} and {len(terms)}")
    q, values, b = qp_data(u_nominal, terms, alpha, problem.u_max)
    problem.solver.update(q=q, A=values, b=b)
    solution = problem.solver.solve()
    if str(solution.status) != "Solved":
        raise RcmKinError(f"the CBF-QP has no solution here ({solution.status}): the input bounds cannot keep B "
                          "from growing")
    return np.array(solution.x)


def cbf_qp(u_nominal: np.ndarray, terms: list[BarrierTerms], alpha: float, u_max) -> np.ndarray:
    """One CBF-QP step on its own (structure built and solved): see :func:`solve_cbf_qp`."""
    u_nominal = np.asarray(u_nominal, dtype=float)
    return solve_cbf_qp(cbf_qp_problem(u_nominal.size, len(terms), u_max), u_nominal, terms, alpha)

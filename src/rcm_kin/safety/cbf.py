"""Control-barrier-function safety filters for ``xdot = f(x) + G(x) u``.

- :func:`safety_control` is Wieland and Allgower's ``k0`` (thesis eq. 3.6):
  ``k0 = -(LfB + sqrt(LfB^2 + kappa^2 |LgB|^2)) / |LgB|^2 * LgB^T``, which gives
  ``Bdot = LfB + LgB k0 = -sqrt(LfB^2 + kappa^2 |LgB|^2) <= 0``.
- :func:`blend_weight` is the smooth bump ``sigma`` (eq. 3.5): 0 for ``B <= -eps``, 1 for
  ``B >= 0``, ``-2 (B/eps)^3 - 3 (B/eps)^2 + 1`` between, and the control is
  ``u = sigma k0 + (1 - sigma) u_nominal`` (eq. 3.4).
- :func:`cbf_qp` is the modern alternative: the input nearest to the nominal one with
  ``LfB_i + LgB_i u <= -alpha B_i`` for every barrier and ``|u| <= u_max`` (Clarabel QP).
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


def cbf_qp(u_nominal: np.ndarray, terms: list[BarrierTerms], alpha: float, u_max) -> np.ndarray:
    """``argmin |u - u_nominal|^2`` s.t. ``LfB_i + LgB_i u <= -alpha B_i`` and ``|u_j| <= u_max_j``,
    solved by Clarabel. Infeasible (the bounds and barriers conflict): a clear error."""
    import clarabel

    u_nominal = np.asarray(u_nominal, dtype=float)
    m = u_nominal.size
    u_max = np.broadcast_to(np.asarray(u_max, dtype=float), (m,))
    rows = [t.lg for t in terms] + list(np.eye(m)) + list(-np.eye(m))
    bounds = [-t.lf - alpha * t.value for t in terms] + list(u_max) + list(u_max)
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    solver = clarabel.DefaultSolver(sparse.csc_matrix(2 * np.eye(m)), -2 * u_nominal,
                                    sparse.csc_matrix(np.array(rows)), np.array(bounds),
                                    [clarabel.NonnegativeConeT(len(bounds))], settings)
    solution = solver.solve()
    if str(solution.status) != "Solved":
        raise RcmKinError(f"the CBF-QP has no solution here ({solution.status}): the input bounds cannot keep B "
                          "from growing")
    return np.array(solution.x)

"""Fixed-step integration of a CasADi right-hand side: the one classical RK4 of the package.

The closed-loop plant (:func:`rcm_kin.simulation.plant.period_map`) and the grey-box fit
(:mod:`rcm_kin.identification.greybox`) both step ``xdot = f(x, p)`` over one sampling period
with the other inputs ``p`` (the held PWM, parameters) constant. The steps are unrolled on SX
symbols, so the result is one expression graph: cheap to evaluate, to map over a record
(``mapaccum``) and to differentiate exactly (AD).
"""

from __future__ import annotations

import casadi as ca


def rk4_map(f: ca.Function, period: float, substeps: int, name: str = "rk4") -> ca.Function:
    """``(x, *p) -> x(T)``: ``f(x, *p) -> xdot`` (the state first, then inputs held constant)
    integrated over ``period`` T (in the time unit of ``f``, s here) by ``substeps`` classical
    RK4 steps of ``T / substeps``. The returned Function takes the inputs of ``f`` and names
    its output ``x_next``."""
    x = ca.SX.sym(f.name_in(0), f.sparsity_in(0))
    p = [ca.SX.sym(f.name_in(i), f.sparsity_in(i)) for i in range(1, f.n_in())]
    h = period / substeps
    xk = x
    for _ in range(substeps):
        k1 = f(xk, *p)
        k2 = f(xk + h / 2 * k1, *p)
        k3 = f(xk + h / 2 * k2, *p)
        k4 = f(xk + h * k3, *p)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function(name, [x, *p], [xk], f.name_in(), ["x_next"])

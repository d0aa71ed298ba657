"""The plant over one controller period: fixed-step RK4 with the PWM held (zero-order hold).

Classical RK4 with ``substeps`` equal steps per period ``T``. The stiffest term of the PSM's
driven joints is the smoothed Coulomb friction at rest (roll: slope ``F_c / v_c`` of 340
N m s/rad on 0.54 kg m^2, 630 1/s; pitch 170 1/s; the insertion loop ~120 rad/s), which gives
``|lambda| h <= 0.4`` at 400 Hz and 4 substeps, inside RK4's stability region (2.8).
``tests/test_simulation.py`` compares one period with DOP853 at rtol 1e-11: within 1e-7 rad in
position and 2e-4 rad/s in velocity, the largest where a velocity reverses through the friction.
"""

from __future__ import annotations

import casadi as ca

from rcm_kin.errors import RcmKinError


def period_map(forward: ca.Function, period: float, substeps: int = 4) -> ca.Function:
    """``(x, u) -> x(T)``: ``forward(x, u) -> xdot`` integrated over one period ``T`` (s) by
    ``substeps`` RK4 steps with ``u`` constant. Returns a CasADi Function (NumPy in, DM out)."""
    if not (period > 0 and substeps >= 1):
        raise RcmKinError(f"the period must be positive and substeps >= 1, got {period} s and {substeps}")
    x = ca.SX.sym("x", forward.size1_in(0))
    u = ca.SX.sym("u", forward.size1_in(1))
    h = period / substeps
    xk = x
    for _ in range(substeps):
        k1 = forward(xk, u)
        k2 = forward(xk + h / 2 * k1, u)
        k3 = forward(xk + h / 2 * k2, u)
        k4 = forward(xk + h * k3, u)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("period_map", [x, u], [xk], ["x", "u"], ["x_next"])

"""Cost of the safety filters per control step and of the SOS certificate searches.

    python benchmarks/bench_safety.py
Targets: a filter step well inside the thesis's 10 ms loop (and the 2.5 ms of our 400 Hz one):
blend under 50 us, CBF-QP under 1 ms; each SOS program under 10 s. The CBF-QP step the scenarios
run (DAQP's active-set method on the prebuilt problem) against the plain Clarabel call built from
the step's data (before issue 16): at least 4x faster. Clarabel with its structure built once and
its data updated per step (the previous implementation) is measured beside them.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import time

import clarabel
import numpy as np
from common import per_call, report
from scipy import sparse

from rcm_kin.safety.barriers import Ellipsoid
from rcm_kin.safety.cbf import barrier_terms, blended_control, cbf_qp, cbf_qp_problem, qp_matrices, solve_cbf_qp
from rcm_kin.safety.scenarios import CARTESIAN_TAU


def main() -> None:
    e = Ellipsoid(np.zeros(3), np.array([0.03, 0.06, 0.03]))
    x = np.array([0.035, 0.01, 0.0])
    A, B = np.diag(-1 / CARTESIAN_TAU), np.diag(1 / CARTESIAN_TAU)
    u = np.array([-0.05, 0.0, 0.0])

    def blend():
        blended_control(u, barrier_terms(e, x, A @ x, B), 1.0, 0.778)

    def qp():
        cbf_qp(u, [barrier_terms(e, x, A @ x, B)], 20.0, 0.1)

    def plain_clarabel():
        """The plain call, as cbf_qp made it before the prebuilt structure: matrices from the
        step's data and a new solver, default settings."""
        P, q, rows, bounds = qp_matrices(u, [barrier_terms(e, x, A @ x, B)], 20.0, 0.1)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        clarabel.DefaultSolver(P, q, rows, bounds, [clarabel.NonnegativeConeT(7)], settings).solve()

    # the previous implementation: one Clarabel solver with fixed sparsity (every barrier entry
    # stored), presolve and equilibration off, its q, A values and b updated each step
    settings = clarabel.DefaultSettings()
    settings.verbose, settings.presolve_enable, settings.equilibrate_enable = False, False, False
    pattern = sparse.csc_matrix(np.vstack([np.ones((1, 3)), np.eye(3), -np.eye(3)]))
    solver = clarabel.DefaultSolver(sparse.csc_matrix(2 * np.eye(3)), np.zeros(3), pattern, np.full(7, 0.1),
                                    [clarabel.NonnegativeConeT(7)], settings)

    def clarabel_updated():
        t = barrier_terms(e, x, A @ x, B)
        values = np.empty((3, 3))
        values[0], values[1], values[2] = t.lg, 1.0, -1.0
        solver.update(q=-2 * u, A=values.ravel(order="F"), b=np.r_[-t.lf - 20.0 * t.value, [0.1] * 6])
        solver.solve()

    problem = cbf_qp_problem(3, 1, 0.1)

    def prebuilt():
        solve_cbf_qp(problem, u, [barrier_terms(e, x, A @ x, B)], 20.0)

    plain, updated = per_call(plain_clarabel, 300), per_call(clarabel_updated, 1000)
    fresh, once = per_call(qp, 2000), per_call(prebuilt, 2000)
    report([("CBF blend (terms, k0, sigma), one step", per_call(blend, 2000)),
            ("CBF-QP: plain Clarabel call built from the step's data (before)", plain),
            ("CBF-QP: Clarabel built once, data updated (previous implementation)", updated),
            ("CBF-QP: cbf_qp (DAQP), one step on its own", fresh),
            ("CBF-QP: DAQP on the prebuilt problem (the scenarios)", once)])
    print(f"CBF-QP step: DAQP prebuilt / plain Clarabel call = {once / plain:.3f} "
          f"(speed-up {plain / once:.1f}x, target >= 4x; Clarabel built once: {plain / updated:.1f}x)")
    try:
        from rcm_kin.safety.sos import PROGRAMS, find_certificate, thesis_program
    except ImportError:
        return
    for number in PROGRAMS:
        start = time.perf_counter()
        c = find_certificate(thesis_program(number))
        print(f"SOS program {number}: {time.perf_counter() - start:.2f} s, "
              f"{'certificate found and verified' if c.feasible else 'no certificate'} ({c.status})")


if __name__ == "__main__":
    main()

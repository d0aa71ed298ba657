"""Cost of the safety filters per control step and of the SOS certificate searches.

    python benchmarks/bench_safety.py
Targets: a filter step well inside the thesis's 10 ms loop (and the 2.5 ms of our 400 Hz one):
blend under 50 us, CBF-QP (Clarabel) under 1 ms; each SOS program under 10 s.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import time

import numpy as np
from common import per_call, report

from rcm_kin.safety.barriers import Ellipsoid
from rcm_kin.safety.cbf import barrier_terms, blended_control, cbf_qp
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

    report([("CBF blend (terms, k0, sigma), one step", per_call(blend, 2000)),
            ("CBF-QP with Clarabel, one step", per_call(qp, 300))])
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

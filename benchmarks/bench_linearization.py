"""Linearisations per second over a 41 x 41 roll x pitch grid: one mapped CasADi call against a
Python loop of Pinocchio's analytic derivatives (same matrices; the tests hold them to 1e-10).

    python benchmarks/bench_linearization.py
Target: the mapped CasADi evaluation is faster per pose than the Pinocchio loop.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import time

import numpy as np
from common import report

from rcm_kin import load_robot
from rcm_kin.control.linearization import equilibrium, linearize_grid, linearize_pinocchio
from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.dynamics.state_space import driven_dynamics


def best_of(fn, repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    psm, params = load_robot("psm"), load_drive_parameters()
    model = driven_dynamics(psm, params)
    grid = np.radians(np.linspace(-30, 30, 41))
    P, R = np.meshgrid(grid, grid, indexing="ij")
    Q = np.column_stack([R.ravel(), P.ravel(), np.full(R.size, 0.08)])
    linearize_grid(model, Q)                                          # builds and caches the mapped function

    def pinocchio_loop():
        for q in Q:
            linearize_pinocchio(psm, model, params.gravity_offsets, *equilibrium(model, q))

    mapped, loop = best_of(lambda: linearize_grid(model, Q)), best_of(pinocchio_loop, 1)
    n = len(Q)
    report([("mapped CasADi (A, B, holding PWM), per pose", mapped / n),
            ("Python loop of Pinocchio ABA derivatives, per pose", loop / n)])
    print(f"41 x 41 grid: CasADi {n / mapped:,.0f} linearisations/s ({mapped:.3f} s), "
          f"Pinocchio loop {n / loop:,.0f}/s ({loop:.3f} s); speed-up {loop / mapped:.1f}x (target > 1)")


if __name__ == "__main__":
    main()

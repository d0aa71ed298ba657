"""Linearisations over a 41 x 41 roll x pitch grid, per pose, next to the plain library call a
user would write, same run:

- ``linearize_grid``: the compiled gravity and Jacobians (A, B, holding PWM) of the closed-chain
  driven model, mapped in C (:mod:`rcm_kin.symbolic.compiled`);
- the same with the interpreted CasADi functions (the fallback without a C compiler);
- a plain Python loop of ``pin.computeABADerivatives`` on the same open tree (the rotors'
  reflected inertia as armature) at the grid's tree configurations and zero velocity: the
  rigid-body derivatives alone, without the loop closure, the drive or the holding input;
- for scale, ``linearize_pinocchio``: the same matrices as ours from Pinocchio (ABA derivatives,
  the closure projection, the offsets' gravity derivatives), which the tests hold to 1e-10.

    python benchmarks/bench_linearization.py [POINTS ...]     (grid points per axis, default 41)
Target (issue 30): ``linearize_grid`` <= 0.3x the plain ``computeABADerivatives`` loop per pose, at
41 x 41 and 201 x 201.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS


import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import best_of, report  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.control.linearization import _armatured_tree, equilibrium, linearize_grid, linearize_pinocchio  # noqa: E402
from rcm_kin.dynamics.drive import DRIVEN, load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.state_space import driven_dynamics  # noqa: E402
from rcm_kin.model.reduced import tree_configuration  # noqa: E402
from rcm_kin.symbolic.compiled import map_points  # noqa: E402


def main(points: int = 41) -> None:
    psm, params = load_robot("psm"), load_drive_parameters()
    model = driven_dynamics(psm, params)
    grid = np.radians(np.linspace(-30, 30, points))
    P, R = np.meshgrid(grid, grid, indexing="ij")
    Q = np.column_stack([R.ravel(), P.ravel(), np.full(R.size, 0.08)])
    n = len(Q)
    linearize_grid(model, Q)                                          # compiles (or loads) once

    def interpreted():
        (g,) = map_points(model.gravity, Q)
        map_points(model.jacobians, np.hstack([Q, np.zeros_like(Q)]), g / model.drive.input_gain)

    tree = _armatured_tree(psm, model)
    data = tree.createData()
    index = [psm.actuated.index(j) for j in DRIVEN]
    Q7 = np.zeros((n, psm.nq))
    Q7[:, index] = Q
    q_tree = [np.array(q) for q in tree_configuration(psm, Q7)]
    zero = np.zeros(tree.nv)
    tau = [pin.computeGeneralizedGravity(tree, data, q).copy() for q in q_tree]   # holds the tree still

    def aba_loop():
        for q, t in zip(q_tree, tau):
            pin.computeABADerivatives(tree, data, q, zero, t)

    def ours_pinocchio():
        for q in Q[:200]:
            linearize_pinocchio(psm, model, params.gravity_offsets, *equilibrium(model, q))

    compiled_time = best_of(lambda: linearize_grid(model, Q)) / n
    interpreted_time = best_of(interpreted, 1) / n
    aba_time = best_of(aba_loop) / n
    ours_time = best_of(ours_pinocchio, 1) / 200
    report([("linearize_grid, compiled (A, B, holding PWM), per pose", compiled_time),
            ("the same, interpreted CasADi map, per pose", interpreted_time),
            ("Python loop of pin.computeABADerivatives (open tree), per pose", aba_time),
            ("linearize_pinocchio (same matrices via Pinocchio), per pose", ours_time)])
    print(f"{points} x {points} grid: compiled/ABA-loop = {compiled_time / aba_time:.3f} (target <= 0.3); "
          f"interpreted/ABA-loop = {interpreted_time / aba_time:.2f}; "
          f"compiled/interpreted = {compiled_time / interpreted_time:.3f}; CasADi {ca.__version__}")


if __name__ == "__main__":
    import sys

    for points in map(int, sys.argv[1:] or ["41"]):       # e.g. 41 201 (issue 30: at most 0.3x at both)
        main(points)

"""Linearisation of robots other than the PSM, per pose, beside a plain Pinocchio loop on the same
model, same run; and the PSM's path for scale (the generic path must cost no more per pose):

- the MTM (no drive file: torque input, all 7 actuated joints) on a 41 x 41 shoulder x elbow grid
  (j2 -40..60 deg, j3 -30..80 deg, the other joints at 0);
- the UR5 of example-robot-data (a two-line sidecar, torque input, 6 joints) at 1681 random poses;
- the bundled PSM (its drive: PWM input, roll, pitch, insertion) on its 41 x 41 roll x pitch grid.

For each: ``linearize_grid`` compiled (A, B and the holding input, mapped in C; the torque-input
models by the closed form at rest, the PSM by AD as before), the same with the interpreted CasADi
functions, and a plain Python loop of ``pin.computeABADerivatives`` on the robot's
open tree at the same configurations, zero velocity and the gravity torque (the rigid-body
derivatives alone: no closure, drive or holding input). Compilation is timed once, apart.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_linearize_any.py
Target: the generic (torque-input) path costs no more per pose than the PSM's.

Five runs each, alternated before/after in the same minutes, 2 cores (other jobs running), us/pose
compiled, best of 3 (warm cache):

    before (4dfe208)  MTM 6.0-10.4   UR5 4.2-6.6   PSM 2.5-4.0   (MTM 1.76-2.82x, UR5 1.14-1.99x the PSM's)
    after             MTM 1.0-1.7    UR5 0.5-0.8   PSM 2.4-3.8   (MTM 0.33-0.44x, UR5 0.14-0.27x the PSM's)

the plain ABA loop 6-11 us (MTM), 5-7 (UR5), 9.5-16 (PSM) in the same runs. Interpreted
(``compile=False``): MTM 35-36 before, 35-42 after; UR5 11.5-14.6 before, 17.6-17.7 after (the SX
Cholesky interpreted costs more than LAPACK's inverse). First build with an empty cache: MTM
1.3 s before, 1.7 s after; UR5 0.3 s, 0.5 s.

Where the time went (MTM, before): building a CasADi map of N poses on every call (``map_points``)
and the map's per-point call of the external function, 4.0 us a pose against 0.8 for the function
itself in one C loop; ``np.linalg.inv`` of the stacked mass matrices, 1.2-1.6 us; products,
assembly and temporaries, about 1. Now one compiled function per model,
:func:`rcm_kin.control.linearization.rest_linearization` (``g``, ``M``, ``dg/dq``, ``M^-1`` by its
Cholesky factor written out in SX, :mod:`rcm_kin.symbolic.linalg`, and the products), runs over
the poses in one C loop (:mod:`rcm_kin.symbolic.points`) writing ``u0``, ``A`` and ``B`` straight
into the result arrays: about 0.13 us a pose more than ``(g, M, dg/dq)`` alone, no NumPy after it
but one sum that checks the result finite. The numbers move by rounding only: at most 3e-15 of
each pose's matrix size against the NumPy/LAPACK form; tiny entries (cancellations, 1e-9 of the
matrix) by up to 1e-9 of themselves, where the old form is off the exact values by the same order.
The PSM's AD path is unchanged (bit for bit); through the C loop it would gain about 20 % (its AD
Jacobians dominate).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import best_of, report  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.control.linearization import _armatured_tree, linearize_grid  # noqa: E402
from rcm_kin.dynamics.state_space import driven_dynamics  # noqa: E402
from rcm_kin.model.reduced import tree_configuration  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def grid_poses(robot, model, first: str, second: str, span1, span2, points: int = 41) -> np.ndarray:
    """(points^2, n) poses of the model's joints: a grid over two joints (deg), the others at 0."""
    P, R = np.meshgrid(np.radians(np.linspace(*span2, points)), np.radians(np.linspace(*span1, points)),
                       indexing="ij")
    Q = np.zeros((R.size, len(model.joints)))
    Q[:, model.joints.index(first)], Q[:, model.joints.index(second)] = R.ravel(), P.ravel()
    return Q


def measure(name: str, robot, model, Q: np.ndarray) -> tuple[list, float]:
    """Rows (name, seconds per pose) of the three paths and the compiled/ABA-loop ratio."""
    n = len(Q)
    start = time.perf_counter()
    linearize_grid(model, Q)                                          # compiles (or loads) once
    build = time.perf_counter() - start

    def interpreted():
        linearize_grid(model, Q, compile=False)

    tree = _armatured_tree(robot, model)
    data = tree.createData()
    index = [robot.actuated.index(j) for j in model.joints]
    full = np.tile(model.q_fixed, (n, 1))
    full[:, index] = Q
    q_tree = [np.array(q) for q in tree_configuration(robot, full)]
    zero = np.zeros(tree.nv)
    tau = [pin.computeGeneralizedGravity(tree, data, q).copy() for q in q_tree]   # holds the tree still

    def aba_loop():
        for q, t in zip(q_tree, tau):
            pin.computeABADerivatives(tree, data, q, zero, t)

    compiled_time = best_of(lambda: linearize_grid(model, Q)) / n
    interpreted_time = best_of(interpreted, 1) / n
    aba_time = best_of(aba_loop) / n
    rows = [(f"{name}: linearize_grid, compiled, per pose", compiled_time),
            (f"{name}: the same, interpreted CasADi map, per pose", interpreted_time),
            (f"{name}: Python loop of pin.computeABADerivatives, per pose", aba_time)]
    print(f"{name}: {len(model.joints)} joints, {model.input_unit} input, {model.model_label}; {n} poses; "
          f"first linearize_grid (compile or cache load) {build:.1f} s; compiled/ABA-loop = "
          f"{compiled_time / aba_time:.2f}")
    return rows, compiled_time


def main() -> None:
    from oracles.dyn_robots import write_ur5

    rows, per_pose = [], {}
    mtm = load_robot("mtm")
    model = driven_dynamics(mtm)
    r, per_pose["mtm"] = measure("MTM", mtm, model, grid_poses(mtm, model, "j2", "j3", (-40, 60), (-30, 80)))
    rows += r
    with tempfile.TemporaryDirectory() as folder:
        ur5 = load_robot(write_ur5(Path(folder)))
        model = driven_dynamics(ur5)
        Q = np.random.default_rng(0).uniform(-2.5, 2.5, (1681, ur5.nq))
        r, per_pose["ur5"] = measure("UR5", ur5, model, Q)
        rows += r
    psm = load_robot("psm")
    model = driven_dynamics(psm)
    Q = grid_poses(psm, model, "roll", "pitch", (-30, 30), (-30, 30))
    Q[:, 2] = 0.08
    r, per_pose["psm"] = measure("PSM", psm, model, Q)
    rows += r
    report(rows)
    print(f"compiled per pose against the PSM's: MTM {per_pose['mtm'] / per_pose['psm']:.2f}x, "
          f"UR5 {per_pose['ur5'] / per_pose['psm']:.2f}x; CasADi {ca.__version__}, Pinocchio {pin.__version__}")


if __name__ == "__main__":
    main()

"""The torque map of any robot per pose, next to a plain Pinocchio gravity loop on the same model, same run:

- the MTM over j2 x j3 (201 x 201, j1 at 20 deg) and a UR5 from example-robot-data (a sidecar written in
  a temporary folder) over shoulder_lift x elbow (201 x 201): :func:`rcm_kin.statics.holding.torque_map`
  (the closed chain's gravity of every actuated joint compiled to C and mapped over the poses), per pose;
- the plain call: ``pin.computeGeneralizedGravity`` on the robot's open tree (both are serial arms: tree q
  = actuated q) in a Python loop over the same poses, per pose;
- the PSM: today's path (``gravity_map``, roll x pitch at one insertion: the driven model's gravity and
  the drive) and the generic map over the same poses (all seven actuated joints, then the drive), per pose.

    OPENBLAS_NUM_THREADS=1 python benchmarks/bench_torque_map_any.py
Target: the generic path costs no more per pose than the PSM path (ratio <= 1.0, within timing noise).

Two runs each, the same minute, 2 cores (another job running), us/pose, best of 7:

    before (cdcf4b2)   MTM 0.52-0.57   UR5 0.26-0.36   PSM gravity_map 0.28-0.39   PSM torque_map 0.39-0.51  (1.29-1.38)
    after              MTM 0.16-0.17   UR5 0.09-0.13   PSM gravity_map 0.29-0.42   PSM torque_map 0.20-0.24  (0.57-0.71)

Where the time went: building a CasADi map of N points (``fn.map(N)``, rebuilt by every
``map_points`` call) costs about as much as evaluating it, and a map's call of an external function
adds about a third per point; the map now runs the compiled function's own C entry in one C loop
per block of poses (:mod:`rcm_kin.symbolic.points`), written into the result in place, the drive in
blocks of 4096 poses (in cache). In the C loop the gravity of all seven PSM joints costs 0.13 us a
pose, the driven model's three 0.07 us; ``gravity_map`` still maps its function by CasADi (0.12 us
a pose plus the map's building), so it would gain from the C loop too.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import best_of  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.statics.holding import torque_map  # noqa: E402
from rcm_kin.statics.maps import gravity_map  # noqa: E402

N = 201
REPEATS = 7         # best of, per timed call (one call is a whole map, some 10 ms)


def ur5(folder: Path):
    from example_robot_data.robots_loader import UR5Loader

    joints = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
              "wrist_3_joint"]
    (folder / "ur5.toml").write_text(f'robot = "ur5"\nurdf = "{UR5Loader().df_path}"\n'
                                     f"actuated = {joints}\n".replace("'", '"') + 'frames = ["tool0"]\n')
    return load_robot(folder / "ur5.toml")


def plain_loop(robot, q, index, values) -> float:
    """Seconds per pose of pin.computeGeneralizedGravity over the grid in a Python loop (the open tree)."""
    model, data = robot.tree, robot.tree.createData()
    A, B = np.meshgrid(*values, indexing="ij")
    poses = np.broadcast_to(q, (A.size, robot.nq)).copy()
    poses[:, index[0]], poses[:, index[1]] = A.ravel(), B.ravel()

    def loop():
        for p in poses:
            pin.computeGeneralizedGravity(model, data, p)

    return best_of(loop, 2) / A.size


def serial_arm(name, robot, grid, q) -> tuple[list, float, float]:
    torque_map(robot, {k: v[:2] for k, v in grid.items()}, q)          # compiles (or loads) once
    ours = best_of(lambda: torque_map(robot, grid, q), REPEATS) / N**2
    plain = plain_loop(robot, np.asarray(q, float), [robot.actuated.index(k) for k in grid], list(grid.values()))
    return [(f"{name} torque map {N} x {N}, per pose", ours),
            (f"{name} pin.computeGeneralizedGravity loop, per pose", plain)], ours, plain


def main() -> None:
    rows, ratios = [], []
    mtm = load_robot("mtm")
    grid = {"j2": np.radians(np.linspace(-40, 60, N)), "j3": np.radians(np.linspace(-30, 80, N))}
    r, ours, plain = serial_arm("MTM", mtm, grid, np.radians([20, 0, 0, 0, 0, 0, 0]))
    rows += r
    ratios.append(("MTM map/plain", ours / plain))
    with tempfile.TemporaryDirectory() as tmp:
        arm = ur5(Path(tmp))
        grid = {"shoulder_lift_joint": np.radians(np.linspace(-90, 0, N)),
                "elbow_joint": np.radians(np.linspace(0, 120, N))}
        r, ours, plain = serial_arm("UR5", arm, grid, [0.3, 0, 0, -0.5, 0.2, 0])
        rows += r
        ratios.append(("UR5 map/plain", ours / plain))
    psm = load_robot("psm")
    deg = np.linspace(-30, 30, N)
    gravity_map(psm, None, deg[:2], deg[:2], [0.08])
    today = best_of(lambda: gravity_map(psm, None, deg, deg, [0.08]), REPEATS) / N**2
    generic_grid = {"pitch": np.radians(deg), "roll": np.radians(deg)}
    q = [0, 0, 0.08, 0, 0, 0, 0]
    torque_map(psm, {k: v[:2] for k, v in generic_grid.items()}, q)
    generic = best_of(lambda: torque_map(psm, generic_grid, q), REPEATS) / N**2
    rows += [(f"PSM today's path (gravity_map, roll x pitch {N} x {N}), per pose", today),
             ("PSM generic torque_map, same poses, per pose", generic)]
    ratios.append(("PSM generic/today (target <= 1.0)", generic / today))
    width = max(len(name) for name, _ in rows)
    for name, seconds in rows:
        print(f"{name:{width}}  {seconds * 1e6:7.3f} us/pose")
    print("; ".join(f"{name} = {value:.3f}" for name, value in ratios))


if __name__ == "__main__":
    main()

"""Torque-map cost per pose next to a plain Pinocchio gravity call in a Python loop, same run.

    python benchmarks/bench_gravity.py
Target: the vectorised map costs no more per pose than the plain call.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import time

import numpy as np
import pinocchio as pin
from common import per_call, report

from rcm_kin import load_robot
from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.statics.gravity_map import gravity_map


def main() -> None:
    psm, drive = load_robot("psm"), load_drive_parameters()
    grid = np.linspace(-30, 30, 301)
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        gravity_map(psm, drive, grid, grid, [0.08])
        best = min(best, time.perf_counter() - start)
    per_pose = best / grid.size**2
    model, data = psm.reduced, psm.reduced.createData()
    q = psm.to_reduced(np.array([0.2, -0.3, 0.08, 0, 0, 0, 0]))
    plain = per_call(lambda: pin.computeGeneralizedGravity(model, data, q), 20000)
    report([("301 x 301 torque map (gravity + drive), per pose", per_pose),
            ("pin.computeGeneralizedGravity in a Python loop", plain)])
    print(f"301 x 301 map: {best:.3f} s in all; ratio map/plain = {per_pose / plain:.2f} (target <= 1)")


if __name__ == "__main__":
    main()

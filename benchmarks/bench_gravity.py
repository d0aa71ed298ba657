"""Torque-map cost per pose next to a plain Pinocchio gravity call in a Python loop, same run, and
the ``rcm-kin torque-map`` command end to end at 1001 x 1001:

- the gravity grid: the driven model's gravity compiled to C and mapped over the 301 x 301
  poses (:func:`rcm_kin.statics.gravity_map.driven_gravity`), per pose;
- the whole map (gravity and the drive model: torque, current, voltage, PWM), per pose;
- the NumPy batch (:func:`rcm_kin.dynamics.gravity.gravity_batch`), the path before compiling;
- the plain call: ``pin.computeGeneralizedGravity`` on the reduced model (the closed chain as
  mimic joints, no calibrated offsets) in a Python loop over the same poses;
- ``rcm-kin torque-map psm`` at 1001 x 1001 in a child process: wall time and peak memory, next
  to its maths alone (``gravity_map`` at the same grid, in this process).

    python benchmarks/bench_gravity.py [--skip-cli]
Targets: gravity grid <= 0.3x the Pinocchio loop per pose at 301 x 301; the command at
1001 x 1001 in under 3x its maths and under 400 MB peak.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import report  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.gravity import gravity_batch  # noqa: E402
from rcm_kin.statics.gravity_map import driven_gravity, gravity_map  # noqa: E402


def best_of(fn, repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def poses(n: int) -> np.ndarray:
    grid = np.radians(np.linspace(-30, 30, n))
    P, R = np.meshgrid(grid, grid, indexing="ij")
    return np.column_stack([R.ravel(), P.ravel(), np.full(R.size, 0.08)])


def main() -> None:
    psm, drive = load_robot("psm"), load_drive_parameters()
    grid = np.linspace(-30, 30, 301)
    Q = poses(301)
    n = len(Q)
    Q7 = np.zeros((n, psm.nq))
    Q7[:, :3] = Q
    driven_gravity(psm, drive, Q[:10])                                # compiles (or loads) once
    compiled = best_of(lambda: driven_gravity(psm, drive, Q)) / n
    whole_map = best_of(lambda: gravity_map(psm, drive, grid, grid, [0.08])) / n
    numpy = best_of(lambda: gravity_batch(psm, Q7, drive.gravity_offsets), 2) / n
    model, data = psm.reduced, psm.reduced.createData()
    reduced = [psm.to_reduced(q) for q in Q7]

    def pinocchio_loop():
        for q in reduced:
            pin.computeGeneralizedGravity(model, data, q)

    plain = best_of(pinocchio_loop, 2) / n
    report([("301 x 301 gravity grid, compiled, per pose", compiled),
            ("301 x 301 torque map (gravity + drive), per pose", whole_map),
            ("301 x 301 NumPy gravity_batch, per pose", numpy),
            ("pin.computeGeneralizedGravity in a Python loop, per pose", plain)])
    print(f"gravity grid/plain = {compiled / plain:.3f} (target <= 0.3); map/plain = {whole_map / plain:.3f}; "
          f"NumPy batch/plain = {numpy / plain:.3f}")
    if "--skip-cli" in sys.argv:
        return
    big = np.linspace(-30, 30, 1001)
    maths = best_of(lambda: gravity_map(psm, drive, big, big, [0.08]), 2)
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "rcm_kin.cli", "torque-map", "psm", "--roll=-30:30:1001",
                        "--pitch=-30:30:1001", "--out", out, "--json"], check=True, capture_output=True)
        wall = time.perf_counter() - start
        size = (Path(out) / "torque_map.csv").stat().st_size
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    print(f"rcm-kin torque-map 1001 x 1001: {wall:.2f} s end to end (CSV {size / 1e6:.0f} MB), maths alone "
          f"{maths:.2f} s: ratio {wall / maths:.1f} (target < 3); peak memory {peak:.0f} MB (target < 400); "
          f"a Pinocchio gravity loop over the same poses would take {plain * big.size**2:.2f} s")


if __name__ == "__main__":
    main()

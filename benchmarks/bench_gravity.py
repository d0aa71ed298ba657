"""Torque-map cost per pose next to a plain Pinocchio gravity call in a Python loop, same run, and
the ``rcm-kin torque-map`` command end to end at 1001 x 1001 next to its maths alone:

- the gravity grid: the driven model's gravity compiled to C and mapped over the 301 x 301
  poses (:func:`rcm_kin.statics.maps.driven_gravity`), per pose;
- the whole map (gravity and the drive model: torque, current, voltage, PWM), per pose;
- the NumPy batch (:func:`rcm_kin.model.gravity.gravity_batch`), the path before compiling;
- the plain call: ``pin.computeGeneralizedGravity`` on the reduced model (the closed chain as
  mimic joints, no calibrated offsets) in a Python loop over the same poses;
- ``rcm-kin torque-map psm`` at 1001 x 1001, tables as CSV (the default) and as ``--format npz``,
  with and without the figures (``--no-figures``), next to its maths alone (``gravity_map`` at the
  same grid, in this process, best of 3). The command's time is given two ways:
  *fresh*: ``python -m rcm_kin.cli torque-map ...`` in a new interpreter, wall time, so with the
  start-up (imports, loading the compiled gravity), and its peak memory (the child's maxrss);
  *in-process*: ``rcm_kin.cli.main([...])`` called in this process after the maths ran (imports
  done, the compiled gravity loaded): the command's own work. The import time of ``rcm_kin.cli``
  in a new interpreter is printed beside them. Each is the best of 2.

    python benchmarks/bench_gravity.py [--skip-cli]
Targets: gravity grid <= 0.3x the Pinocchio loop per pose at 301 x 301; the command at
1001 x 1001 in under 3x its maths and under 400 MB peak.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import contextlib  # noqa: E402
import io  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import best_of, report  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.cli import main as cli_main  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.model.gravity import gravity_batch  # noqa: E402
from rcm_kin.statics.maps import driven_gravity, gravity_map  # noqa: E402


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
    maths = best_of(lambda: gravity_map(psm, drive, big, big, [0.08]), 3)
    imports = min(fresh_run("import rcm_kin.cli")[0] for _ in range(2))
    print(f"rcm-kin torque-map psm --roll=-30:30:1001 --pitch=-30:30:1001: maths alone (gravity_map) {maths:.2f} s; "
          f"a Pinocchio gravity loop over the same poses would take {plain * big.size**2:.2f} s; "
          f"importing rcm_kin.cli in a new interpreter {imports:.2f} s")
    print(f"{'tables':30} {'fresh s':>8} {'/maths':>7} {'in-process s':>13} {'/maths':>7} {'peak MB':>8} "
          f"{'MB written':>11}   under 3x and 400 MB: fresh, in-process")
    for options in (["--format", "csv"], ["--format", "npz"], ["--format", "csv", "--no-figures"],
                    ["--format", "npz", "--no-figures"]):
        argv = ["torque-map", "psm", "--roll=-30:30:1001", "--pitch=-30:30:1001", "--json", *options]
        fresh = [fresh_run(RUN_CLI, argv) for _ in range(2)]
        wall, peak = min(t for t, _ in fresh), max(m for _, m in fresh)
        inside, written = min(in_process(argv) for _ in range(2))
        meets = ["yes" if seconds < 3 * maths and peak < 400 else "no" for seconds in (wall, inside)]
        print(f"{' '.join(options):30} {wall:8.2f} {wall / maths:7.1f} {inside:13.2f} {inside / maths:7.1f} "
              f"{peak:8.0f} {written / 1e6:11.0f}   {', '.join(meets)}")


# the child's own peak resident memory, printed last on stderr: VmHWM belongs to the memory of the
# new program, while ru_maxrss would include the pages of this (large) process it was forked from
PEAK = ("import atexit, runpy, sys; atexit.register(lambda: print(open('/proc/self/status').read()"
        ".split('VmHWM:')[1].split()[0], file=sys.stderr)); sys.argv[0] = 'rcm-kin'; {run}")
RUN_CLI = "runpy.run_module('rcm_kin.cli', run_name='__main__')"


def fresh_run(code: str, argv: list[str] = ()) -> tuple[float, float]:
    """Wall time (s) and peak memory (MB) of ``python -c CODE ARGV`` in a new interpreter (a
    torque-map writes into a temporary folder)."""
    with tempfile.TemporaryDirectory() as out:
        args = [*argv, "--out", out] if argv else []
        start = time.perf_counter()
        run = subprocess.run([sys.executable, "-c", PEAK.format(run=code), *args], capture_output=True, text=True)
        wall = time.perf_counter() - start
    if run.returncode != 0:
        raise RuntimeError(f"{code} {' '.join(argv)} failed: {run.stderr}")
    return wall, int(run.stderr.split()[-1]) / 1024


def in_process(argv: list[str]) -> tuple[float, int]:
    """Seconds of ``rcm_kin.cli.main(argv)`` in this process (output folder in a temporary
    folder), and the bytes it wrote."""
    with tempfile.TemporaryDirectory() as out, contextlib.redirect_stdout(io.StringIO()):
        start = time.perf_counter()
        if cli_main([*argv, "--out", out]) != 0:
            raise RuntimeError(f"rcm-kin {' '.join(argv)} failed")
        seconds = time.perf_counter() - start
        written = sum(f.stat().st_size for f in Path(out).iterdir())
    return seconds, written


if __name__ == "__main__":
    main()

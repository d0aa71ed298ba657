"""Time per call of the exported C model (``rcm-kin export psm --c``): holding PWM and its
gradient at one pose, timed in a C loop on this machine, next to the calls a Python user would
make for the same numbers, same run: the interpreted CasADi function of the export (PWM and
gradient), the library's ``holding_pwm`` (PWM only) and one ``pin.computeGeneralizedGravity``
on the reduced model (gravity only, no drive, no gradient: a cost floor).

    python benchmarks/bench_firmware_model.py
Reports: operations per call (the exporter's count) and ns per call at -O2; no target (the
microcontroller is slower; the operation count is what carries over).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import shutil  # noqa: E402
import subprocess  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import per_call, report  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.codegen.psm_model import export_c, holding_pwm_function  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm  # noqa: E402

TIMING_MAIN = r"""
#include <stdio.h>
#include <time.h>
#include "rcm_psm_model.h"
#define POSES 1024
int main(void) {
    static double q[POSES][3];
    double pwm[3], grad[9], sink = 0.0;
    struct timespec t0, t1;
    long calls = 0, i;
    for (i = 0; i < POSES; ++i) {          /* a fixed spread of poses in the joint range */
        q[i][0] = -0.5 + i * (1.0 / POSES); q[i][1] = 0.4 - i * (0.8 / POSES); q[i][2] = 0.02 + i * (0.1 / POSES);
    }
    clock_gettime(CLOCK_MONOTONIC, &t0);
    do {
        for (i = 0; i < POSES; ++i) { rcm_psm_holding_pwm(q[i], pwm, grad); sink += pwm[0] + grad[4]; }
        calls += POSES;
        clock_gettime(CLOCK_MONOTONIC, &t1);
    } while ((t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec) < 0.5);
    printf("%.6e %g\n", ((t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec)) / calls, sink);
    return 0;
}
"""


def c_time_per_call(folder: Path, compiler: str) -> float:
    (folder / "timing.c").write_text(TIMING_MAIN)
    subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2",
                    "-D_POSIX_C_SOURCE=199309L",
                    str(folder / "timing.c"), str(folder / "rcm_psm_model.c"), "-o", str(folder / "timing"), "-lm"],
                   check=True)
    best = min(float(subprocess.run([str(folder / "timing")], capture_output=True, text=True, check=True)
                     .stdout.split()[0]) for _ in range(3))
    return best


def main() -> None:
    psm = load_robot("psm")
    model = driven_dynamics(psm, load_drive_parameters())
    compiler = shutil.which(os.environ.get("CC") or "cc")
    if compiler is None:
        raise SystemExit("no C compiler: set CC")
    with tempfile.TemporaryDirectory() as work:
        result = export_c(model, work)
        c_call = c_time_per_call(Path(work), compiler)
    fn = holding_pwm_function(model)
    q = np.array([0.2, -0.3, 0.08])
    interpreted = per_call(lambda: fn(q), 5000)
    library = per_call(lambda: holding_pwm(model, q), 5000)
    reduced, data = psm.reduced, psm.reduced.createData()
    qr = psm.to_reduced(np.r_[q, np.zeros(4)])
    gravity = per_call(lambda: pin.computeGeneralizedGravity(reduced, data, qr), 20000)
    report([("exported C: holding PWM + gradient (-O2)", c_call),
            ("CasADi interpreted: holding PWM + gradient", interpreted),
            ("rcm_kin holding_pwm (PWM only)", library),
            ("pin.computeGeneralizedGravity, reduced model", gravity)])
    print(f"{result.operations} operations per call ({result.operation_counts}); "
          f"C {c_call * 1e9:.0f} ns/call = {c_call / interpreted:.3f}x interpreted CasADi, "
          f"{c_call / gravity:.3f}x a Pinocchio gravity call from Python")


if __name__ == "__main__":
    main()

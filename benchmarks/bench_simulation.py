"""Simulated seconds per wall-clock second of the 400 Hz closed loop (nonlinear PSM plant, RK4
with 4 substeps per period, encoder/PWM quantisation, firmware velocity estimate).

    python benchmarks/bench_simulation.py
Target: at least 10 simulated seconds per wall-clock second for every controller, so the
report's experiments and a parameter sweep stay interactive on 2 cores.
"""

from __future__ import annotations

import time

import numpy as np
from common import per_call, report

from rcm_kin.hardware import FIRMWARE_PERIOD, PWM_LIMIT
from rcm_kin.simulation.controllers import CONTROLLERS, Sample, make_controller
from rcm_kin.simulation.experiments import psm_plant_and_schedule, run_experiment


def main() -> None:
    plant, schedule = psm_plant_and_schedule()
    x, u = plant.initial(np.array([0.1, -0.1, 0.08])), np.array([-20.0, -80.0, 5.0])
    sample = Sample(np.array([5.0, -5.0, 0.08]), np.array([1.0, 2.0, 0.0]), np.array([6.0, -4.0, 0.08]),
                    np.zeros(3), np.zeros(3), FIRMWARE_PERIOD, PWM_LIMIT)
    scheduled = make_controller("scheduled-gravity", schedule)
    memory = scheduled.initial_memory()
    report([("plant: one 2.5 ms period (RK4 x4, CasADi)", per_call(lambda: plant.step(x, u), 2000)),
            ("controller: scheduled-gravity, one tick", per_call(lambda: scheduled.command(memory, sample), 2000))])
    duration = 6.0
    for name in CONTROLLERS:
        run_experiment("sine", name, duration=1.0)                  # warm-up
        best = float("inf")
        for _ in range(3):
            start = time.perf_counter()
            run_experiment("sine", name, duration=duration)
            best = min(best, time.perf_counter() - start)
        print(f"sine {duration:g} s with {name:17}: {best:.3f} s wall, "
              f"{(duration + 1.0) / best:5.1f} simulated s per wall s (incl. 1 s settling; target >= 10)")


if __name__ == "__main__":
    main()

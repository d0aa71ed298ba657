"""Samples per second of a robustness run (``rcm-kin robustness``) on an embedded Dask cluster of 1
and 2 worker processes, and the scaling (2 workers / 1 worker), against the plain loop a user
would write in one process (``run_sample`` for each seed, no Dask), same run.

Each sample: one parameter set drawn, the sinusoid (6 s at 400 Hz plus the 1 s settling) with
the P and the scheduled controllers on the drawn plant, and their linear margins on a 5 x 5 grid.
Each cluster is warmed up first (one sample per worker: imports, the compiled kernels, the nominal
gain schedule), so the rates are the steady ones; the start-up is reported beside them, and the
CPU time the workers spent (``time.process_time`` in each) per sample and as a share of the
wall-clock time: on a busy machine the scaling is the CPU the workers got, which this shows.

    python benchmarks/bench_robustness.py [SAMPLES]
The scaling is bounded by the cores free: on a machine shared with other work, read it with the
load average printed beside it.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import sys  # noqa: E402
import time  # noqa: E402

from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.parallel import dask_client  # noqa: E402
from rcm_kin.robustness.execution import run_robustness  # noqa: E402
from rcm_kin.robustness.sampling import sample_seeds, uncertain_parameters  # noqa: E402
from rcm_kin.robustness.statistics import summarise  # noqa: E402
from rcm_kin.robustness.task import Study, run_sample  # noqa: E402

CONTROLLERS = ("p", "scheduled")
SEED = 0


def plain_loop(study: Study, samples: int) -> tuple[float, dict]:
    """Seconds for ``samples`` samples in this process, one after the other, and the result."""
    seeds = sample_seeds(SEED, samples)
    run_sample(study, 0, seeds[0])                       # warm-up: schedule, kernels
    start = time.perf_counter()
    outcomes = [run_sample(study, i, s) for i, s in enumerate(seeds)]
    return time.perf_counter() - start, summarise(study, SEED, outcomes).as_dict()


def on_cluster(study: Study, samples: int, workers: int) -> tuple[float, float, float, dict]:
    """Start-up seconds (cluster and one warm-up sample per worker), seconds for ``samples``
    samples, the workers' CPU seconds for them, and the result."""
    start = time.perf_counter()
    with dask_client(workers=workers) as client:
        run_robustness(study, workers, SEED + 1, client, batch_size=1, progress=False)
        cpu = client.run(time.process_time)
        ready = time.perf_counter()
        result = run_robustness(study, samples, SEED, client, batch_size=1, progress=False)
        seconds = time.perf_counter() - ready
        spent = sum(t - cpu[w] for w, t in client.run(time.process_time).items())
        return ready - start, seconds, spent, result.as_dict()


def main(samples: int) -> None:
    params = load_drive_parameters()
    study = Study(params, uncertain_parameters(params), CONTROLLERS, "sine")
    print(f"{samples} samples of the sinusoid with {', '.join(CONTROLLERS)}; load average "
          f"{' '.join(f'{v:.2f}' for v in os.getloadavg())} on {os.cpu_count()} cores")
    plain, expected = plain_loop(study, samples)
    rates = {}
    print(f"{'plain loop, one process':28} {samples / plain:6.3f} samples/s")
    for workers in (1, 2):
        startup, seconds, cpu, result = on_cluster(study, samples, workers)
        assert result == expected, "a cluster run differs from the plain loop"
        rates[workers] = samples / seconds
        print(f"{f'Dask, {workers} worker(s)':28} {rates[workers]:6.3f} samples/s  "
              f"({rates[workers] * plain / samples:.2f} x the plain loop; start-up {startup:.1f} s; workers' CPU "
              f"{cpu / samples:.2f} s per sample, {cpu / (seconds * workers):.0%} of their wall-clock time)")
    print(f"scaling 2 workers / 1 worker: {rates[2] / rates[1]:.2f}; results identical to the plain loop")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 12)

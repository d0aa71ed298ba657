"""What a user feels (issue 30): commands from a fresh process against ``python -c "import
pinocchio"``, and the in-process cost of a controller period against the kernel's, same run.

Fresh processes, interleaved, best of ``--repeats`` wall times (a process's start-up is its
imports, the cached files it reads, and its work):

- ``rcm-kin simulate psm --experiment sine --controller scheduled --duration 31 --json``
  (target: at most 4x the Pinocchio import);
- ``rcm-kin torque-map psm --out DIR`` (61 x 61, the three figures; target at most 6x), and
  ``python -c "import matplotlib.pyplot"`` for scale;
- ``rcm-kin --help``;
- with ``--report``: the warm ``rcm-kin report --out DIR`` (target: at most 20x the Pinocchio
  import), in the same rounds.

In process: ``run_experiment`` of the same simulation, warm (second call), per controller period,
against the compiled kernel alone (``simulate_compiled`` on the already built plant and law;
target within 2x).

``--robustness``: ``rcm-kin robustness psm --controller p --controller scheduled --experiment sine``
with 8 and 32 samples from fresh processes; a sample's cost is the difference over 24, against the
in-process simulation of the same controllers and experiment (target: at most 3x); the first and
second sample timed inside fresh processes (what a worker pays first: its models); then the
compiler runs of 8 samples on an empty cache and of 32 more drawn from another seed (target: none
after the first sample).

``--against SRC`` runs the commands a second time with ``PYTHONPATH=SRC`` (another checkout's
``src``, e.g. ``git archive main src | tar -x -C /tmp/main``): before and after in one run. The
caches (compiled functions and kernel, gain schedules) are warm: run each command once first, as the
benchmark does. So is Python's bytecode, as after ``pip install .`` (which compiles it): the
processes write and read it under ``PYTHONPYCACHEPREFIX`` (``common.PYCACHE``), whatever
``PYTHONDONTWRITEBYTECODE`` says (with it set, an editable checkout compiled every imported
module on every start: about 0.1 s of rcm-kin's start-up that an installed copy does not pay).

    python benchmarks/bench_startup.py [--repeats 5] [--against /tmp/main/src] [--report]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

from common import best_of, child_env, fresh_run  # noqa: E402

SRC = str(Path(__file__).resolve().parents[1] / "src")
SIMULATE = ["simulate", "psm", "--experiment", "sine", "--controller", "scheduled", "--duration", "31", "--json"]


def fresh(args: list[str], src: str = SRC) -> float:
    """Wall seconds of ``python args`` in a new process with ``src`` first on the path."""
    return fresh_times(args, src)[0]


def fresh_times(args: list[str], src: str = SRC) -> tuple[float, float]:
    """Wall and CPU seconds (user + system, its child processes included) of ``python args`` in a
    new process with ``src`` first on the path."""
    return fresh_run(args, src)[:2]


def commands(out: str, report: bool = False) -> dict[str, list[str]]:
    cases = {"import pinocchio": ["-c", "import pinocchio"],
             "import matplotlib.pyplot": ["-c", "import matplotlib.pyplot"],
             "import matplotlib Figure, Agg": ["-c", "import matplotlib.figure, matplotlib.backends.backend_agg"],
             "rcm-kin --help": ["-m", "rcm_kin.cli", "--help"],
             "simulate (31 s, scheduled)": ["-m", "rcm_kin.cli", *SIMULATE],
             "torque-map psm --out (61 x 61)": ["-m", "rcm_kin.cli", "torque-map", "psm", "--out", out],
             "torque-map psm --no-figures": ["-m", "rcm_kin.cli", "torque-map", "psm", "--out", f"{out}/tables",
                                             "--no-figures"]}
    if report:
        cases["report --out (warm)"] = ["-m", "rcm_kin.cli", "report", "--out", f"{out}/report"]
    return cases


def fresh_processes(repeats: int, against: str | None, report: bool = False) -> None:
    sources = {"this": SRC} | ({"against": against} if against else {})
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as out:
        cases = commands(out, report)
        best = {(name, label): (float("inf"), float("inf")) for name in cases for label in sources}
        for name, args in cases.items():           # warm the caches
            for src in sources.values():
                fresh(args, src)
        for _ in range(repeats):                   # interleaved: the machine's load falls on all alike
            for name, args in cases.items():
                for label, src in sources.items():
                    best[name, label] = tuple(map(min, best[name, label], fresh_times(args, src)))
    # the same command under each source: its best time is the base of every ratio (wall and CPU)
    wall, cpu = (min(best["import pinocchio", label][k] for label in sources) for k in (0, 1))
    print(f"fresh processes, best of {repeats} (load average {load:.2f} before, {os.getloadavg()[0]:.2f} after); "
          f"import pinocchio {wall:.3f} s wall, {cpu:.3f} s CPU; ratios wall (CPU)")
    for name in cases:
        row = "  ".join(f"{label} {best[name, label][0]:6.3f} s = {best[name, label][0] / wall:5.2f}x "
                        f"({best[name, label][1] / cpu:5.2f}x)" for label in sources)
        print(f"  {name:32} {row}")


def in_process() -> None:
    sys.path.insert(0, SRC)
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.simulation.compiled_loop import loop_law, simulate_compiled
    from rcm_kin.simulation.experiments import (
        experiment_reference,
        named_controller,
        psm_plant_and_schedule,
        run_experiment,
    )
    from rcm_kin.simulation.firmware import FirmwareSettings

    params, settings = load_drive_parameters(), FirmwareSettings()
    run_experiment("sine", "scheduled", 31.0, params, settings)
    whole = best_of(lambda: run_experiment("sine", "scheduled", 31.0, params, settings), 3)
    plant, _ = psm_plant_and_schedule(params, settings.period, fast=True)
    law = loop_law(named_controller("scheduled", params))
    reference = experiment_reference("sine", settings.period, 31.0)
    kernel = best_of(lambda: simulate_compiled(plant, law, "scheduled", reference, settings), 3)
    ticks = reference.time.size + round(1.0 / settings.period)
    print(f"in process, per controller period (31 s + 1 s settling, {ticks} periods): run_experiment "
          f"{whole / ticks * 1e6:.2f} us, the kernel alone {kernel / ticks * 1e6:.2f} us = {whole / kernel:.2f}x")


FIGURES = """
import sys, time
import numpy as np
from types import SimpleNamespace
from rcm_kin import load_robot, plotting
from rcm_kin.statics.holding import torque_map
from rcm_kin.statics.maps import gravity_map, map_drive
psm = load_robot("psm"); drive = map_drive(psm, None); grid = np.linspace(-30, 30, 61)
gmap = gravity_map(psm, drive, grid, grid, [0.08])
sweep = gravity_map(psm, drive, (0.0, 20.0), (-20.0, 0.0, 20.0), np.linspace(0.0, 0.16, 81))
mtm = load_robot("mtm"); tmap = torque_map(mtm, {"j1": np.radians(grid), "j3": np.radians(grid)})
t = np.linspace(0.0, 4.0, 1601); wave = np.column_stack([np.sin(3 * t), np.cos(2 * t)])
run = SimpleNamespace(time=t, reference=wave, measured=0.9 * wave, error=0.1 * wave, pwm=-80 * wave, controller="p")
out = sys.argv[1]
draws = {"torque-map: heat maps": lambda: plotting.effort_heatmaps(gmap, drive, f"{out}/a.png"),
         "torque-map: trend curves": lambda: plotting.thesis_trend_curves(gmap, f"{out}/b.png"),
         "torque-map: insertion curves": lambda: plotting.insertion_curves(sweep, f"{out}/c.png"),
         "report: a tracking figure": lambda: plotting.tracking_figure(run, f"{out}/d.png", "sine, p:"),
         "report: the MTM's torque map": lambda: plotting.torque_heatmaps(tmap, f"{out}/e.png")}
start = time.process_time()
import matplotlib.figure, matplotlib.backends.backend_agg
print("import matplotlib", time.process_time() - start)
for name, draw in draws.items():
    times = []
    for _ in range(4):
        start = time.process_time(); draw(); times.append(time.process_time() - start)
    print(name, times[0], min(times[1:]))
"""


def figures(against: str | None) -> None:
    """CPU seconds of each figure in a fresh process per source: the first drawing (fonts and
    caches cold) and the best of three more."""
    print("figures, CPU s in process (first drawing, best of 3 after):")
    with tempfile.TemporaryDirectory() as out:
        for label, src in ({"this": SRC} | ({"against": against} if against else {})).items():
            env = child_env(src)
            lines = subprocess.run([sys.executable, "-c", FIGURES, out], env=env, check=True, capture_output=True,
                                   text=True).stdout.splitlines()
            for line in lines:
                name, *numbers = line.rsplit(" ", 2) if line.startswith(("torque", "report")) else line.rsplit(" ", 1)
                print(f"  {label:8} {name:32} " + "  ".join(f"{float(x):.3f}" for x in numbers))


ROBUSTNESS = ["-m", "rcm_kin.cli", "robustness", "psm", "--controller", "p", "--controller", "scheduled",
              "--experiment", "sine", "--json", "--samples"]


def robustness(repeats: int, against: str | None) -> None:
    sys.path.insert(0, SRC)
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.simulation.experiments import run_experiment

    params = load_drive_parameters()
    for name in ("p", "scheduled"):
        run_experiment("sine", name, None, params)
    simulation = best_of(lambda: [run_experiment("sine", name, None, params) for name in ("p", "scheduled")], 3)
    for label, src in ({"this": SRC} | ({"against": against} if against else {})).items():
        runs = {n: min(fresh(ROBUSTNESS + [str(n)], src) for _ in range(repeats)) for n in (8, 32)}
        sample = (runs[32] - runs[8]) / 24
        print(f"robustness ({label}): 8 samples {runs[8]:.2f} s, 32 samples {runs[32]:.2f} s: a sample "
              f"{sample:.3f} s = {sample / simulation:.1f}x the in-process simulation of both controllers "
              f"({simulation:.3f} s)")


FIRST_SAMPLE = ["-c", """
import time
from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.model import load_robot
from rcm_kin.robustness.sampling import sample_seeds, uncertain_parameters
from rcm_kin.robustness.task import Study, run_batch
params = load_drive_parameters()
load_robot("psm")
study = Study(params, uncertain_parameters(params), ("p", "scheduled"), "sine")
seeds = list(enumerate(sample_seeds(0, 2)))
start = time.perf_counter(); run_batch(study, seeds[:1]); middle = time.perf_counter(); run_batch(study, seeds[1:])
print(middle - start, time.perf_counter() - middle)
"""]


def first_samples(rounds: int, against: str | None) -> None:
    """In process, in fresh processes as a forked worker starts: the first robustness sample (its
    plant family and parametric model built, compiled libraries loaded) and the second, interleaved
    rounds, best and median."""
    sources = {"this": SRC} | ({"against": against} if against else {})
    times = {label: [] for label in sources}
    for _ in range(rounds):
        for label, src in sources.items():
            times[label].append([float(x) for x in fresh_run(FIRST_SAMPLE, src)[2].split()])
    for label, pairs in times.items():
        first, second = sorted(p[0] for p in pairs), sorted(p[1] for p in pairs)
        print(f"robustness in process ({label}): first sample {first[0]:.3f} s best, {first[len(first) // 2]:.3f} s "
              f"median; second {second[0]:.3f} s, {second[len(second) // 2]:.3f} s ({rounds} fresh processes)")


def compiler_calls(src: str = SRC) -> None:
    """Compiler runs of ``robustness`` on an empty cache (8 samples, seed 0), then of 32 samples
    drawn from another seed on that cache: with the plant family and the shared model
    (:mod:`rcm_kin.simulation.plant_family`), none after the first sample's libraries."""
    with tempfile.TemporaryDirectory() as folder:
        log, wrapper = Path(folder) / "calls.log", Path(folder) / "cc"
        wrapper.write_text(f'#!/bin/sh\necho "$@" >> {log}\nexec cc "$@"\n')
        wrapper.chmod(0o755)
        env = child_env(src, CC=str(wrapper), XDG_CACHE_HOME=folder)
        counts = []
        for samples, seed in ((8, 0), (32, 1)):
            subprocess.run([sys.executable, *ROBUSTNESS, str(samples), "--seed", str(seed)], env=env, check=True,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            counts.append(len(log.read_text().splitlines()) if log.exists() else 0)
        print(f"compiler runs on an empty cache: 8 samples {counts[0]}, then 32 samples of another seed "
              f"{counts[1] - counts[0]} more")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--against", help="another checkout's src folder, run in the same rounds")
    parser.add_argument("--skip-fresh", action="store_true")
    parser.add_argument("--robustness", action="store_true", help="also the robustness samples (about a minute)")
    parser.add_argument("--report", action="store_true", help="also the warm report (10-20 s a run)")
    parser.add_argument("--figures", action="store_true", help="also each figure's drawing in process")
    args = parser.parse_args()
    if not args.skip_fresh:
        fresh_processes(args.repeats, args.against, args.report)
    if args.figures:
        figures(args.against)
    in_process()
    if args.robustness:
        robustness(max(1, args.repeats // 2), args.against)
        first_samples(max(5, args.repeats), args.against)
        compiler_calls()


if __name__ == "__main__":
    main()

"""Wall time of the shipped tuning (``rcm-kin schedule psm --tune``) on 2 cores, and closed-loop runs
per second of the compiled loop it simulates, beside one readable-loop run, same run.

1. The command itself, in this process: ``rcm_kin.cli.main(["schedule", "psm", "--tune", "--out", TMP,
   "--workers", "2", ...])`` with the settings of the shipped study (``tuning.SHIPPED_STUDY``, its
   draws, seeds, ``--budget`` and ``--generations``; the command's defaults where there is none: 64
   draws per set, seeds 0 and 1, 16 tuned on), i.e. ``design_study(load_drive_parameters(), 64, 0, 1,
   16, budget_s, workers=2, generations=G)`` (:mod:`rcm_kin.tuning.study`) and then the 41 x 41
   stability survey, the files and the figures; and whether the design equals the shipped one (a
   generations limit makes the search independent of the machine's speed). Timed: the command and
   the study (wall; CPU of this process and of its forked workers) and the study's phases, each by wrapping
   the function ``design_study`` calls (one clock read per call; the wrapper also keeps the study it
   returned): the LQR/LQI schedule (``psm_schedule``), the two draw sets (``build_draws``, 41 x 41
   frozen loops each), the two searches (``tune``: the thesis law on the draws, the differential
   evolution ``searches[k].minimum.wall_s``, the winner judged again), the scheduled winner without
   its slopes (``judge``), the four laws judged on both draw sets (``judge_all``) and the structure
   variants (``judge_variants``). Target (issue): the study under 600 s on 2 cores. Not counted: the
   imports (about 1 s).
2. Closed-loop runs per second during tuning: the searches' own figure (``searches[k].runs_per_s``:
   runs per second of one worker's wall time, everything a candidate costs), and measured directly
   after the study on the first ``--loop-draws`` tuning draws (``build_draws(params, n, seed)``)
   with the chosen design (``tuned_controller(tuned_schedule(psm_schedule(params), study.values))``),
   per experiment (sine 6 s, target 4 s, each after the loop's 1 s of settling, 400 Hz):
   - compiled: ``closed_loop(draw.plant, controller, reference, settings, hold=draw.holds[e])``
     (``fast=True``, the compiled C kernel), best of ``--repeats`` passes over the draws;
   - the objective around it: ``evaluate`` (adds the joint-range check and the tracking metrics)
     and ``judge`` (adds building the candidate's schedule and controller and the frozen-loop
     spectral radius on the 9 x 9 tuning grid of every draw), per run;
   - ONE readable-loop run of the same controller, plant, reference and hold on the first draw
     (``closed_loop(..., fast=False)``, :func:`rcm_kin.simulation.loop.simulate`, the plain Python
     loop and the compiled loop's fallback; after one short untimed run, 1.1 s simulated, so its
     first-call costs are not counted), the ratio compiled / readable, and whether the two runs
     agree tick for tick (``bench_simulation.tick_for_tick``).
   The plain call a user would write without the toolkit has no control law, quantisation or
   stick-slip drive trains; for scale, ``bench_simulation.pinocchio_period`` (Pinocchio ``crba`` +
   ``nonLinearEffects`` + a 3 x 3 solve, semi-implicit Euler x 4, on the smooth model) timed per
   period and multiplied by a run's periods: the runs per second of the plant alone in a Python
   loop, an upper bound for such a loop.

    python benchmarks/bench_tuning.py [--quick] [--budget S] [--generations G] [--workers 2]
                                      [--loop-draws 4] [--repeats 3]
``--quick``: ``--draws 8 --tune-draws 4 --budget 20`` (about a minute; a smoke run, not the shipped
design); ``--budget``, ``--generations``, ``--workers``: passed to the command. On a machine shared
with other work the wall times grow with its load: the load average is printed before and after,
and the CPU share beside the wall time.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402
from bench_simulation import pinocchio_period, tick_for_tick  # noqa: E402
from common import best_of, per_call  # noqa: E402

import rcm_kin.tuning.study as study_module  # noqa: E402
from rcm_kin import load_robot  # noqa: E402
from rcm_kin.cli import main as cli_main  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.simulation.controllers import ThesisController  # noqa: E402
from rcm_kin.simulation.experiments import closed_loop, psm_schedule  # noqa: E402
from rcm_kin.tuning.design import tuned_schedule  # noqa: E402
from rcm_kin.tuning.draws import build_draws  # noqa: E402
from rcm_kin.tuning.objective import evaluate  # noqa: E402
from rcm_kin.tuning.optimise import judge, tuned_controller  # noqa: E402

QUICK = ["--draws", "8", "--tune-draws", "4", "--budget", "20"]    # a smoke run, not the shipped design
TARGET = 600.0            # s: the shipped design study on 2 cores (issue)
SETTLE = 1.0              # s the loop holds the first pose before t = 0 (simulate's default)
PHASES = ("psm_schedule", "build_draws", "tune", "judge", "judge_all", "judge_variants")   # what design_study calls

# the objective's statistics over a draw set where every run of a candidate was unstable (a penalty, not a fault)
warnings.filterwarnings("ignore", message="All-NaN slice encountered", category=RuntimeWarning)


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def cpu_seconds() -> tuple[float, float]:
    """User + system CPU seconds of this process and of its waited-for children (the forked workers)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime, children.ru_utime + children.ru_stime


@contextmanager
def phase_clocks(module, names):
    """Wrap ``module.<name>`` for each name it has with a wall clock and keep what each call returned;
    yields ``{name: [(seconds, returned) per call]}``."""
    clocks = {name: [] for name in names if hasattr(module, name)}
    originals = {name: getattr(module, name) for name in clocks}

    def clocked(name, function):
        def run(*args, **kwargs):
            start = time.perf_counter()
            result = function(*args, **kwargs)
            clocks[name].append((time.perf_counter() - start, result))
            return result
        return run

    for name, function in originals.items():
        setattr(module, name, clocked(name, function))
    try:
        yield clocks
    finally:
        for name, function in originals.items():
            setattr(module, name, function)


def shipped_command(argv: list[str]):
    """``rcm-kin schedule psm --tune --out TMP ARGV`` in this process: the study it ran, the command's
    wall seconds, the CPU seconds (this process, the forked workers) and the clocks of ``design_study``
    and of what it calls."""
    own, children = cpu_seconds()
    with tempfile.TemporaryDirectory() as out, phase_clocks(study_module, ("design_study",) + PHASES) as clocks:
        start = time.perf_counter()
        status = cli_main(["schedule", "psm", "--tune", "--out", out, *argv])
        wall = time.perf_counter() - start
    if status:
        raise SystemExit(f"rcm-kin schedule psm --tune {' '.join(argv)} failed (status {status})")
    own_after, children_after = cpu_seconds()
    return clocks.pop("design_study")[0], wall, (own_after - own, children_after - children), clocks


def report_study(study, seconds: float, wall: float, cpu: tuple[float, float], clocks: dict) -> None:
    def total(name):
        return sum(t for t, _ in clocks.get(name, ()))

    def each(name):
        return " + ".join(f"{t:.1f}" for t, _ in clocks.get(name, ()))

    print(f"\ndesign study: {seconds:.1f} s wall ({'meets' if seconds < TARGET else 'MISSES'} the {TARGET:.0f} s "
          f"target); the whole command {wall:.1f} s (+ {wall - seconds:.1f} s: 41 x 41 survey, files, figures); "
          f"CPU {cpu[0]:.1f} s this process + {cpu[1]:.1f} s its workers = {(cpu[0] + cpu[1]) / wall:.2f} cores "
          f"busy on average; chosen: {study.chosen}")
    rows = [("LQR/LQI schedule (psm_schedule)", total("psm_schedule"), ""),
            (f"draws: tuning + held-out ({study.samples} each, 41 x 41 loops; build_draws)", total("build_draws"),
             each("build_draws"))]
    for (kind, search), (seconds_k, _) in zip(study.searches.items(), clocks["tune"]):
        m = search.minimum
        rows.append((f"search {kind} (tune; {study.tune_samples} draws, 9 x 9 loops)", seconds_k,
                     f"search {m.wall_s:.1f} s ({m.stopped}, {len(m.history)} generations, {m.evaluations} "
                     f"candidates); the thesis law and the winner on the draws {seconds_k - m.wall_s:.1f} s"))
    if "judge" in clocks:
        rows.append(("the scheduled winner without slopes (judge)", total("judge"), each("judge")))
    rows.append((f"judging 4 laws on both draw sets (judge_all, {study.samples} draws x 2 experiments)",
                 total("judge_all"), each("judge_all")))
    if "judge_variants" in clocks:
        rows.append(("structure variants on both draw sets (judge_variants)", total("judge_variants"),
                     each("judge_variants")))
    rows.append(("rest of design_study", seconds - sum(total(name) for name in clocks), ""))
    width = max(len(r[0]) for r in rows)
    for name, phase_s, note in rows:
        print(f"  {name:{width}}  {phase_s:7.1f} s  {note}")


def loop_rates(params, study, loop_draws: int, repeats: int) -> None:
    """Runs per second of the compiled loop (bare and inside the objective) and of one readable run."""
    base = psm_schedule(params)
    values = study.values
    draws = build_draws(params, loop_draws, study.seeds[0])          # the first tuning draws, 9 x 9 loops
    controller = tuned_controller(tuned_schedule(base, values))
    experiments = tuple(draws.references)
    print(f"\nclosed loop, the chosen ({study.chosen}) design on the first {loop_draws} tuning draws "
          f"(load {load()}); runs per second, best of {repeats}:")
    for d in draws.draws:                                   # warm-up: kernel cache load, each plant
        for e in experiments:
            closed_loop(d.plant, controller, draws.references[e], draws.settings, hold=d.holds[e])
    short = {e: replace(r, **{f: getattr(r, f)[:40] for f in ("time", "position", "velocity", "acceleration")})
             for e, r in draws.references.items()}
    for e in experiments:                                   # and the readable loop's first call (1.1 s simulated)
        closed_loop(draws.draws[0].plant, controller, short[e], draws.settings, hold=draws.draws[0].holds[e],
                    fast=False)
    header = (f"  {'experiment':10} {'ticks':>5}  {'compiled':>9}  {'sim s/wall s':>12}  {'readable (1 run)':>16}  "
              f"{'compiled/readable':>17}  {'tick for tick':>13}")
    print(header)
    compiled_rates = {}
    for e in experiments:
        reference, first = draws.references[e], draws.draws[0]
        ticks = reference.time.size + int(round(SETTLE / draws.settings.period))
        seconds = per_call(lambda: [closed_loop(d.plant, controller, reference, draws.settings, hold=d.holds[e])
                                    for d in draws.draws], 1, repeats) / len(draws)
        compiled = closed_loop(first.plant, controller, reference, draws.settings, hold=first.holds[e])
        start = time.perf_counter()
        readable = closed_loop(first.plant, controller, reference, draws.settings, hold=first.holds[e], fast=False)
        readable_s = time.perf_counter() - start
        same = compiled.engine == "compiled" and readable.engine == "readable" and tick_for_tick(compiled, readable)
        compiled_rates[e] = 1 / seconds
        print(f"  {e:10} {ticks:5d}  {1 / seconds:7.1f}/s  {ticks * draws.settings.period / seconds:10.0f} x  "
              f"{1 / readable_s:14.2f}/s  {readable_s / seconds:15.0f} x  {'equal' if same else 'DIFFERS':>13}")
    runs = len(draws) * len(experiments)
    baseline = evaluate(ThesisController(), draws)
    objective = best_of(lambda: evaluate(controller, draws), repeats) / runs
    judged = best_of(lambda: judge(values, base, draws, baseline), repeats) / runs
    mixed = runs / sum(len(draws) / compiled_rates[e] for e in experiments)
    print(f"  both experiments, as the tuning runs them: compiled loop {mixed:.1f} runs/s; inside the objective "
          f"(evaluate: + range check, metrics) {1 / objective:.1f} runs/s; a whole candidate (judge: + schedule, "
          f"controller, frozen-loop radius on 9 x 9 poses) {1 / judged:.1f} runs/s")
    for kind, search in study.searches.items():
        print(f"  search {kind}: {search.runs_per_s:.1f} runs/s per worker (runs_per_s: every candidate's runs over "
              f"the search's wall time x workers)")
    psm = load_robot("psm")
    plain = pinocchio_period(psm, params)
    position = draws.references["sine"].position[0]
    q, v = psm.to_reduced(np.r_[position, np.zeros(psm.nq - 3)]), np.zeros(psm.reduced.nv)
    period_s = per_call(lambda: plain(q, v, np.array([-20.0, -80.0, 5.0])), 500, repeats)
    ticks = draws.references["sine"].time.size + int(round(SETTLE / draws.settings.period))
    print(f"  plain Pinocchio plant period in Python (crba + nle + solve, Euler x 4, smooth model, no controller): "
          f"{period_s * 1e6:.0f} us, so {1 / (period_s * ticks):.2f} sine runs/s at best "
          f"(the compiled loop {compiled_rates['sine'] * period_s * ticks:.0f} x that)")


def shipped_settings() -> tuple[list[str], str]:
    """The command's flags that reproduce the shipped study (its ``tuning.json``: draws, seeds, the
    time budget and the generations limit), or none (the command's defaults) when there is none."""
    path = getattr(study_module, "SHIPPED_STUDY", None)
    if path is None or not path.is_file():
        return [], "the command's defaults (no shipped study found)"
    data = json.loads(path.read_text())
    argv = ["--draws", str(data["samples"]), "--tune-draws", str(data["tune_samples"]),
            "--seed", str(data["seeds"]["tuning"]), "--check-seed", str(data["seeds"]["held_out"])]
    if data.get("budget_s") is not None:
        argv += ["--budget", f"{data['budget_s']:g}"]
    if data.get("generations_limit") is not None:
        argv += ["--generations", str(data["generations_limit"])]
    return argv, f"the shipped study's settings ({path.name})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="8 draws per set, 4 tuned on, 20 s of search (~1 min)")
    parser.add_argument("--budget", help="the command's --budget (default: the shipped study's, else the command's)")
    parser.add_argument("--generations", help="the command's --generations (default: as --budget)")
    parser.add_argument("--workers", default="2", help="the command's --workers (default 2)")
    parser.add_argument("--loop-draws", type=int, default=4, help="tuning draws of the direct loop timing")
    parser.add_argument("--repeats", type=int, default=3, help="passes of the direct loop timing, best taken")
    args = parser.parse_args()
    argv, origin = (QUICK, "--quick") if args.quick else shipped_settings()
    argv = argv + ["--workers", args.workers]
    argv += [a for flag, value in (("--budget", args.budget), ("--generations", args.generations)) if value
             for a in (flag, value)]                         # later flags win (argparse)
    print(f"rcm-kin schedule psm --tune --out TMP {' '.join(argv)} (in this process; {origin}); "
          f"load average {load()} on {os.cpu_count()} cores")
    (seconds, study), wall, cpu, clocks = shipped_command(argv)
    print(f"the study: samples={study.samples}, seeds={study.seeds}, tune_samples={study.tune_samples}, "
          f"budget_s={getattr(study, 'budget_s', float('nan')):g}, generations={getattr(study, 'generations', None)}")
    path = getattr(study_module, "SHIPPED_STUDY", None)
    if not args.quick and path is not None and path.is_file():
        shipped = json.loads(path.read_text())
        same = shipped["chosen"] == study.chosen and shipped["values"] == study.values
        print(f"the design {'equals' if same else 'DIFFERS from'} the shipped one ({path})")
    report_study(study, seconds, wall, cpu, clocks)
    loop_rates(load_drive_parameters(), study, args.loop_draws, args.repeats)
    print(f"\nload average at the end {load()}")


if __name__ == "__main__":
    main()

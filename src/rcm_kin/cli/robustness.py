"""``robustness``: controllers over the parameter uncertainty; ``sweep``: design trade-offs. Both
run on Dask (an embedded local cluster, or ``--scheduler tcp://HOST:PORT``); a small robustness run
without ``--scheduler`` on a pool of forked processes instead."""

from __future__ import annotations

import contextlib

from rcm_kin.cli.common import (
    RAW,
    add_json,
    add_params,
    count,
    emit,
    finite,
    path_text,
    progress_wanted,
    psm_robot,
    require_psm,
)
from rcm_kin.cli.outputs import FOLDER_FORCE, new_folder
from rcm_kin.errors import RcmKinError
from rcm_kin.simulation.controllers import CONTROLLERS

EPILOG_ROBUSTNESS = (
    "examples: rcm-kin robustness psm --controller p --controller scheduled --experiment sine --samples 64 --json\n"
    "          rcm-kin robustness psm --controller scheduled --experiment sine --samples 1000 "
    "--scheduler tcp://10.0.0.5:8786\n"
    "          rcm-kin robustness psm --controller scheduled --experiment sine --samples 64 "
    "--uncertainty identify.json\n"
    "(errors in deg over each run; spreads: p5/median/p95/worst over the samples; the same --seed gives the same "
    "numbers on any cluster)")
EPILOG_SWEEP = (
    "examples: rcm-kin sweep psm counterweights --main-mass 1 2 3 4 --dpm-mass 0.5 1 1.5 --out sweep\n"
    "          rcm-kin sweep psm weights --error-deg 0.5 1 2 4 --pwm-fraction 0.5 1 --out sweep "
    "--scheduler tcp://10.0.0.5:8786")


def add_scheduler(p) -> None:
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on the Dask cluster of this scheduler (tcp://HOST:PORT; start one with `dask scheduler` "
                        "and workers with `dask worker ADDRESS`); default: an embedded local cluster "
                        "(robustness: up to 64 samples on a pool of local processes, no cluster)")
    p.add_argument("--workers", type=count(1, 256, "workers"),
                   help="worker processes of the embedded cluster or the local pool (default: one per core)")


def add_robustness(sub) -> None:
    p = sub.add_parser("robustness", help="Monte Carlo of controllers over the identified parameter uncertainty",
                       parents=[psm_robot()], epilog=EPILOG_ROBUSTNESS, formatter_class=RAW)
    p.add_argument("--controller", action="append", required=True, choices=CONTROLLERS,
                   help="a controller to judge (repeat the option for several; as in `simulate`)")
    p.add_argument("--experiment", required=True, choices=("sine", "step", "target"),
                   help="the experiment each sample runs (as in `simulate`)")
    p.add_argument("--samples", type=count(1, 1_000_000, "samples"), required=True, help="parameter sets drawn")
    p.add_argument("--seed", type=count(0, 2**32 - 1, ""), default=0,
                   help="seed of the draws (default 0): sample i uses "
                                                       "SeedSequence(seed).spawn(samples)[i]")
    p.add_argument("--duration", type=finite(0.0, 10_000.0, "s", open_lo=True),
                   help="simulated seconds (default: the experiment's, as `simulate`)")
    p.add_argument("--skip", type=finite(0.0, 10_000.0, "s"), default=0.0,
                   help="leave the first S seconds out of the statistics (0)")
    add_params(p, "nominal drive parameter TOML: the schedule is designed on it (default: the shipped set)")
    p.add_argument("--uncertainty", metavar="FILE",
                   help="`rcm-kin identify ... --json` output: its (jackknife, else Gauss-Newton) standard errors "
                        "set the drive trains' spreads (default: the stated default spreads)")
    p.add_argument("--batch-size", type=count(1, 1_000_000, "samples"),
                   help="samples per Dask task (default: about 4 tasks per worker)")
    add_scheduler(p)
    p.add_argument("--out", metavar="DIR", type=path_text, help="write the empirical-CDF figure (PNG) into DIR")
    p.add_argument("--force", action="store_true", help=FOLDER_FORCE)
    add_json(p, '{"samples", "seed", "experiment", "controllers": {NAME: {"roll": {"max_error_deg": {"p5", "median", '
                '"p95", "worst"}, "mean_error_deg": {...}, "saturated_fraction"}, "pitch": {...}, "unstable_fraction", '
                '"stability": {...} | null}}, "uncertainty": {PARAMETER: {"nominal", "sigma", "distribution", '
                '"source"}}, "drive_train_source": {JOINT: "fold sets (N) and the own set" | "spreads (...)"}}')
    p.set_defaults(func=cmd_robustness)


def cmd_robustness(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.parallel import dask_client
    from rcm_kin.robustness.execution import run_robustness
    from rcm_kin.robustness.sampling import drive_train_sources, read_standard_errors, uncertain_parameters
    from rcm_kin.robustness.task import Study
    from rcm_kin.robustness.work import check_robustness

    require_psm(args, "the robustness runs simulate the PSM's driven joints, not '{robot}'")
    if args.workers is not None and args.scheduler:
        raise RcmKinError("--workers sizes the embedded cluster; a --scheduler's cluster has its own workers")
    params = load_drive_parameters(args.params)
    errors = read_standard_errors(args.uncertainty) if args.uncertainty else None
    study = Study(params, uncertain_parameters(params, errors), tuple(dict.fromkeys(args.controller)),
                  args.experiment, args.duration, args.skip)
    check_robustness(study, args.samples)
    out = new_folder(args.out, args.force) if args.out else None
    # without --scheduler, run_robustness chooses: a pool of forked processes for a small run, else an
    # embedded cluster of --workers
    with dask_client(args.scheduler) if args.scheduler else contextlib.nullcontext() as client:
        result = run_robustness(study, args.samples, args.seed, client, args.batch_size, progress=progress_wanted(args),
                                workers=args.workers)
    lines = [f"{args.experiment}: {result.samples} samples (seed {args.seed}); max error deg p5/median/p95/worst"]
    for name, c in result.controllers.items():
        cells = [f"{axis} " + "/".join(f"{v:.2f}" for v in vars(a.max_error_deg).values())
                 for axis, a in c.axes.items()]
        radius = (f"400 Hz radius median {c.firmware_spectral_radius.median:.4f} worst "
                  f"{c.firmware_spectral_radius.worst:.4f}" if c.has_margin else "no linear margin")
        lines.append(f"  {name:20} {'  '.join(cells)}  unstable {c.unstable_fraction:.0%}  {radius}")
    lines += [f"drive train {joint}: {source}" for joint, source in drive_train_sources(study.uncertain).items()]
    if out:
        from rcm_kin.robustness.figures import robustness_figure

        lines.append(f"wrote {robustness_figure(result, out / f'robustness_{args.experiment}.png')}")
    emit(args, result.as_dict(), "\n".join(lines))


def add_sweep(sub) -> None:
    from rcm_kin.hardware import DPM_COUNTERWEIGHT, MAIN_COUNTERWEIGHT

    p = sub.add_parser("sweep", help="design sweeps (counterweights, LQR/LQI budgets): a table and a trade-off figure",
                       parents=[psm_robot()], epilog=EPILOG_SWEEP, formatter_class=RAW)
    p.add_argument("design", choices=("counterweights", "weights"),
                   help="counterweights: masses against holding effort over the workspace; weights: LQR/LQI budgets "
                        "against tracking and PWM use on the sinusoid")
    p.add_argument("--main-mass", nargs="+", type=finite(0.0, 100.0, "kg", open_lo=True),
                   default=[MAIN_COUNTERWEIGHT[0] * f for f in (0.5, 0.75, 1, 1.25)],
                   help="counterweights: main counterweight masses, kg (default: 0.5-1.25 x osMDV's)")
    p.add_argument("--dpm-mass", nargs="+", type=finite(0.0, 100.0, "kg", open_lo=True),
                   default=[DPM_COUNTERWEIGHT[0] * f for f in (0.5, 1, 1.5)],
                   help="counterweights: DPM counterweight masses, kg (default: 0.5-1.5 x osMDV's)")
    p.add_argument("--points", type=count(2, 201, "points per axis"), default=13,
                   help="counterweights: workspace grid points per axis (13)")
    p.add_argument("--error-deg", nargs="+", type=finite(0.0, 90.0, "deg", open_lo=True), default=[0.5, 1.0, 2.0, 4.0],
                   help="weights: roll and pitch error budgets, deg (default 0.5 1 2 4)")
    p.add_argument("--pwm-fraction", nargs="+", type=finite(0.0, 1.0, open_lo=True), default=[0.5, 1.0],
                   help="weights: PWM budgets as fractions of the firmware limits (default 0.5 1)")
    p.add_argument("--duration", type=finite(0.0, 600.0, "s", open_lo=True),
                   help="weights: simulated seconds of the sinusoid (default 6)")
    add_params(p)
    add_scheduler(p)
    p.add_argument("--out", metavar="DIR", type=path_text, required=True, help="folder for sweep_<design>.csv and .png")
    p.add_argument("--force", action="store_true", help=FOLDER_FORCE)
    add_json(p, '{"design", "rows": [{column: value}], "table", "figure"}')
    p.set_defaults(func=cmd_sweep)


def cmd_sweep(args) -> None:
    from dataclasses import asdict
    from itertools import product

    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.parallel import dask_client, map_batches
    from rcm_kin.robustness import figures, sweeps
    from rcm_kin.robustness.work import check_counterweight_sweep, check_weights_sweep

    require_psm(args, "the design sweeps are of the PSM, not '{robot}'")
    params = load_drive_parameters(args.params)
    if args.design == "counterweights":
        check_counterweight_sweep(len(args.main_mass), len(args.dpm_mass), args.points)
        points, task, shared = list(product(args.main_mass, args.dpm_mass)), sweeps.counterweight_batch, \
            {"params": params, "points": args.points}
    else:
        check_weights_sweep(len(args.error_deg), len(args.pwm_fraction), args.duration)
        points, task, shared = list(product(args.error_deg, args.pwm_fraction)), sweeps.weights_batch, \
            {"params": params, "duration": args.duration}
    out = new_folder(args.out, args.force)
    with dask_client(args.scheduler, args.workers) as client:
        batches = [[point] for point in points]
        rows = [row for batch in map_batches(client, task, batches, progress_wanted(args), f"sweep {args.design}",
                                             **shared) for row in batch]
    table = sweeps.write_table(rows, out / f"sweep_{args.design}.csv")
    draw = figures.counterweight_figure if args.design == "counterweights" else figures.weights_figure
    figure = draw(rows, out / f"sweep_{args.design}.png")
    payload = {"design": args.design, "rows": [asdict(r) for r in rows], "table": str(table), "figure": str(figure)}
    emit(args, payload, f"{len(rows)} {args.design} designs\nwrote {table}\nwrote {figure}")

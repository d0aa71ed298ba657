"""``schedule psm --tune``: gains chosen by simulating the closed loop over the identified
uncertainty, judged beside the thesis law on draws the tuning saw and on draws it did not."""

from __future__ import annotations

import json
import os

from rcm_kin.atomic import write_text
from rcm_kin.cli.common import count, emit, finite, progress_wanted
from rcm_kin.cli.outputs import new_folder
from rcm_kin.control.friction import DEFAULT_RAMP_DEG_S
from rcm_kin.errors import RcmKinError

TUNE_HELP = ("tune the firmware law by simulation instead of designing it by LQR/LQI: differential evolution "
             "over a fixed and a pose-scheduled gain set (Kp, Kd of both axes, pitch Ki, friction compensation, "
             "pitch feedforward scale), minimising on the thesis sinusoid and target runs (from 1 s) the mean plus "
             "the largest of twelve ratios to the thesis law on the same draws (p90 and worst max error, median "
             "mean error, per experiment and axis) subject to: no unstable run, the frozen-gain 400 Hz loop's "
             "spectral radius < 0.999 at every pose of a 9 x 9 grid of every tuned-on draw, no more PWM saturation "
             "than the thesis law, gains whose one-count quantisation moves the PWM by at most 10 counts; then "
             "the Kp slopes over roll and pitch from that gain set; the design is chosen on --draws (seed --seed) "
             "and checked on --draws held out (seed --check-seed), the loop on 41 x 41 poses; writes the chosen design "
             "(gains.json, gains.csv, gain_schedule.h with its law, gravity and friction feedforward), "
             "tuning.json, tuning.png and tuning_gains.png")


def add_tune_options(p) -> None:
    """The ``--tune`` flag and its options on the ``schedule`` parser."""
    p.add_argument("--tune", action="store_true", help=TUNE_HELP)
    p.add_argument("--draws", type=count(8, 1024), default=None,
                   help="--tune: plants drawn per judging set, seeded (8 to 1024, default 64)")
    p.add_argument("--tune-draws", type=count(1, 1024), default=None,
                   help="--tune: the first N of them the search simulates (default 16)")
    p.add_argument("--seed", type=count(0, 2**32 - 1), default=None, help="--tune: seed of the tuning draws and the "
                   "search (default 0)")
    p.add_argument("--check-seed", type=count(0, 2**32 - 1), default=None,
                   help="--tune: seed of the held-out draws (default 1)")
    p.add_argument("--budget", type=finite(1, 86400, "s"), default=None,
                   help="--tune: seconds of search, 60 %% the gain set and 40 %% its pose slopes (default 300; the "
                        "whole run adds about 2 minutes of draws and judging on 2 cores)")
    p.add_argument("--generations", type=count(1, 100_000), default=None,
                   help="--tune: each search also stops after G generations (the same seed then gives the same "
                        "design on any machine; the shipped design: 20)")
    p.add_argument("--workers", type=count(1, 64), default=None,
                   help="--tune: processes scoring the candidates (default: 2, or 1 on one core)")


TUNE_OPTIONS = {"draws": 64, "tune_draws": 16, "seed": 0, "check_seed": 1, "budget": 300.0, "generations": None,
                "workers": min(2, os.cpu_count() or 1)}      # their defaults
LQR_OPTIONS = ("friction_ramp", "check_points", "gravity_feedforward", "friction_feedforward")


def check_tune_options(args, weights: dict) -> None:
    """Refuse the --tune options without --tune, and the LQR/LQI design's options with it (each
    would be silently ignored); fill the --tune options' defaults."""
    given = [name for name in TUNE_OPTIONS if getattr(args, name) is not None]
    if not args.tune:
        if given:
            raise RcmKinError(f"--{given[0].replace('_', '-')} is an option of --tune (the LQR/LQI design has no "
                              "draws, seeds or search)")
        return
    lqr = [name for name in LQR_OPTIONS if getattr(args, name) not in (None, False, DEFAULT_RAMP_DEG_S)]
    lqr += [name for name, value in weights.items() if getattr(args, name) != value]
    if lqr:
        raise RcmKinError(f"--{lqr[0].replace('_', '-')} is an option of the LQR/LQI design: --tune chooses the gains "
                          "and friction compensation itself, always with the gravity and friction feedforward, and "
                          "checks the loop on 41 x 41 poses")
    for name, value in TUNE_OPTIONS.items():
        if getattr(args, name) is None:
            setattr(args, name, value)
    if args.seed == args.check_seed:
        raise RcmKinError(f"--check-seed must differ from --seed (the held-out draws), got {args.seed} for both")


def run_tune(args, model) -> None:
    """``schedule psm --tune``: the design study, its files and summary."""
    from rcm_kin.codegen.firmware_export import write_gain_schedule
    from rcm_kin.control.stability import stability_survey
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.thesis import K_PITCH, K_ROLL
    from rcm_kin.tuning.figures import gains_figure, study_figure
    from rcm_kin.tuning.study import design_study

    if args.grid not in (None, ["thesis"]) or args.insertion is not None:
        raise RcmKinError("--tune designs on the thesis grid at the home insertion (roll -20,0,20 x pitch -15,0,15 "
                          "deg, 80 mm): leave out --grid and --insertion")
    if args.tune_draws > args.draws:
        raise RcmKinError(f"--tune-draws ({args.tune_draws}) is at most --draws ({args.draws})")
    folder = new_folder(args.out, args.force)
    study = design_study(load_drive_parameters(args.params), args.draws, args.seed, args.check_seed, args.tune_draws,
                         args.budget, args.workers, progress=progress_wanted(args),
                         generations=args.generations)
    survey = stability_survey(model, study.schedule, points=41)
    files = write_gain_schedule(study.schedule, folder, survey, gravity_feedforward=True, friction_feedforward=True)
    data = study.to_dict()
    files.append(folder / "tuning.json")
    write_text(files[-1], json.dumps(data, indent=1))
    files.append(study_figure(data, folder / "tuning.png"))
    files.append(gains_figure(study.schedule, {"roll": K_ROLL, "pitch": K_PITCH}, folder / "tuning_gains.png"))
    emit(args, {"files": [str(f) for f in files], "chosen": study.chosen, "values": study.values,
                "scores": data["scores"], "criteria": data["criteria"], "stable": survey.stable,
                **survey.weakest(), "model": model.model_label, "input_unit": model.input_unit}, summary(data, files))


def summary(data: dict, files) -> str:
    """The study for people: the scores, the criteria and the chosen design."""
    lines = [f"wrote {f}" for f in files]
    lines.append(f"draws: {data['samples']} (seed {data['seeds']['tuning']}; tuned on the first "
                 f"{data['tune_samples']}) and {data['samples']} held out (seed {data['seeds']['held_out']}); "
                 f"{sum(data['rejected_as_inconsistent_with_holds'])} drawn sets skipped as against the measured holds")
    for name, scores in data["scores"].items():
        lines.append(f"score on the {name.replace('_', '-')} draws (lower is better; tracking alone gives the thesis "
                     "law 2, penalties add 100 or more): " + ", ".join(f"{c} {v:.3f}" for c, v in scores.items()))
    for name, met in data["criteria"].items():
        failed = [k for k, v in met.items() if not v]
        lines.append(f"{data['chosen']} design against the thesis law, {name.replace('_', '-')} draws: "
                     + ("every criterion met" if not failed else f"NOT met: {', '.join(failed)}"))
    margin = f"{100 * data['schedule_margin']:g} %"
    lines.append(f"chosen: {data['chosen']} ("
                 + (f"the scheduled gains beat one gain set by {margin} or more on the tuning draws"
                    if data["chosen"] == "scheduled" else
                    f"one gain set is as good on this robot: scheduling did not beat it by {margin} on the tuning "
                    "draws") + "; the held-out draws check, they do not choose)")
    lines.append("  " + ", ".join(f"{k} {v:.4g}" for k, v in data["values"].items()))
    return "\n".join(lines)

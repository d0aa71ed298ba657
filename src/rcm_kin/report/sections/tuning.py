"""The gains tuned by simulation (``rcm-kin schedule psm --tune``): the shipped design run now on the
nominal robot beside the thesis law and the LQR/LQI schedule, and what its design study found over
the drawn plants (scores, the issue's criteria, the choice between one gain set and a schedule, the
design's values, which of its parts does the work, the draws and the search), read from the shipped
``tuning.json`` (:func:`rcm_kin.tuning.study.read_study`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from rcm_kin.report.render import Table, relative

FRESH = ("thesis", "scheduled-friction", "tuned")      # the controllers run on the nominal robot
DRAW_SETS = {"tuning": "tuning draws", "held_out": "held-out draws"}
CRITERIA = {"median_at_or_below_thesis": "median max and mean errors at or below the thesis law's "
                                         "(both experiments, both axes)",
            "worst_no_worse": "the worst draw's max error no worse",
            "no_unstable_run": "no unstable run",
            "frozen_loop_stable": "the frozen 400 Hz loop stable at every pose of every draw",
            "saturation_no_more": "no more time at the PWM limit"}
VARIANTS = {   # what each variant of rcm_kin.tuning.structures changes, in one sentence
    "design without friction compensation": "The chosen design with the sliding-friction compensation of both "
                                            "axes set to 0.",
    "design without the roll's friction compensation": "The chosen design with the roll's friction compensation "
                                                        "alone set to 0.",
    "design without the pitch feedforward": "The chosen design without the pitch's model-inverse feedforward.",
    "design pitch Ki at its least (1)": "The chosen design with the pitch Ki at the least of its range, "
                                        "1 PWM/(deg s): in effect no integral action.",
    "design without gravity feedforward": "The chosen design without the holding-PWM (gravity) feedforward.",
    "design damping the measured velocity": "The chosen design damping the measured velocity instead of the "
                                            "velocity error.",
    "thesis law": "The thesis's flashed tables and law (Kd on the measured velocity, no feedforward).",
    "thesis law, Kd 0": "The thesis law with its Kd zeroed: no velocity term.",
    "thesis law, Kd flipped (damping)": "The thesis law with its Kd negated to the damping (hardware) sign.",
}
DEFAULTS = {"samples": 64, "tune_samples": 16, "seed": 0, "check_seed": 1}     # rcm-kin schedule psm --tune


@dataclass(frozen=True)
class TuningSection:
    template: ClassVar[str] = "tuning.html.j2"
    fresh: Table                   # nominal robot: experiment, controller, axis, errors, saturation
    skip_s: float                  # statistics from here on (s)
    chosen: str                    # "fixed" or "scheduled"
    chosen_label: str
    margin: float                  # the scheduled design's least gain over one gain set, both draw sets
    scheduled_against_fixed: dict[str, float]     # draw set -> scheduled score / fixed score - 1
    flat_schedule: bool            # the scheduled search's best design has every Kp slope at 0
    same_designs: bool             # and is the fixed design itself
    shipped_is_chosen: bool        # gains.json holds the study's chosen design (on this drive file)
    scores: Table                  # controller x draw set: score and frozen-loop radius
    criteria: Table                # criterion x draw set, the chosen design against the thesis law
    values: Table                  # the chosen design: parameter, value, unit, range, why the range
    gains: Table                   # its tables beside the thesis's (schedule section's rows)
    structures: Table | None       # variant x draw set (absent from an early study)
    radius_limit: float
    penalty: float
    draws: dict                    # samples, tune_samples, seeds, rejected, stability_points
    search: Table                  # per search: generations, evaluations, wall time, runs/s, stop
    budget_s: float | None
    generations_limit: int | None
    command: str
    machine_independent: bool      # every search stopped on generations or converged, none on the clock
    files: dict[str, str]          # the study's gains.json and tuning.json, copied
    figures: dict[str, str]        # "study", "gains"


def _g(value, digits: int = 4) -> str:
    return "n/a" if value is None or value != value else f"{value:.{digits}g}"


def _radius(value) -> str:
    """A spectral radius, to the digits that tell 0.99999 from 1."""
    return "n/a" if value is None or value != value else f"{value:.6f}"


def _fresh_table(gains: Path | None, skip: float) -> Table:
    """The controllers of :data:`FRESH` on the thesis experiments, nominal robot, from ``skip`` s."""
    from rcm_kin.simulation.experiments import run_experiment
    from rcm_kin.simulation.loop import tracking_metrics
    from rcm_kin.tuning.figures import LABELS

    labels = {"thesis": LABELS["thesis"], "scheduled-friction": LABELS["lqr"], "tuned": "tuned (shipped gains.json)"}
    rows = []
    for experiment in ("sine", "target"):
        for controller in FRESH:
            run = run_experiment(experiment, controller, gains=gains if controller == "tuned" else None)
            for axis, m in tracking_metrics(run, skip).items():
                rows.append([experiment, labels[controller], axis, f"{m.max_error_deg:.3f}",
                             f"{m.mean_error_deg:.3f}", f"{m.saturation_s:.3f}"])
    return Table.of(rows, ["experiment", "controller", "axis", f"max error from {skip:g} s (deg)",
                           f"mean error from {skip:g} s (deg)", "at the PWM limit (s)"])


def _scores(study: dict) -> Table:
    from rcm_kin.tuning.figures import LABELS

    judged = study["judged"]
    rows = [[LABELS[c] + (" (chosen)" if c == study["chosen"] else "")]
            + [_g(study["scores"][d][c]) for d in DRAW_SETS]
            + [_radius(judged[d][c]["spectral_radius"]) for d in DRAW_SETS] for c in LABELS]
    return Table.of(rows, ["controller"] + [f"score, {n}" for n in DRAW_SETS.values()]
                    + [f"frozen-loop radius, {n}" for n in DRAW_SETS.values()])


def _criteria(study: dict) -> Table:
    met = study["criteria"]
    names = list(dict.fromkeys(k for d in DRAW_SETS for k in met[d]))
    return Table.of([[CRITERIA.get(k, k.replace("_", " "))] + ["yes" if met[d].get(k) else "NO" for d in DRAW_SETS]
                     for k in names], ["criterion"] + list(DRAW_SETS.values()))


def _values(study: dict) -> Table:
    space = {p["name"]: p for p in study["searches"][study["chosen"]]["space"]}
    rows = []
    for name, value in study["values"].items():
        p = space.get(name, {})
        bounds = f"{_g(p['low'])} to {_g(p['high'])}{' (log)' if p.get('log') else ''}" if p else "n/a"
        rows.append([name, _g(value), p.get("unit", ""), bounds, p.get("reason", "")])
    return Table.of(rows, ["parameter", "value", "unit", "searched over", "why that range"])


def _penalised(variant: dict, limit: float, penalty: float) -> list[str]:
    reasons = [f"frozen-loop radius >= {limit:g}"] if variant["spectral_radius"] >= limit else []
    reasons += ["unstable runs"] if variant["unstable_runs"] else []
    return reasons or (["more time at the PWM limit"] if variant["score"] >= penalty else [])


def _structures(study: dict, penalty: float) -> Table | None:
    sets = study.get("structures")
    if not sets:
        return None
    limit = study["radius_limit"]
    rows = []
    for name in sets["tuning"]:
        v = {d: sets[d][name] for d in DRAW_SETS}
        why = list(dict.fromkeys(r for d in DRAW_SETS for r in _penalised(v[d], limit, penalty)))
        rows.append([name, VARIANTS.get(name, "")] + [_g(v[d]["score"]) for d in DRAW_SETS]
                    + [_radius(v[d]["spectral_radius"]) for d in DRAW_SETS] + ["; ".join(why)])
    return Table.of(rows, ["variant", "what it changes"] + [f"score, {n}" for n in DRAW_SETS.values()]
                    + [f"frozen-loop radius, {n}" for n in DRAW_SETS.values()] + ["penalised for"])


def _search(study: dict) -> Table:
    rows = [[kind, s["generations"], s["evaluations"], f"{s['wall_s']:.0f}", f"{s['runs_per_s']:.0f}", s["stopped"],
             _g(s["score_tuning_subset"])] for kind, s in study["searches"].items()]
    return Table.of(rows, ["space", "generations", "evaluations", "wall time (s)", "runs per s (per worker)",
                           "stopped by", "score on the searched draws"])


def reproducing_command(study: dict) -> str:
    """The ``rcm-kin schedule psm --tune`` command line of ``study`` (its options that are not the
    defaults; budget and generations when the study recorded them), into ``--out tuned``."""
    seeds = study["seeds"]
    options = [("--generations", study.get("generations_limit")),
               ("--budget", study.get("budget_s")),
               ("--draws", study["samples"] if study["samples"] != DEFAULTS["samples"] else None),
               ("--tune-draws", study["tune_samples"] if study["tune_samples"] != DEFAULTS["tune_samples"] else None),
               ("--seed", seeds["tuning"] if seeds["tuning"] != DEFAULTS["seed"] else None),
               ("--check-seed", seeds["held_out"] if seeds["held_out"] != DEFAULTS["check_seed"] else None)]
    given = [f"{flag} {value:g}" for flag, value in options
             if value is not None and not (isinstance(value, float) and math.isnan(value))]
    return " ".join(["rcm-kin schedule psm --tune", *given, "--out tuned"])


def _choice(study: dict) -> tuple[dict[str, float], bool, bool]:
    """Scheduled against fixed per draw set (relative score), whether the scheduled design's Kp
    slopes are all 0, and whether it is then the fixed design itself. The study's own choice
    (:func:`rcm_kin.tuning.study.choose` on the tuning draws' scores) must follow from its scores."""
    from rcm_kin.errors import RcmKinError
    from rcm_kin.tuning.study import choose

    scores = study["scores"]
    against = {d: scores[d]["scheduled"] / scores[d]["fixed"] - 1.0 for d in DRAW_SETS}
    if study["chosen"] != choose(scores["tuning"], study["schedule_margin"]):
        raise RcmKinError(f"the design study chose {study['chosen']!r}, which its scores do not give",
                          parameter="study")
    designs = study.get("designs", {})
    scheduled = designs.get("scheduled", {})
    flat = bool(scheduled) and all(v == 0.0 for k, v in scheduled.items() if k.endswith("_slope"))
    same = flat and designs.get("fixed") == {k: v for k, v in scheduled.items() if not k.endswith("_slope")}
    return against, flat, same


def _shipped_is_chosen(schedule, values: dict) -> bool:
    """Whether ``schedule`` (read from gains.json) has the tables of the design ``values`` on the
    LQR/LQI schedule of the shipped drive file."""
    import numpy as np

    from rcm_kin.simulation.experiments import psm_schedule
    from rcm_kin.tuning.design import tuned_schedule

    design = tuned_schedule(psm_schedule(), values)
    same = [np.allclose(getattr(schedule, k), getattr(design, k), rtol=1e-9, atol=1e-12)
            for k in ("k_roll", "k_pitch", "ff_pitch")]
    friction = schedule.friction is not None and np.allclose(
        (*schedule.friction.pwm, schedule.friction.ramp_deg_s), (*design.friction.pwm, design.friction.ramp_deg_s))
    return all(same) and friction


def tuning_section(out: Path, study: str | Path | None = None, gains: str | Path | None = None) -> TuningSection:
    """The section from the design study ``study`` (``tuning.json``; default the shipped one,
    :data:`rcm_kin.tuning.study.SHIPPED_STUDY`) and its gain file ``gains`` (default the shipped
    tuned design, :data:`rcm_kin.control.schedule_file.SHIPPED_TUNED`): six runs on the nominal
    robot, the study's tables, ``out/tuning.png``, ``out/tuning_gains.png`` and both files copied
    into ``out/tuned_gains``."""
    from rcm_kin.atomic import write_text
    from rcm_kin.control.schedule_file import read_schedule_file
    from rcm_kin.errors import output_folder
    from rcm_kin.report.sections.schedule import gain_rows
    from rcm_kin.thesis import K_PITCH, K_ROLL
    from rcm_kin.tuning.figures import LABELS, gains_figure, study_figure
    from rcm_kin.tuning.objective import PENALTY, SKIP_S
    from rcm_kin.tuning.study import SHIPPED_STUDY, read_study

    data, loaded = read_study(study), read_schedule_file(gains)
    against, flat, same = _choice(data)
    folder = output_folder(out / "tuned_gains")
    files = {"gains.json": folder / "gains.json", "tuning.json": folder / "tuning.json"}
    write_text(files["gains.json"], loaded.path.read_text())
    write_text(files["tuning.json"], Path(SHIPPED_STUDY if study is None else study).read_text())
    figures = {"study": study_figure(data, out / "tuning.png"),
               "gains": gains_figure(loaded.schedule, {"roll": K_ROLL, "pitch": K_PITCH}, out / "tuning_gains.png")}
    s = loaded.schedule
    roll_labels = [f"roll {r:g}" for r in s.roll_deg]
    budget = data.get("budget_s")
    return TuningSection(
        fresh=_fresh_table(loaded.path, SKIP_S), skip_s=SKIP_S, chosen=data["chosen"],
        chosen_label=LABELS[data["chosen"]], margin=data["schedule_margin"], scheduled_against_fixed=against,
        flat_schedule=flat, same_designs=same,
        shipped_is_chosen=_shipped_is_chosen(s, data["values"]), scores=_scores(data), criteria=_criteria(data),
        values=_values(data),
        gains=Table.of(gain_rows(s), ["gain", "pitch (deg)"] + [f"tuned, {r}" for r in roll_labels]
                       + [f"thesis, {r}" for r in roll_labels]),
        structures=_structures(data, PENALTY), radius_limit=data["radius_limit"], penalty=PENALTY,
        draws={"samples": data["samples"], "tune_samples": data["tune_samples"], "seeds": data["seeds"],
               "rejected": dict(zip(DRAW_SETS, data["rejected_as_inconsistent_with_holds"])),
               "stability_points": data["stability_points"]},
        search=_search(data), budget_s=None if budget is None or budget != budget else float(budget),
        generations_limit=data.get("generations_limit"), command=reproducing_command(data),
        machine_independent=all(s["stopped"] != "time budget" for s in data["searches"].values()),
        files={name: relative(path, out) for name, path in files.items()},
        figures={name: relative(path, out) for name, path in figures.items()})

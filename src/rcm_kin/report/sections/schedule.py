"""The model-based gain schedule on the thesis's grid, its firmware export, its stability, and
the thesis's gain tables beside it."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.control.thesis_comparison import ScheduleContrast
from rcm_kin.control.weights import Weights
from rcm_kin.hardware import FIRMWARE_PERIOD, ROLL_FILTER
from rcm_kin.report.render import Table, relative
from rcm_kin.thesis import K_PITCH, K_ROLL, SOURCES


@dataclass(frozen=True)
class ScheduleSection:
    template: ClassVar[str] = "schedule.html.j2"
    insertion_mm: float
    weights: Weights
    files: dict[str, str]          # gains.json, gains.csv, gain_schedule.h
    gains: Table                   # model beside thesis, per gain and pitch row
    thesis_source: str
    survey_points: int             # per axis of the stability surveys
    verdicts: Table
    figure: str                    # stability maps
    contrast: ScheduleContrast
    thesis_roll_poles: str         # closed-loop poles of the thesis's (0, 0) roll gains on its G(s)
    roll_filter: float             # EMA coefficient of the firmware's roll velocity
    schedule: GainSchedule = field(repr=False, compare=False)   # for the sections that build on it


def gain_rows(s: GainSchedule) -> list[list[str]]:
    """Per gain and pitch row of ``s``'s grid: its values per roll, then the thesis table's
    (Tables 4.4-4.8; ``s`` on the thesis grid)."""
    names = [("roll Kp (PWM/deg)", s.k_roll[..., 0], K_ROLL[..., 0]),
             ("roll Kd (PWM/(deg/s))", s.k_roll[..., 1], K_ROLL[..., 1]),
             ("pitch Kp (PWM/deg)", s.k_pitch[..., 0], K_PITCH[..., 0]),
             ("pitch Kd (PWM/(deg/s))", s.k_pitch[..., 1], K_PITCH[..., 1]),
             ("pitch Ki (PWM/(deg s))", s.k_pitch[..., 2], K_PITCH[..., 2])]
    rows = []
    for name, ours, theirs in names:
        for j, pitch in enumerate(s.pitch_deg):
            rows.append([name if j == 0 else "", f"{pitch:g}"] + [f"{v:.4g}" for v in ours[j]]
                        + [f"{v:.4g}" for v in theirs[j]])
    return rows


def _verdicts(surveys: dict) -> Table:
    rate = 1.0 / FIRMWARE_PERIOD
    rows = [[title, "yes" if v.stable else "NO", f"{v.max_real.max():+.3g}",
             f"{-np.log(v.spectral_radius.max()) * rate:+.3g}", f"{v.min_damping.min():.3f}"]
            for title, v in surveys.items()]
    return Table.of(rows, ["gains", "stable", "max Re (continuous, 1/s)", f"slowest decay, {rate:.0f} Hz loop (1/s)",
                           f"least damping, {rate:.0f} Hz loop"])


def schedule_section(out: Path, survey_points: int = 21) -> ScheduleSection:
    """Schedule (:func:`rcm_kin.simulation.experiments.psm_schedule`, the one the simulations use),
    export (``out/gain_schedule``), stability surveys on ``survey_points`` per axis and the
    stability maps, with the numbers that set the two schedules apart."""
    from rcm_kin.codegen.firmware_export import write_gain_schedule
    from rcm_kin.control.thesis_comparison import compare_with_thesis, schedule_contrast
    from rcm_kin.dynamics.state_space import driven_dynamics
    from rcm_kin.errors import output_folder
    from rcm_kin.model import load_robot
    from rcm_kin.plotting import stability_maps
    from rcm_kin.simulation.experiments import psm_schedule

    c = compare_with_thesis(driven_dynamics(load_robot("psm"), coulomb=False), survey_points, psm_schedule())
    s = c.model
    folder = output_folder(out / "gain_schedule")
    write_gain_schedule(s, folder, c.ours, gravity_feedforward=True)
    surveys = {"model-based schedule": c.ours, "thesis gains": c.thesis,
               "thesis gains, Kd sign flipped": c.thesis_damping_flipped}
    figure = stability_maps(surveys, out / "stability_maps.png")
    roll_labels = [f"roll {r:g}" for r in s.roll_deg]
    return ScheduleSection(
        insertion_mm=s.insertion * 1e3, weights=s.weights,
        files={name: relative(folder / name, out) for name in ("gains.json", "gains.csv", "gain_schedule.h")},
        gains=Table.of(gain_rows(s), ["gain", "pitch (deg)"] + [f"model, {r}" for r in roll_labels]
                       + [f"thesis, {r}" for r in roll_labels]),
        thesis_source=f"{SOURCES['K_ROLL']}; {SOURCES['K_PITCH']}",
        survey_points=survey_points,
        verdicts=_verdicts({"model-based schedule": c.ours, "thesis tables": c.thesis,
                            "thesis tables, Kd sign flipped": c.thesis_damping_flipped}),
        figure=relative(figure, out), contrast=schedule_contrast(s),
        thesis_roll_poles=", ".join(f"{p.real:+.3g}{p.imag:+.3g}j" for p in c.thesis_on_identified_roll),
        roll_filter=ROLL_FILTER, schedule=s)

"""The da Vinci safety thesis: the CBF scenarios with each filter, the remote centre of motion
of the three RCM chains, and the SOS barrier certificates when cvxpy is installed."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.report.render import Table, relative
from rcm_kin.robot import load_robot

RCM_CHAINS = ("psm", "davinci", "davinci_rcm")


@dataclass(frozen=True)
class SafetySection:
    template: ClassVar[str] = "safety.html.j2"
    scenarios: Table
    figure: str | None                  # barrier values along the scenarios (the PSM's has no B(t) of its own)
    psm_no_go_mm: float | None          # the PSM scenario's ellipsoid radius (mm), if it ran
    psm_allowance_mm: float | None      # what the filter adds for the tracking error (mm)
    rcm: Table
    certificates: Table | None          # None: cvxpy missing or not asked for
    sos_available: bool


def _scenarios(out: Path, scenarios, filters) -> tuple[Table, str | None, object]:
    from rcm_kin.report.figures import barrier_figure
    from rcm_kin.safety.scenarios import run_scenario

    runs, rows, psm = {}, [], None
    for scenario in scenarios:
        for name in filters:
            run = run_scenario(scenario, name)
            summary = run.summary()
            if scenario == "psm":
                psm = run
            else:
                runs.setdefault(scenario, {})[name] = run
            rows.append([scenario, name, f"{summary['min_margin']:+.4g}", summary["violations"], summary["samples"]])
    figure = relative(barrier_figure(runs, out / "safety_barriers.png"), out) if runs else None
    return Table.of(rows, ["scenario", "filter", "min margin", "unsafe samples", "samples"]), figure, psm


def _rcm_table(chains) -> Table:
    from rcm_kin.kinematics.rcm_scatter import rcm_scatter

    rows = []
    for name in chains:
        robot = load_robot(name)
        rcm = robot.description.rcm
        scatter = rcm_scatter(robot, rcm.shaft_frame, rcm.joints, rcm.base_frame)
        rows.append([name, f"{np.round(scatter.point, 4).tolist()} ({rcm.base_frame or 'base'})",
                     f"{scatter.max_distance * 1e3:.3g}", f"{scatter.rms_distance * 1e3:.3g}"])
    return Table.of(rows, ["robot", "RCM point (m)", "shaft lines within (mm)", "RMS (mm)"])


def _certificates(programs=None) -> Table:
    from rcm_kin.safety.sos import PROGRAMS, check_by_sampling, find_certificate, thesis_program

    rows = []
    for number in programs or PROGRAMS:
        program = thesis_program(number)
        c = find_certificate(program)
        check = check_by_sampling(c.B, program) if c.B else None
        rows.append([number, program.name, "yes" if c.feasible else "no", c.status,
                     "passed" if check and check.passed else "-"])
    return Table.of(rows, ["program", "closed loop", "certificate", "solver", "sampling check"])


def safety_section(out: Path, scenarios=None, filters=None, chains=RCM_CHAINS, certificates: bool = True,
                   programs=None) -> SafetySection:
    """Run ``scenarios`` x ``filters`` (default all), the RCM scatter of ``chains`` and, with
    ``certificates`` and cvxpy installed, the SOS programs ``programs`` (default all)."""
    from rcm_kin.safety.scenarios import FILTERS, SCENARIOS

    table, figure, psm = _scenarios(out, scenarios or SCENARIOS, filters or FILTERS)
    sos = importlib.util.find_spec("cvxpy") is not None
    return SafetySection(
        table, figure, float(np.min(psm.ellipsoid.radii)) * 1e3 if psm else None,
        psm.allowance * 1e3 if psm else None, _rcm_table(chains),
        _certificates(programs) if sos and certificates else None, sos)

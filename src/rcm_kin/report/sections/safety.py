"""The da Vinci safety thesis: the CBF scenarios with each filter, the remote centre of motion
of the three RCM chains, and the SOS barrier certificates when cvxpy is installed."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.model import load_robot
from rcm_kin.report.render import Table, relative

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


@dataclass(frozen=True)
class ScenarioRuns:
    """Scenarios run with each filter: their rows of the scenario table, the barrier figure of
    those with a B(t) of their own (None: only the PSM's ran), and the PSM run's no-go radius and
    the allowance its filter adds (mm; None: the PSM's did not run)."""

    rows: tuple[tuple[str, ...], ...]
    figure: str | None
    psm_no_go_mm: float | None
    psm_allowance_mm: float | None


SCENARIO_HEADER = ("scenario", "filter", "min margin", "unsafe samples", "samples")


def scenario_runs(out: Path, scenarios=None, filters=None) -> ScenarioRuns:
    """Run ``scenarios`` x ``filters`` (default all); the barrier figure into
    ``out/safety_barriers.png``."""
    from rcm_kin.plotting import barrier_figure
    from rcm_kin.safety.scenarios import FILTERS, SCENARIOS, run_scenario

    runs, rows, psm = {}, [], None
    for scenario in scenarios or SCENARIOS:
        for name in filters or FILTERS:
            run = run_scenario(scenario, name)
            summary = run.summary()
            if scenario == "psm":
                psm = run
            else:
                runs.setdefault(scenario, {})[name] = run
            rows.append([scenario, name, f"{summary['min_margin']:+.4g}", summary["violations"], summary["samples"]])
    figure = relative(barrier_figure(runs, out / "safety_barriers.png"), out) if runs else None
    return ScenarioRuns(Table.of(rows, SCENARIO_HEADER).rows, figure,
                        float(np.min(psm.ellipsoid.radii)) * 1e3 if psm else None,
                        psm.allowance * 1e3 if psm else None)


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
    from rcm_kin.safety.sos import PROGRAMS, find_certificate, thesis_program

    rows = []
    for number in programs or PROGRAMS:
        program = thesis_program(number)
        c = find_certificate(program)
        rows.append([number, program.name, "yes" if c.feasible else "no", c.status,
                     "passed" if c.check and c.check.passed else "-"])
    return Table.of(rows, ["program", "closed loop", "certificate", "solver", "sampling check"])


@dataclass(frozen=True)
class SafetyChecks:
    """The RCM scatter of the chains and the SOS certificates (None: cvxpy missing or not asked for)."""

    rcm: Table
    certificates: Table | None
    sos_available: bool


def safety_checks(chains=RCM_CHAINS, certificates: bool = True, programs=None) -> SafetyChecks:
    """The RCM scatter of ``chains`` and, with ``certificates`` and cvxpy installed, the SOS
    programs ``programs`` (default all)."""
    sos = importlib.util.find_spec("cvxpy") is not None
    return SafetyChecks(_rcm_table(chains), _certificates(programs) if sos and certificates else None, sos)


def safety_from_parts(runs: list[ScenarioRuns], checks: SafetyChecks) -> SafetySection:
    """The section of scenario runs (rows in the order of ``runs``; the report runs the scenarios
    with a barrier figure in one part, the PSM's in another) and the checks. Two parts with a
    barrier figure are refused: each draws only its own scenarios into the same file name."""
    figures = [r.figure for r in runs if r.figure]
    if len(figures) > 1:
        raise RcmKinError("the scenarios with a barrier figure must run in one part: each part draws only its own")
    figure = figures[0] if figures else None
    psm = next((r for r in runs if r.psm_no_go_mm is not None), None)
    return SafetySection(Table(SCENARIO_HEADER, tuple(row for r in runs for row in r.rows)), figure,
                         psm.psm_no_go_mm if psm else None, psm.psm_allowance_mm if psm else None, checks.rcm,
                         checks.certificates, checks.sos_available)


def safety_section(out: Path, scenarios=None, filters=None, chains=RCM_CHAINS, certificates: bool = True,
                   programs=None) -> SafetySection:
    """Run ``scenarios`` x ``filters`` (default all), the RCM scatter of ``chains`` and, with
    ``certificates`` and cvxpy installed, the SOS programs ``programs`` (default all)."""
    return safety_from_parts([scenario_runs(out, scenarios, filters)], safety_checks(chains, certificates, programs))

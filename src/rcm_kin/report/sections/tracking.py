"""The thesis's tracking experiments on the model (its Ch. 5): the baseline P against the
scheduled controllers on the sinusoid and on target following, with the thesis's measured
errors beside the sinusoid's."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.errors import output_folder
from rcm_kin.hardware import FIRMWARE_PERIOD
from rcm_kin.report.render import Table, relative
from rcm_kin.thesis import FIGURES, SINE_AMPLITUDE_DEG, SINE_CYCLE_S, SINE_TRACKING_ERROR_DEG, SOURCES

CONTROLLERS = ("p", "scheduled", "scheduled-gravity")
SETTLED_FROM = 0.5          # s: the sinusoid starts at full speed; statistics again from here
ANIMATION_EVERY = 8         # every 8th sample of the 400 Hz run in the animation


@dataclass(frozen=True)
class ExperimentRuns:
    name: str
    errors_figure: str                    # the controllers' errors together
    runs: tuple[tuple[str, str], ...]     # (controller, its figure)
    animation: str | None                 # meshcat page of the last controller's run


@dataclass(frozen=True)
class TrackingSection:
    template: ClassVar[str] = "tracking.html.j2"
    table: Table
    experiments: tuple[ExperimentRuns, ...]
    animated: str                         # the controller the animations show
    trajectory: str                       # where the target-following trajectory came from
    sine_amplitude_deg: tuple[float, float]
    sine_cycle_s: float
    settled_from_s: float
    loop_rate_hz: float
    thesis_source: str
    thesis_figures: dict[str, str]


def _thesis_cell(experiment: str, controller: str, axis: str) -> str:
    quoted = SINE_TRACKING_ERROR_DEG.get((controller, axis)) if experiment == "sine" else None
    return f"{quoted[0]:.2f} / {quoted[1]:.2f}" if quoted else ""


def _rows(experiment: str, result) -> list[list[str]]:
    from rcm_kin.simulation.loop import tracking_metrics

    whole, settled = tracking_metrics(result), tracking_metrics(result, skip=SETTLED_FROM)
    return [[experiment, result.controller, axis, f"{m.max_error_deg:.3f} / {m.mean_error_deg:.3f}",
             f"{settled[axis].max_error_deg:.3f} / {settled[axis].mean_error_deg:.3f}", f"{m.rms_error_deg:.3f}",
             f"{m.rms_pwm:.1f}", f"{m.saturation_s:.3f}", _thesis_cell(experiment, result.controller, axis)]
            for axis, m in whole.items()]


def _animation(run, path: Path, period: float) -> Path:
    """A meshcat page of ``run``, the tool-tip path coloured by the pitch PWM."""
    from rcm_kin.model import load_robot
    from rcm_kin.simulation.loop import si_units
    from rcm_kin.visualization.views import animate, frame_path, robot_view, scalar_trail, write_html

    psm = load_robot("psm")
    Q = np.zeros((len(run.time), psm.nq))
    Q[:, :3] = si_units(run.position)
    viz = robot_view(psm)
    animate(viz, psm, Q, period, every=ANIMATION_EVERY)
    scalar_trail(viz, "pitch_pwm", frame_path(psm, Q[::ANIMATION_EVERY], "tool_tip"), run.pwm[::ANIMATION_EVERY, 1])
    return write_html(viz, path)


@dataclass(frozen=True)
class TrackingRuns:
    """One experiment of the tracking section: its rows of the table and its figures."""

    rows: tuple[tuple[str, ...], ...]
    runs: ExperimentRuns


TABLE_HEADER = ("experiment", "controller", "axis", "max / mean", f"from {SETTLED_FROM:g} s", "RMS", "PWM RMS",
                "saturated (s)", "thesis max / mean")


def tracking_experiment(out: Path, schedule: GainSchedule, experiment: str, trajectory=None,
                        duration: float | None = None, animate: bool = True) -> TrackingRuns:
    """Simulate ``experiment`` with each controller of :data:`CONTROLLERS` (``duration`` s, default
    the experiment's own; ``trajectory`` an MTM recording for target following, default the
    bundled one) and write its figures and animation into ``out/tracking``. The runs are the
    compiled closed loop (:func:`rcm_kin.simulation.experiments.closed_loop`, equal to the readable
    reference loop tick for tick)."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.plotting import error_comparison_figure, tracking_figure
    from rcm_kin.simulation.controllers import make_controller
    from rcm_kin.simulation.experiments import closed_loop, experiment_reference, psm_plant, start_hold
    from rcm_kin.simulation.firmware import FirmwareSettings

    settings = FirmwareSettings()
    plant = psm_plant(load_drive_parameters(), settings.period, fast=True)
    folder = output_folder(out / "tracking")
    reference = experiment_reference(experiment, settings.period, duration, trajectory=trajectory)
    hold = start_hold(reference)
    results = [closed_loop(plant, make_controller(name, schedule), reference, settings, hold=hold)
               for name in CONTROLLERS]
    figures = [(r.controller, relative(tracking_figure(r, folder / f"{experiment}_{r.controller}.png",
                                                       title=f"{experiment}, {r.controller}:"), out))
               for r in results]
    rows = [row for r in results for row in _rows(experiment, r)]
    errors = error_comparison_figure(results, folder / f"{experiment}_errors.png", title=f"{experiment}:")
    page = _animation(results[-1], folder / f"{experiment}_animation.html", settings.period) if animate else None
    return TrackingRuns(Table.of(rows, TABLE_HEADER).rows,
                        ExperimentRuns(experiment, relative(errors, out), tuple(figures),
                                       relative(page, out) if page else None))


def tracking_from_parts(parts: list[TrackingRuns], trajectory=None) -> TrackingSection:
    """The section of the experiments ``parts`` (:func:`tracking_experiment`), in their order."""
    return TrackingSection(
        Table(TABLE_HEADER, tuple(row for part in parts for row in part.rows)), tuple(p.runs for p in parts),
        CONTROLLERS[-1], "the MTM recording given" if trajectory else "the bundled figure-eight MTM trajectory",
        SINE_AMPLITUDE_DEG, SINE_CYCLE_S, SETTLED_FROM, 1.0 / FIRMWARE_PERIOD,
        SOURCES["SINE_TRACKING_ERROR_DEG"], FIGURES)


def tracking_section(out: Path, schedule: GainSchedule, trajectory=None, experiments=("sine", "target"),
                     duration: float | None = None, animate: bool = True) -> TrackingSection:
    """:func:`tracking_experiment` of each of ``experiments``, as one section."""
    return tracking_from_parts([tracking_experiment(out, schedule, e, trajectory, duration, animate)
                                for e in experiments], trajectory)

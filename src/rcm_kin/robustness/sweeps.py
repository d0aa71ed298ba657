"""Design sweeps, one Dask task per batch of design points (:func:`rcm_kin.parallel.map_batches`).

- counterweights: for each (main, DPM) counterweight mass pair, the positions that minimise the
  RMS holding PWM of roll and pitch over the workspace (:func:`rcm_kin.statics.counterweights.design_counterweights`,
  the CAD model with the calibrated offsets left out, as :func:`~rcm_kin.statics.counterweights.osmdv_designs`),
  and what is left: the trade-off between added mass and holding effort;
- weights: for each Bryson budget pair (error budget in deg for roll and pitch, PWM budget as a
  fraction of the firmware limit), the gain schedule designed with it on the nominal model, the
  tracking error and PWM it gives on the sinusoid with the scheduled controller (the identified
  plant), and its 400 Hz linear margin: the trade-off between tracking and PWM use.
"""

from __future__ import annotations

import csv
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import numpy as np

from rcm_kin.atomic import atomic_open
from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG, schedule_gains
from rcm_kin.control.weights import Weights
from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import PWM_LIMIT
from rcm_kin.model import load_robot
from rcm_kin.robustness.task import linear_law, loop_margins, sample_plant
from rcm_kin.simulation.controllers import make_controller
from rcm_kin.simulation.experiments import closed_loop, experiment_reference, start_hold
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import tracking_metrics
from rcm_kin.statics.counterweights import design_counterweights, workspace_grid


@dataclass(frozen=True)
class CounterweightRow:
    """One counterweight design: masses (kg), positions (m, deg) and the holding PWM left (counts)."""

    main_mass_kg: float
    dpm_mass_kg: float
    main_distance_m: float
    dpm_distance_m: float
    dpm_angle_deg: float
    rms_pwm_roll: float
    rms_pwm_pitch: float
    peak_pwm_roll: float
    peak_pwm_pitch: float


@dataclass(frozen=True)
class WeightsRow:
    """One LQR/LQI budget: the budgets, and on the sinusoid the largest and mean errors (deg), the
    RMS PWM (counts), the 400 Hz loop's worst spectral radius over the grid, and whether that loop
    is stable at every grid pose (radius below 1: the errors of an unstable design are those of
    its bounded, saturated run, not of a design to flash)."""

    error_budget_deg: float
    pwm_fraction: float
    max_error_roll_deg: float
    max_error_pitch_deg: float
    mean_error_roll_deg: float
    mean_error_pitch_deg: float
    rms_pwm_roll: float
    rms_pwm_pitch: float
    spectral_radius: float
    stable: bool


def counterweight_batch(batch: list[tuple[float, float]], params: DriveParameters,
                        points: int = 13) -> list[CounterweightRow]:
    """The designs of the mass pairs ``(main kg, DPM kg)`` over the joints' whole roll x pitch
    range at the home insertion, ``points`` per axis."""
    without = load_robot("psm", counterweights=False)
    cad = DriveParameters(params.joints, {})
    Q = workspace_grid(without, points=points)
    rows = []
    for main, dpm in batch:
        d = design_counterweights(without, cad, Q, main, dpm)
        rows.append(CounterweightRow(main, dpm, d.main_distance, d.dpm_distance, float(np.degrees(d.dpm_angle)),
                                     *map(float, d.rms_pwm), *map(float, d.peak_pwm)))
    return rows


def budget_weights(error_deg: float, pwm_fraction: float) -> Weights:
    """The default budgets with the roll and pitch error budgets set to ``error_deg`` and the PWM
    budgets to ``pwm_fraction`` of the firmware limits."""
    return replace(Weights(), roll_error_deg=error_deg, pitch_error_deg=error_deg,
                   roll_pwm=pwm_fraction * float(PWM_LIMIT[0]), pitch_pwm=pwm_fraction * float(PWM_LIMIT[1]))


def weights_batch(batch: list[tuple[float, float]], params: DriveParameters, experiment: str = "sine",
                  duration: float | None = None, points: int = 5) -> list[WeightsRow]:
    """For each ``(error budget deg, PWM fraction)``: the schedule designed with those budgets on
    ``params``' smooth model (Coulomb left out, as ``rcm-kin schedule``), run by the scheduled
    controller on ``params``' plant."""
    settings = FirmwareSettings()
    psm = load_robot("psm")
    model = driven_dynamics(psm, params, coulomb=False)
    plant = sample_plant(params, settings.period)
    reference = experiment_reference(experiment, settings.period, duration)
    hold = start_hold(reference, model=model)
    rows = []
    for error_deg, fraction in batch:
        schedule = schedule_gains(model, THESIS_ROLL_DEG, THESIS_PITCH_DEG, weights=budget_weights(error_deg, fraction))
        run = closed_loop(plant, make_controller("scheduled", schedule), reference, settings, hold=hold)
        m = tracking_metrics(run)
        _, radius, _ = loop_margins(model, schedule, linear_law("scheduled", schedule), points)
        rows.append(WeightsRow(error_deg, fraction, m["roll"].max_error_deg, m["pitch"].max_error_deg,
                               m["roll"].mean_error_deg, m["pitch"].mean_error_deg, m["roll"].rms_pwm,
                               m["pitch"].rms_pwm, radius, bool(radius < 1.0)))
    return rows


def write_table(rows: list, path: str | Path) -> Path:
    """The rows (dataclasses of one type) as a CSV with a header of their field names."""
    if not rows:
        raise RcmKinError("no rows to write")
    path = Path(path)
    try:
        with atomic_open(path, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow([field.name for field in fields(rows[0])])
            writer.writerows([list(asdict(r).values()) for r in rows])
    except OSError as exc:
        raise RcmKinError(f"cannot write the table {path}: {exc.strerror}") from None
    return path

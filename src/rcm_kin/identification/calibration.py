"""Calibration of the drive and gravity model against measured holding efforts.

At a held pose the PWM the controllers send balances gravity (within the static friction
band). From the measured logs:

- roll step logs: the PWM of both joints just before the open-loop step (the thesis recipe:
  the step is the first input change above 0.1 count), averaged over the 0.25 s before it;
- pitch PRBS logs: the mean PWM of the whole run (the PRBS is zero-mean), at the mean pose.

The model ``pwm_j = pwm_per_torque_j * g_j(q; offsets)`` is fitted by nonlinear least squares
(scipy, bounded) over

- one effective ``volts_per_pwm`` for roll and pitch (one driver type on one supply), which the
  pitch data fix: their gravity signal is large and its shape is the CAD's;
- first-moment offsets the CAD cannot give: the roll body's lateral (y, a roll torque
  ~ cos(roll)) and vertical (z, ~ sin(roll): the main counterweight's effective lever) first
  moments, and the drive link's first moment along the main axis (x, a pitch torque
  ~ cos(pitch): the DPM counterweight's placement, never stored).

A drive-link z offset is left out: it acts on pitch like the CAD gravity itself and trades
off exactly against ``volts_per_pwm``. The insertion is not measured
in these logs (a wrong conversion, see the data README): the poses are taken at the home
insertion (:data:`rcm_kin.hardware.HOME_INSERTION`, 80 mm).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import least_squares

from rcm_kin.dynamics.drive import DriveParameters, check_drive, drive_effort, with_joint
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.identification.telemetry import TelemetryLog, load_telemetry, step_index, telemetry_files
from rcm_kin.model.gravity import gravity_batch

if TYPE_CHECKING:
    from rcm_kin.model import Robot

HOLD_WINDOW = 0.25         # s before the step
PARAMETERS = ("volts_per_pwm", "roll_link.y", "roll_link.z", "drive_link.x")
UNITS = ("V/count", "kg m", "kg m", "kg m")


@dataclass(frozen=True)
class HoldingPoint:
    """One measured holding effort."""

    source: str
    roll: float        # rad
    pitch: float       # rad
    pwm_roll: float    # counts
    pwm_pitch: float   # counts


@dataclass(frozen=True)
class CalibrationResult:
    parameters: DriveParameters
    names: tuple[str, ...]
    values: np.ndarray            # fitted values, units in UNITS
    std: np.ndarray               # one-sigma uncertainty from the Jacobian (same units)
    points: tuple[HoldingPoint, ...]
    predicted: np.ndarray         # (n, 2) PWM roll, pitch of the fitted model at the points
    residual_rms: np.ndarray      # (2,) counts, roll and pitch
    friction_band: np.ndarray     # (2,) counts: largest |residual|, the band holding all holds


def holding_point(log: TelemetryLog) -> HoldingPoint:
    """The holding effort in one log: roll step logs by their step, PRBS logs by their mean."""
    for joint in ("roll", "pitch"):
        log.require(joint)
    name = log.path.name.lower()
    if "prbs" in name:
        window = slice(None)
    elif "step" in name:
        k = step_index(log.pwm["roll"])
        first = int(np.searchsorted(log.time, log.time[k] - HOLD_WINDOW))
        window = slice(first, k)
    else:
        raise RcmKinError(f"{log.path.name}: cannot tell a roll step log from a PRBS log by its name "
                          "(expected 'step' or 'prbs' in it)")
    mean = lambda x: float(np.mean(x[window]))  # noqa: E731
    return HoldingPoint(log.path.name, np.radians(mean(log.position["roll"])), np.radians(mean(log.position["pitch"])),
                        mean(log.pwm["roll"]), mean(log.pwm["pitch"]))


def holding_points(paths) -> tuple[HoldingPoint, ...]:
    return tuple(holding_point(load_telemetry(p)) for p in paths)


def _poses(robot: Robot, points) -> np.ndarray:
    Q = np.zeros((len(points), robot.nq))
    Q[:, robot.actuated.index("roll")] = [p.roll for p in points]
    Q[:, robot.actuated.index("pitch")] = [p.pitch for p in points]
    Q[:, robot.actuated.index("insertion")] = HOME_INSERTION
    return Q


def apply_values(base: DriveParameters, values) -> DriveParameters:
    """``base`` with the calibrated quantities of PARAMETERS set to ``values``."""
    params = with_joint(base, "roll", volts_per_pwm=float(values[0]))
    params = with_joint(params, "pitch", volts_per_pwm=float(values[0]))
    offsets = dict(params.gravity_offsets)
    offsets["roll_link"] = np.array([0.0, values[1], values[2]])
    offsets["drive_link"] = np.array([values[3], 0.0, 0.0])
    return replace(params, gravity_offsets=offsets)     # the robot and drive train kept


def predict_pwm(robot: Robot, params: DriveParameters, points) -> np.ndarray:
    """(n, 2) holding PWM of roll and pitch at the points' poses."""
    tau = gravity_batch(robot, _poses(robot, points), params.gravity_offsets)
    pwm = drive_effort(params, tau[:, [robot.actuated.index(j) for j in params.driven]]).pwm
    return pwm[:, [params.driven.index(j) for j in ("roll", "pitch")]]    # by name: any order of the file


def calibrate(robot: Robot, base: DriveParameters, points, start=None) -> CalibrationResult:
    """Least-squares fit of PARAMETERS to measured holding points (at least 4), starting from
    ``base``, the drive parameters of ``robot`` (checked: :func:`check_drive`): from its
    ``volts_per_pwm`` and zero offsets, or from ``start`` (values of PARAMETERS, e.g. a fit on more
    holds, which the leave-one-out refits start from)."""
    base = check_drive(robot, base)
    points = tuple(points)
    if len(points) < 4:
        raise RcmKinError(f"calibration needs at least 4 holding points, got {len(points)}")
    measured = np.array([[p.pwm_roll, p.pwm_pitch] for p in points])
    scale = np.array([base["pitch"].volts_per_pwm, 0.1, 0.1, 0.1])
    x0 = scale * [1.0, 0.0, 0.0, 0.0] if start is None else np.asarray(start, dtype=float)
    lower = np.array([1e-3, -np.inf, -np.inf, -np.inf])   # volts_per_pwm > 0

    def residual(x):
        return (predict_pwm(robot, apply_values(base, x * scale), points) - measured).ravel()

    fit = least_squares(residual, x0 / scale, bounds=(lower, np.inf), x_scale="jac")
    values = fit.x * scale
    dof = max(fit.fun.size - values.size, 1)
    sigma2 = float(fit.fun @ fit.fun) / dof
    J = fit.jac / scale                       # d residual / d value
    cov = sigma2 * np.linalg.pinv(J.T @ J)
    params = apply_values(base, values)
    predicted = predict_pwm(robot, params, points)
    res = predicted - measured
    return CalibrationResult(params, PARAMETERS, values, np.sqrt(np.diag(cov)), points, predicted,
                             np.sqrt(np.mean(res**2, axis=0)), np.max(np.abs(res), axis=0))


def calibration_logs(folder: str | Path) -> list[Path]:
    """The roll step and pitch PRBS logs in a data folder (``psm-sysid`` layout), or one level below it."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RcmKinError(f"no data folder {folder}")
    logs = [log for kind in ("roll-step", "pitch-prbs") for depth in ("", "*/")
            for log in telemetry_files(folder, f"{depth}{kind}/*")]
    if not logs:
        raise RcmKinError(f"no roll-step/ or pitch-prbs/ logs (CSV or ROS 2 bags) below {folder}")
    return logs

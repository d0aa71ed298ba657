"""Identification over a grid of logs (one per pose) beside the physics linearisation there.

Per log: the record (step or PRBS), the transfer-function fit, and at the log's pose (from its
file name, at the home insertion of 80 mm) the physics model's single-axis transfer function
from PWM to angle (deg/PWM) without Coulomb friction, the other joints held as their
controllers held them: its DC gain and poles (python-control) beside the identified ones.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import control
import numpy as np

from rcm_kin.atomic import atomic_open
from rcm_kin.control.linearization import check_in_range
from rcm_kin.dynamics.state_space import DrivenDynamics
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.identification.records import Record, operating_point, prbs_record, step_record
from rcm_kin.identification.telemetry import load_telemetry, telemetry_files
from rcm_kin.identification.transfer_function import TransferFunctionFit, dc_gain, fit_transfer_function

AXIS = {"roll": 0, "pitch": 1}
DEFAULT_ORDER = {"step": 2, "prbs": 3}
PRBS_SEGMENT = 500           # samples (1 s at 2 ms): the multiple-shooting horizon of PRBS fits


@dataclass(frozen=True)
class PhysicsAxis:
    """Single-axis linear model of the physics at a pose, PWM -> deg."""

    dc_gain: float           # deg per PWM count
    poles: np.ndarray        # 1/s


@dataclass(frozen=True)
class PoseModel:
    path: Path
    pose_deg: tuple[float, float] | None     # (roll, pitch) from the file name
    record: Record
    fit: TransferFunctionFit
    physics: PhysicsAxis | None


def physics_transfer_function(model: DrivenDynamics, joint: str, roll_deg: float, pitch_deg: float,
                              insertion: float = HOME_INSERTION) -> control.TransferFunction:
    """The physics model's PWM (counts) -> angle (deg) transfer function of ``joint`` at a pose
    (deg, deg, m) with the other joints held still (their controllers hold them):
    ``G(s) = (180 / pi) k_u / (M_ii s^2 + d_i s + K_ii)``, ``K_ii = dg_i/dq_i`` (AD)."""
    i = AXIS[joint]
    q = np.array([np.radians(roll_deg), np.radians(pitch_deg), insertion])
    check_in_range(model, q)
    M = np.array(model.mass_matrix(q))[i, i]
    K = np.array(_gravity_slope(model)(q))[i, i]
    return control.tf([np.degrees(model.drive.input_gain[i])], [M, model.drive.damping[i], K],
                      inputs=f"{joint} PWM [counts]", outputs=f"{joint} [deg]")


def physics_axis(model: DrivenDynamics, joint: str, roll_deg: float, pitch_deg: float,
                 insertion: float = HOME_INSERTION) -> PhysicsAxis:
    """DC gain and poles of :func:`physics_transfer_function`."""
    G = physics_transfer_function(model, joint, roll_deg, pitch_deg, insertion)
    return PhysicsAxis(dc_gain(G), G.poles())


def _gravity_slope(model: DrivenDynamics) -> ca.Function:
    q = ca.SX.sym("q", 3)
    return ca.Function("gravity_slope", [q], [ca.jacobian(model.gravity(q), q)])


def identify_log(path, joint: str, method: str | None = None, order: int | None = None, zeros: int | None = None,
                 samples: int = 1000, segment: int | None = None, model: DrivenDynamics | None = None,
                 pose_deg: tuple[float, float] | None = None) -> PoseModel:
    """Identify ``joint`` from one telemetry log. ``method`` defaults to ``step`` for the roll and
    ``prbs`` for the pitch; ``order`` to 2 (step) or 3 (PRBS) poles; ``samples`` trims a step
    record; ``segment`` is the PRBS horizon (default 500 samples). With a ``model``, the physics
    at the pose (``pose_deg`` or the file name's) is attached."""
    if joint not in AXIS:
        raise RcmKinError(f"identification is for the roll or the pitch, not '{joint}'")
    method = method or ("step" if joint == "roll" else "prbs")
    if method not in DEFAULT_ORDER:
        raise RcmKinError(f"unknown method '{method}' (choose step or prbs)")
    log = load_telemetry(path)
    record = step_record(log, joint, samples) if method == "step" else prbs_record(log, joint)
    if method == "prbs":
        segment = min(segment or PRBS_SEGMENT, record.u.size)
    order = DEFAULT_ORDER[method] if order is None else order
    fit = fit_transfer_function(record.u, record.y, record.period, order, zeros,
                                segment=segment if method == "prbs" else None)
    pose = pose_deg if pose_deg is not None else operating_point(path)
    physics = physics_axis(model, joint, *pose) if (model is not None and pose is not None) else None
    return PoseModel(Path(path), pose, record, fit, physics)


def identify_folder(folder, joint: str, model: DrivenDynamics | None = None, **options) -> list[PoseModel]:
    """:func:`identify_log` on every log of ``folder`` (CSV or ROS 2 bag) whose name carries a pose, sorted."""
    paths = [p for p in telemetry_files(folder) if operating_point(p) is not None]
    if not paths:
        raise RcmKinError(f"no logs named like '..._roll_R_pitch_P.csv' in {folder}")
    return [identify_log(p, joint, model=model, **options) for p in paths]


def pose_table_rows(models: list[PoseModel]) -> list[dict]:
    """One flat row per pose: identified and physics DC gain and poles."""
    rows = []
    for m in models:
        row = {"file": m.path.name, "roll_deg": m.pose_deg[0] if m.pose_deg else None,
               "pitch_deg": m.pose_deg[1] if m.pose_deg else None, "u0_pwm": m.record.u0,
               "fit_percent": m.fit.fit_percent, "num": m.fit.num.tolist(), "den": m.fit.den.tolist(),
               "dc_gain": m.fit.dc_gain, "poles": _pole_text(m.fit.poles)}
        if m.physics is not None:
            row.update(physics_dc_gain=m.physics.dc_gain, physics_poles=_pole_text(m.physics.poles),
                       dc_gain_ratio=m.fit.dc_gain / m.physics.dc_gain)
        rows.append(row)
    return rows


def _pole_text(poles: np.ndarray) -> str:
    return " ".join(f"{p.real:.3g}{p.imag:+.3g}j" if abs(p.imag) > 1e-9 else f"{p.real:.3g}"
                    for p in sorted(poles, key=lambda p: (p.real, p.imag)))


def write_pose_table(models: list[PoseModel], path: str | Path) -> Path:
    rows = pose_table_rows(models)
    path = Path(path)
    with atomic_open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(max(rows, key=len)))
        writer.writeheader()
        writer.writerows(rows)
    return path

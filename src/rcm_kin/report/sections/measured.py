"""Measured data: calibration on the holding efforts and identification per pose."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from rcm_kin.errors import output_folder
from rcm_kin.model import load_robot
from rcm_kin.report.render import Table, relative

LOG_FOLDERS = (("roll-step", "roll", "step, 2 poles"), ("pitch-prbs", "pitch", "PRBS, 3 poles"))


@dataclass(frozen=True)
class PoseModels:
    joint: str
    method: str            # e.g. "step, 2 poles"
    table: Table
    csv: str


@dataclass(frozen=True)
class MeasuredSection:
    template: ClassVar[str] = "measured.html.j2"
    data_name: str         # the data folder's name (no absolute path in the report)
    calibration: Table
    holding_points: int
    residual_rms: tuple[float, float]   # PWM, roll and pitch
    pose_models: tuple[PoseModels, ...]


def _calibration(data: Path, params) -> tuple[Table, int, tuple[float, float]]:
    from rcm_kin.identification.calibration import calibrate, calibration_logs, holding_points

    points = holding_points(calibration_logs(data))
    cal = calibrate(load_robot("psm"), params, points)
    table = Table.of([[n, f"{v:+.4g}", f"{sd:.2g}"] for n, v, sd in zip(cal.names, cal.values, cal.std)],
                     ["parameter", "value", "std"])
    return table, len(points), (float(cal.residual_rms[0]), float(cal.residual_rms[1]))


def _pose_models(logs: Path, joint: str, method: str, model, folder: Path, out: Path) -> PoseModels:
    from rcm_kin.identification.pose_models import identify_folder, pose_table_rows, write_pose_table

    models = identify_folder(logs, joint, model)
    path = write_pose_table(models, folder / f"{joint}_pose_models.csv")
    rows = [[r["file"], f"{r['fit_percent']:.1f}", f"{r['dc_gain']:+.4f}", r["poles"],
             f"{r.get('physics_dc_gain', float('nan')):+.4f}", r.get("physics_poles", "")]
            for r in pose_table_rows(models)]
    return PoseModels(joint, method, Table.of(rows, ["log", "fit %", "DC (deg/PWM)", "poles (1/s)", "physics DC",
                                                     "physics poles"]), relative(path, out))


def measured_section(out: Path, data: Path) -> MeasuredSection:
    """Calibrate and identify the first ``roll-step`` and ``pitch-prbs`` folders below ``data``;
    files into ``out/identification``. (The identified drive trains have their own section,
    :mod:`rcm_kin.report.sections.drive_train`; the smooth grey-box fit they replace stays
    available as ``rcm-kin greybox``.)"""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.state_space import driven_dynamics

    params = load_drive_parameters()
    calibration, points, rms = _calibration(data, params)
    model = driven_dynamics(load_robot("psm"), params, coulomb=False)
    folder = output_folder(out / "identification")
    pose_models = []
    for sub, joint, method in LOG_FOLDERS:
        found = sorted(data.glob(f"**/{sub}"))
        if found:
            pose_models.append(_pose_models(found[0], joint, method, model, folder, out))
    return MeasuredSection(data.name, calibration, points, rms, tuple(pose_models))

"""Measured data: the identified drive trains against the logs, each log also predicted by the
model fitted without it (leave-one-log-out), with a figure per log."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.errors import output_folder
from rcm_kin.report.render import Table, relative


@dataclass(frozen=True)
class DriveTrainSection:
    template: ClassVar[str] = "drive_train.html.j2"
    joint: str
    parameters: Table          # name, value (shipped)
    checks: Table              # per log: in-sample and cross-validated fit, travel, final error, stick times
    figures: tuple[tuple[str, str], ...]   # (log, relative path)
    mean_cv_fit: float
    worst_travel_error: float  # fraction


def drive_train_section(out: Path, data: Path, joint: str = "roll", cv: bool = False) -> DriveTrainSection | None:
    """The shipped ``joint`` drive train on the step logs below ``data``: per log the fit of the
    shipped model and (``cv``, minutes: off in the report, whose text points to ``rcm-kin identify
    --cv``) of the model fitted on the other logs; figures into ``out/identification``. None when
    the shipped set has no drive train for ``joint`` or no log can show it."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.stick_slip import axis_plant
    from rcm_kin.identification.drive_train import (
        DEFAULT_TERMS,
        axis_log,
        check_log,
        leave_one_out,
        predict_log,
        search_for,
    )
    from rcm_kin.identification.figures import prediction_figure
    from rcm_kin.identification.identify import base_model
    from rcm_kin.identification.log_catalog import catalog

    params = load_drive_parameters()
    friction = params.drive_train.get(joint)
    steps = [e for e in catalog([data], (joint,)) if e.kind == "step"]
    if friction is None or not steps:
        return None
    model = base_model(params)
    logs = [axis_log(e.path, joint) for e in steps]
    plants = [axis_plant(model, joint, g.pose) for g in logs]
    shipped = [check_log(g.name, g.measured, predict_log(friction, p, g), g.period) for g, p in zip(logs, plants)]
    crossed = leave_one_out(search_for(DEFAULT_TERMS), plants, logs)[0] if cv and len(logs) > 1 else []
    folder = output_folder(out / "identification")
    figures = []
    for g, p, c in zip(logs, plants, shipped):
        path = prediction_figure(g.time, np.degrees(g.measured), np.degrees(predict_log(friction, p, g)),
                                 folder / f"predict_{Path(g.name).stem}.png", f"{g.name}: shipped model, fit "
                                 f"{c.fit_percent:.1f} %")
        figures.append((g.name, relative(path, out)))
    header = ["log", "fit % (shipped)", "travel (deg)", "final error (deg)", "stick time (s)", "model's stick time (s)"]
    rows = [[c.name, f"{c.fit_percent:.1f}", f"{c.travel_deg:+.2f}", f"{c.final_error_deg:+.2f}", f"{c.stick_time:.2f}",
             f"{c.predicted_stick_time:.2f}"] for c in shipped]
    if crossed:                              # the left-out columns only where they were computed
        header += ["fit % (left out)", "final error, left out (deg)", "travel error, left out"]
        rows = [r + [f"{x.fit_percent:.1f}", f"{x.final_error_deg:+.2f}", f"{100 * x.travel_error:.0f} %"]
                for r, x in zip(rows, crossed)]
    values = Table.of([[k, f"{v:.4g}"] for k, v in friction.as_dict().items() if v], ["parameter", "value (SI)"])
    return DriveTrainSection(joint, values, Table.of(rows, header), tuple(figures),
                             float(np.mean([x.fit_percent for x in crossed])) if crossed else float("nan"),
                             max((x.travel_error for x in crossed), default=float("nan")))

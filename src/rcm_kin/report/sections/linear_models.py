"""The linear models of the gain schedule's grid: A, B and the holding PWM per pose, and poles."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.atomic import write_text
from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.report.render import Table


@dataclass(frozen=True)
class LinearModelsSection:
    template: ClassVar[str] = "linear_models.html.j2"
    table: Table
    data: str              # the JSON of every model


def _poles(A: np.ndarray) -> str:
    return " ".join(f"{p.real:+.3g}{p.imag:+.2g}j" if abs(p.imag) > 1e-9 else f"{p.real:+.3g}"
                    for p in sorted(np.linalg.eigvals(A), key=lambda p: p.real))


def linear_models_section(out: Path, schedule: GainSchedule) -> LinearModelsSection:
    """Write ``out/linear_models.json`` and tabulate the input gains and poles per pose."""
    models, rows = [], []
    for j, pitch in enumerate(schedule.pitch_deg):
        for i, roll in enumerate(schedule.roll_deg):
            A, B = schedule.A[j, i], schedule.B[j, i]
            models.append({"roll_deg": float(roll), "pitch_deg": float(pitch), "insertion_m": schedule.insertion,
                           "A": A.tolist(), "B": B.tolist(), "u_hold_pwm": schedule.u_hold[j, i].tolist()})
            rows.append([f"{roll:g}", f"{pitch:g}", f"{B[3, 0]:+.4g}", f"{B[4, 1]:+.4g}", _poles(A)])
    write_text(out / "linear_models.json", json.dumps(models, indent=1))
    return LinearModelsSection(Table.of(rows, ["roll (deg)", "pitch (deg)", "B roll (rad/s^2 per PWM)", "B pitch",
                                               "poles of A (1/s)"]), "linear_models.json")

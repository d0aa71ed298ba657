"""How a predicted angle compares with a measured one: NRMSE fit, final travel, stick time."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def fit_percent(measured: np.ndarray, predicted: np.ndarray) -> float:
    """NRMSE fit in percent (MATLAB's ``compare``): 100 (1 - |y - yhat| / |y - mean y|)."""
    spread = np.linalg.norm(measured - measured.mean())
    return float(100.0 * (1.0 - np.linalg.norm(measured - predicted) / spread)) if spread > 0 else float("nan")


@dataclass(frozen=True)
class LogCheck:
    """How a model predicts one log (angles in degrees, times in s)."""

    name: str
    fit_percent: float         # NRMSE fit of the measured angle
    travel_deg: float          # measured final travel from the start
    final_error_deg: float     # predicted minus measured final angle
    stick_time: float          # s after the start when the measured angle stops for good
    predicted_stick_time: float

    @property
    def travel_error(self) -> float:
        """Final-travel error as a fraction of the measured travel."""
        return abs(self.final_error_deg) / abs(self.travel_deg) if self.travel_deg else float("inf")


def stick_time(angle: np.ndarray, period: float, tolerance: float = np.radians(0.02)) -> float:
    """Time after which ``angle`` (rad) stays within ``tolerance`` of its final value."""
    moving = np.flatnonzero(np.abs(angle - angle[-1]) > tolerance)
    return float((moving[-1] + 1) * period) if moving.size else 0.0


def check_log(name: str, measured: np.ndarray, predicted: np.ndarray, period: float) -> LogCheck:
    """Fit, final travel and stick time of ``predicted`` against ``measured`` (rad, same grid)."""
    travel = np.degrees(measured[-1] - measured[0])
    return LogCheck(name, fit_percent(measured, predicted), float(travel),
                    float(np.degrees(predicted[-1] - measured[-1])), stick_time(measured, period),
                    stick_time(predicted, period))

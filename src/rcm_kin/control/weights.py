"""Weights of the LQR/LQI designs, as Bryson budgets (kept free of heavy imports: the CLI reads the defaults)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import PWM_LIMIT


@dataclass(frozen=True)
class Weights:
    """LQR/LQI weights by Bryson's rule: each term is divided by the square of its budget,
    ``Q = diag(1/e^2, 1/v^2[, 1/E^2])``, ``R = 1/u^2``.

    The defaults aim the closed loops at about 20-25 rad/s: fast enough that the thesis's
    sinusoids (3 s period, 2.1 rad/s) are tracked within a few per cent of their amplitude,
    slow enough for the 400 Hz loop and the roll's velocity filter (EMA 0.9: a pole at
    42 rad/s), which :func:`firmware_loop_matrix` checks. A 2 deg error may use the full
    firmware PWM range (:data:`rcm_kin.hardware.PWM_LIMIT`: roll 100, pitch 150 counts);
    100 deg/s is a fast but ordinary joint speed; the pitch integral budget of 0.5 deg s lets
    the integrator remove a friction-sized offset in a fraction of a second without dominating
    the transient.
    """

    roll_error_deg: float = 2.0
    roll_rate_deg_s: float = 100.0
    roll_pwm: float = float(PWM_LIMIT[0])
    pitch_error_deg: float = 2.0
    pitch_rate_deg_s: float = 100.0
    pitch_integral_deg_s: float = 0.5
    pitch_pwm: float = float(PWM_LIMIT[1])

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not (np.isfinite(value) and value > 0):
                raise RcmKinError(f"weight budget {name} must be a positive number, got {value}")

    def roll(self) -> tuple[np.ndarray, np.ndarray]:
        return np.diag([self.roll_error_deg**-2, self.roll_rate_deg_s**-2]), np.array([[self.roll_pwm**-2]])

    def pitch(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.diag([self.pitch_error_deg**-2, self.pitch_rate_deg_s**-2, self.pitch_integral_deg_s**-2]),
                np.array([[self.pitch_pwm**-2]]))

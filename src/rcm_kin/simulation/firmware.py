"""What the PSM microcontroller sees and sends, as the thesis firmware does it.

The defaults are the flashed firmware's numbers (:mod:`rcm_kin.hardware`):

- Encoders: the angle is a whole number of counts (roll 0.009 deg, pitch 0.0135 deg,
  insertion 0.030 mm per count), optionally with random count noise.
- Velocity: backward difference of the measured angle over the period; the roll's is
  smoothed by an EMA ``vf = a vf + (1 - a) v_raw`` (a = 0.9), the pitch's is raw.
- PWM: the controller's command is saturated (roll +-100, pitch +-150, insertion +-100 counts)
  and sent as a whole number of counts (truncated toward zero, as a C ``int`` cast does).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import DRIVER_PWM_RANGE, ENCODER_COUNT, FIRMWARE_PERIOD, PWM_LIMIT, ROLL_FILTER


@dataclass(frozen=True)
class FirmwareSettings:
    """Sampling, sensing and actuation of the controller (units as stated per field)."""

    period: float = FIRMWARE_PERIOD                                         # s
    pwm_limit: np.ndarray = field(default_factory=lambda: PWM_LIMIT.copy())  # counts (roll, pitch, insertion)
    encoder_count: np.ndarray = field(default_factory=lambda: ENCODER_COUNT.copy())  # deg, deg, m; 0: exact
    roll_filter: float = ROLL_FILTER                                        # EMA coefficient of the roll velocity
    quantise_pwm: bool = True
    noise_counts: float = 0.0                                               # std of encoder noise, counts

    def __post_init__(self):
        limits = np.asarray(self.pwm_limit, dtype=float)
        counts = np.asarray(self.encoder_count, dtype=float)
        if not (np.isfinite(self.period) and self.period > 0):
            raise RcmKinError(f"the controller period must be a positive number of seconds, got {self.period}")
        if limits.shape != (3,) or np.any(~(limits > 0)) or np.any(limits > DRIVER_PWM_RANGE):
            raise RcmKinError(f"PWM limits are 3 values in (0, {DRIVER_PWM_RANGE:g}] counts, got {limits.tolist()}")
        if counts.shape != (3,) or np.any(~(counts >= 0)):
            raise RcmKinError(f"encoder resolutions are 3 values >= 0, got {counts.tolist()}")
        if not (0 <= self.roll_filter < 1) or not (self.noise_counts >= 0):
            raise RcmKinError("the roll filter coefficient is in [0, 1) and the noise a std >= 0 counts")


def encoder_reading(settings: FirmwareSettings, position: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Measured (roll deg, pitch deg, insertion m) of the true position in the same units."""
    count = settings.encoder_count
    exact = count == 0
    counts = np.round(position / np.where(exact, 1.0, count))
    if settings.noise_counts:
        counts = counts + np.round(rng.normal(0.0, settings.noise_counts, 3))
    return np.where(exact, position, counts * count)


def velocity_estimate(settings: FirmwareSettings, measured: np.ndarray, previous: np.ndarray,
                      filtered: np.ndarray) -> np.ndarray:
    """Firmware velocity (deg/s, deg/s, m/s): backward difference, EMA on the roll only."""
    raw = (measured - previous) / settings.period
    a = settings.roll_filter
    return np.array([a * filtered[0] + (1 - a) * raw[0], raw[1], raw[2]])


def sent_pwm(settings: FirmwareSettings, command: np.ndarray) -> np.ndarray:
    """The PWM the drivers receive: saturated, then whole counts."""
    u = np.clip(command, -settings.pwm_limit, settings.pwm_limit)
    return np.trunc(u) if settings.quantise_pwm else u

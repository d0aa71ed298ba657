"""What the PSM microcontroller sees and sends, as the thesis firmware does it.

The defaults are the flashed firmware's numbers (:mod:`rcm_kin.hardware`):

- Encoders: the angle is a whole number of counts (roll 0.009 deg, pitch 0.0135 deg,
  insertion 0.030 mm per count), optionally with random count noise.
- Velocity: backward difference of the measured angle over the period; the roll's is
  smoothed by an EMA ``vf = a vf + (1 - a) v_raw`` (a = 0.9), the pitch's is raw.
- PWM: the controller's command is saturated (roll +-100, pitch +-150, insertion +-100 counts)
  and sent as a whole number of counts (truncated toward zero, as a C ``int`` cast does).

The rules themselves are stated in :mod:`rcm_kin.firmware_rules`; the functions here apply
them with a :class:`FirmwareSettings`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.firmware_rules import quantise_axes, saturate, velocity_estimate
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
    """Measured (roll deg, pitch deg, insertion m) of the true position in the same units
    (:func:`rcm_kin.firmware_rules.quantise`); with noise, 3 whole counts drawn from ``rng``."""
    noise = np.round(rng.normal(0.0, settings.noise_counts, 3)) if settings.noise_counts else np.zeros(3)
    return quantise_axes(position, settings.encoder_count, noise)


def firmware_velocity(settings: FirmwareSettings, measured: np.ndarray, previous: np.ndarray,
                      filtered: np.ndarray) -> np.ndarray:
    """Firmware velocity (deg/s, deg/s, m/s): :func:`rcm_kin.firmware_rules.velocity_estimate`."""
    return velocity_estimate(measured, previous, filtered, settings.period, settings.roll_filter)


def sent_pwm(settings: FirmwareSettings, command: np.ndarray) -> np.ndarray:
    """The PWM the drivers receive: :func:`rcm_kin.firmware_rules.saturate` at the settings' limits."""
    return saturate(command, settings.pwm_limit, settings.quantise_pwm)

"""What the robot's fast experiments say about the friction at speed: upper bounds the
identification must satisfy (constraints, not validation).

The identified logs are slow (the roll steps move at 2-17 deg/s); the thesis's P-controller
sinusoids and the pitch's PWM-ramp runaway are fast, and each bounds the sliding friction at
its speed:

- **P-sinusoid** (thesis Sec. 5.2.1): roll and pitch track ``A sin(2 pi t / T)`` together under
  ``u = Kp e`` (:data:`rcm_kin.hardware.P_GAINS`), with a measured maximum error ``e_max``
  (:data:`rcm_kin.thesis.SINE_TRACKING_ERROR_DEG`). At the zero crossing (roll = pitch = 0) the
  speed peaks at ``A 2 pi / T`` and the acceleration is zero, so the controller's PWM, at most
  ``Kp e_max``, carries the holding effort there (gravity, ``|g(0) / k_u|`` counts), the back-EMF
  and the friction: ``friction(v) <= |k_u| (Kp e_max - |hold|) - b_emf v`` (N m). Gravity is taken
  to add to the friction: on the crossing in one of the two directions it does.
- **Runaway** (the pitch PWM ramp log, ``pitch_speed_ramp_down_response.csv``): near -115 counts
  the pitch breaks away and swings to its far stop, its speed peaking at about 130 deg/s. At the
  peak the acceleration is zero and the drive torque balances back-EMF, friction and gravity,
  gravity assumed to oppose the rising pitch (the model's holding PWM is negative over the whole
  range): ``friction(v) <= |k_u u| - b_emf v``. Its position column holds raw encoder counts
  (data README), a negative PWM raises the pitch (hardware sign -1): the angle is
  ``-counts x ENCODER_COUNT`` deg.

The friction at speed ``v`` of an :class:`AxisFriction` sliding: Coulomb (link and motor), the
Stribeck excess ``(F_s - F_c) exp(-(v/v_s)^2)``, the presliding spring's slip force (it slides
saturated), and viscous (link and motor) ``(b + b_m) v``. ``k_u`` carries the calibrated volts
per PWM, whose +-15 % uncertainty the bounds share.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, load_drive_parameters
from rcm_kin.dynamics.state_space import DrivenDynamics, drive_constants, holding_pwm
from rcm_kin.hardware import ENCODER_COUNT, HOME_INSERTION, P_GAINS
from rcm_kin.identification.telemetry import TelemetryLog, load_telemetry
from rcm_kin.thesis import SINE_AMPLITUDE_DEG, SINE_CYCLE_S, SINE_TRACKING_ERROR_DEG

AXES = ("roll", "pitch")
RAMP_LEVELS = 20      # distinct PWM levels that make a log a ramp (the ramp log has about 130)
RAMP_START = 2.0      # counts: a ramp starts within this of 0
ACTIVE = 0.01         # a bound within this fraction of its limit is active


@dataclass(frozen=True)
class SpeedBound:
    """The sliding friction of ``joint`` at ``speed`` (rad/s) is at most ``max_force`` (N m)."""

    name: str
    joint: str
    speed: float          # rad/s
    max_force: float      # N m
    source: str

    def value(self, friction: AxisFriction) -> float:
        """``friction``'s sliding friction at :attr:`speed` (N m; see the module text)."""
        return sliding_friction(friction, self.speed)

    def active(self, friction: AxisFriction) -> bool:
        """Whether ``friction`` is on the bound (within :data:`ACTIVE` of it, or beyond)."""
        return self.value(friction) >= (1.0 - ACTIVE) * self.max_force

    def as_dict(self, friction: AxisFriction) -> dict:
        value = self.value(friction)
        return {"joint": self.joint, "speed_rad_s": self.speed, "value_n_m": value, "limit_n_m": self.max_force,
                "active": bool(self.active(friction)), "satisfied": bool(value <= self.max_force * (1 + 1e-9)),
                "source": self.source}


def sliding_friction(friction: AxisFriction, speed: float) -> float:
    """Friction (N m) that opposes ``friction``'s axis sliding at ``speed`` rad/s (> 0)."""
    f = friction
    stribeck = max(f.static - f.coulomb, 0.0) * np.exp(-(speed / f.stribeck_velocity) ** 2)
    return float(f.coulomb + f.motor_coulomb + stribeck + f.presliding_force + (f.viscous + f.motor_viscous) * speed)


def back_emf(params: DriveParameters, joint: str) -> float:
    """The drive's back-EMF damping of ``joint`` (N m s/rad): its damping without the viscous friction."""
    i = DRIVEN.index(joint)
    return float(drive_constants(params).damping[i] - params[joint].viscous)


def sinusoid_bound(model: DrivenDynamics, params: DriveParameters, joint: str) -> SpeedBound:
    """The P-controller sinusoid's bound on ``joint`` (see the module text); ``model``: the
    rigid-body model with the drive (its gravity gives the holding effort at the crossing)."""
    k = AXES.index(joint)
    speed = np.radians(SINE_AMPLITUDE_DEG[k]) * 2.0 * np.pi / SINE_CYCLE_S
    hold = abs(float(holding_pwm(model, np.array([0.0, 0.0, HOME_INSERTION]))[model.joints.index(joint)]))
    error = SINE_TRACKING_ERROR_DEG[("p", joint)][0]
    effort = P_GAINS[k] * error
    gain = abs(float(drive_constants(params).input_gain[DRIVEN.index(joint)]))
    limit = gain * (effort - hold) - back_emf(params, joint) * speed
    return SpeedBound(f"{joint}_p_sinusoid", joint, float(speed), float(limit),
                      f"thesis Sec. 5.2.1: Kp {P_GAINS[k]:g} x max error {error:g} deg "
                      f"= {effort:.1f} PWM, minus the holding {hold:.1f} PWM at roll = pitch = 0, at "
                      f"{np.degrees(speed):.1f} deg/s")


def is_ramp(log: TelemetryLog) -> bool:
    """Whether ``log`` is the pitch's open-loop PWM ramp: the pitch PWM from about 0 (the log's first
    sample reads -1), monotone, through at least :data:`RAMP_LEVELS` levels."""
    if "pitch" not in log.pwm or "pitch" not in log.position:
        return False
    u = log.pwm["pitch"]
    steps = np.diff(u)
    monotone = np.all(steps <= 0) or np.all(steps >= 0)
    return bool(abs(u[0]) <= RAMP_START and np.unique(u).size >= RAMP_LEVELS and monotone)


def damping_bound(source, params: DriveParameters | None = None) -> dict:
    """The runaway at the end of the pitch ramp log ``source`` (path or log) with the drive of
    ``params`` (default: the shipped set): time (s), speed
    peak (deg/s), PWM there (counts), back-EMF damping and the bound on the viscous friction
    beyond it (N m s/rad), the travel (deg) and the bound on the friction at the peak (N m)."""
    log, i = (source if isinstance(source, TelemetryLog) else load_telemetry(source)), DRIVEN.index("pitch")
    params = params or load_drive_parameters()
    angle = -log.position["pitch"] * ENCODER_COUNT[i]                   # counts -> deg
    t, u = log.time, log.pwm["pitch"]
    speed = np.gradient(angle, t)                                       # central differences
    k = int(np.argmax(speed))
    emf = back_emf(params, "pitch")
    v_peak = np.radians(speed[k])
    torque = abs(float(drive_constants(params).input_gain[i]) * u[k])
    return {"time_s": float(t[k]), "speed_deg_s": float(speed[k]), "pwm": float(u[k]), "back_emf": emf,
            "viscous_bound": float(torque / v_peak - emf), "travel_deg": float(np.ptp(angle)),
            "speed_rad_s": float(v_peak), "max_force": float(torque - emf * v_peak)}


def runaway_bound(source, params: DriveParameters) -> SpeedBound:
    """The pitch runaway's bound (see the module text) from the ramp log ``source``."""
    b = damping_bound(source, params)
    name = source.path.name if isinstance(source, TelemetryLog) else str(source)
    return SpeedBound("pitch_runaway", "pitch", b["speed_rad_s"], b["max_force"],
                      f"{name}: {b['pwm']:.0f} PWM at the {b['speed_deg_s']:.0f} deg/s speed peak "
                      f"(viscous <= {b['viscous_bound']:.2f} N m s/rad)")


def speed_bounds(model: DrivenDynamics, params: DriveParameters, joint: str, logs=()) -> tuple[SpeedBound, ...]:
    """Every bound on ``joint``: its P-sinusoid's, and for the pitch the runaway's when a ramp log
    (:func:`is_ramp`) is among ``logs`` (telemetry logs already read)."""
    bounds = [sinusoid_bound(model, params, joint)]
    if joint == "pitch":
        bounds += [runaway_bound(log, params) for log in logs if is_ramp(log)][:1]
    return tuple(bounds)

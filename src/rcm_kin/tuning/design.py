"""What the tuning chooses: the firmware's state-feedback law with its gains, feedforwards and
compensation as a vector of named, bounded design parameters.

The law is the one the firmware runs for the model-based schedule
(:class:`~rcm_kin.simulation.controllers.StateFeedbackController`, ``track_velocity``, gravity and
friction feedforward on): roll ``u = -(Kp e + Kd (v - rdot)) + u_hold + u_fc``, pitch
``u = -(Kp e + Kd (v - rdot) + Ki E) + F_v rdot + F_a rddot + u_hold + u_fc`` with the error
integral's conditional anti-windup, ``u_fc = -F tanh(rdot / v_ramp)`` the sliding-friction
compensation (:class:`~rcm_kin.control.friction.FrictionCompensation`). A design is
:class:`DesignSpace` (the parameters, their bounds, each bound's reason) and a point of it;
:func:`tuned_schedule` writes the point into the tables of a
:class:`~rcm_kin.control.gain_schedule.GainSchedule`, so the tuned law runs in both engines and
exports to ``gain_schedule.h`` as the designed one does.

Two spaces: ``fixed`` (one gain set at every pose) and ``scheduled`` (the proportional gains of
both axes affine in roll and pitch over the thesis grid, written exactly by its 3 x 3 bilinear
tables). Bounds: the gains whose quantisation the firmware can carry (one encoder count of
position error, or of velocity over one period through the roll's EMA, moves the PWM by at most
:data:`PWM_PER_COUNT` counts), the friction compensation within the PWM the identified sliding
friction and the holding band span, and a friction ramp from a few encoder counts per period.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from rcm_kin.control.friction import FrictionCompensation
from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG, GainSchedule, closed_loop_matrix
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import ENCODER_COUNT, FIRMWARE_PERIOD, PWM_LIMIT, ROLL_FILTER

PWM_PER_COUNT = 0.1 * PWM_LIMIT[0]   # PWM counts one encoder count may move through a gain: 10 % of the roll's range
VELOCITY_COUNT = ENCODER_COUNT[:2] / FIRMWARE_PERIOD * np.array([1 - ROLL_FILTER, 1.0])  # deg/s of one count


@dataclass(frozen=True)
class Parameter:
    """One design parameter: its bounds (``log``: searched on the logarithm), unit and reason."""

    name: str
    low: float
    high: float
    unit: str
    reason: str
    log: bool = False

    def from_unit(self, x: float) -> float:
        """The value at ``x`` in [0, 1] of the search's unit box."""
        if self.log:
            return float(np.exp(np.log(self.low) + x * (np.log(self.high) - np.log(self.low))))
        return float(self.low + x * (self.high - self.low))

    def to_unit(self, value: float) -> float:
        """Inverse of :meth:`from_unit`, clipped to [0, 1]."""
        value = float(np.clip(value, self.low, self.high))
        if self.log:
            x = (np.log(value) - np.log(self.low)) / (np.log(self.high) - np.log(self.low))
        else:
            x = (value - self.low) / (self.high - self.low)
        return float(np.clip(x, 0.0, 1.0))


def _kp(axis: int) -> float:
    return PWM_PER_COUNT / ENCODER_COUNT[axis]


def _kd(axis: int) -> float:
    return PWM_PER_COUNT / VELOCITY_COUNT[axis]


_QUANTUM = f"one encoder count moves the PWM by at most {PWM_PER_COUNT:g} counts"
FIXED = (
    Parameter("roll_kp", 10.0, _kp(0), "PWM/deg", _QUANTUM, log=True),
    Parameter("roll_kd", -_kd(0), 0.0, "PWM/(deg/s)", _QUANTUM + " (velocity over one period, after the EMA); "
              "<= 0: damping (the hardware sign)"),
    Parameter("pitch_kp", 10.0, _kp(1), "PWM/deg", _QUANTUM, log=True),
    Parameter("pitch_kd", -_kd(1), 0.0, "PWM/(deg/s)", _QUANTUM + " (velocity over one period); <= 0: damping"),
    Parameter("pitch_ki", 1.0, 3000.0, "PWM/(deg s)", "from the thesis's order (0.15) to beyond the LQI's (300)",
              log=True),
    Parameter("roll_friction_pwm", 0.0, 40.0, "PWM", "about 3x the sliding friction the shipped drive file "
              "identifies (11.7 PWM)"),
    Parameter("pitch_friction_pwm", 0.0, 40.0, "PWM", "about 3x the sliding friction the shipped drive file "
              "identifies (13.3 PWM)"),
    Parameter("friction_ramp_deg_s", 0.5, 40.0, "deg/s", "a few velocity counts to the sinusoid's peak speed",
              log=True),
    Parameter("pitch_feedforward", 0.0, 2.0, "1", "scale of the model inverse F_v rdot + F_a rddot (1: as designed)"),
)
SLOPES = (
    Parameter("roll_kp_roll_slope", -0.5, 0.5, "1", "relative change of roll Kp from the grid's centre to roll +20"),
    Parameter("roll_kp_pitch_slope", -0.5, 0.5, "1", "relative change of roll Kp to pitch +15 deg"),
    Parameter("pitch_kp_roll_slope", -0.5, 0.5, "1", "relative change of pitch Kp to roll +20 deg"),
    Parameter("pitch_kp_pitch_slope", -0.5, 0.5, "1", "relative change of pitch Kp to pitch +15 deg"),
)
SCHEDULED = FIXED + SLOPES
SPACES = {"fixed": FIXED, "scheduled": SCHEDULED, "slopes": SLOPES}


@dataclass(frozen=True)
class DesignSpace:
    """The parameters one tuning searches (:data:`SPACES`: ``fixed``, ``scheduled``, or ``slopes``
    alone, the rest of a design held)."""

    kind: str = "scheduled"

    def __post_init__(self):
        if self.kind not in SPACES:
            raise RcmKinError(f"a design space is {' or '.join(SPACES)}, got {self.kind!r}", parameter="kind")

    @property
    def parameters(self) -> tuple[Parameter, ...]:
        return SPACES[self.kind]

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def values(self, unit: np.ndarray) -> dict[str, float]:
        """The design at the point ``unit`` of the unit box, by name."""
        unit = np.asarray(unit, dtype=float)
        if unit.shape != (len(self.parameters),) or not np.all(np.isfinite(unit)):
            raise RcmKinError(f"a point of the {self.kind} space has {len(self.parameters)} finite values in [0, 1]",
                              parameter="unit")
        return {p.name: p.from_unit(float(np.clip(x, 0, 1))) for p, x in zip(self.parameters, unit)}

    def unit(self, values: dict[str, float]) -> np.ndarray:
        """The unit-box point of a design given by name (missing slopes 0)."""
        return np.array([p.to_unit(values.get(p.name, 0.0)) for p in self.parameters])


def bounds_excess(values: dict[str, float]) -> float:
    """How far (relative, summed) the scheduled proportional gains leave their parameter's bounds at
    the thesis grid's corners, where the slopes act most (0 inside: the slopes may not carry a gain
    past what the quantisation bound allows)."""
    corners = pose_gains(values, np.array([-20.0, -20.0, 20.0, 20.0]), np.array([-15.0, 15.0, -15.0, 15.0]))
    excess = 0.0
    for column, p in ((0, FIXED[0]), (2, FIXED[2])):
        k = corners[:, column]
        excess += float(np.sum(np.clip(k / p.high - 1, 0, None)) + np.sum(np.clip(1 - k / p.low, 0, None)))
    return excess


def gain_tables(values: dict[str, float], roll_deg, pitch_deg) -> tuple[np.ndarray, np.ndarray]:
    """``(k_roll (np, nr, 2), k_pitch (np, nr, 3))`` of a design on a roll x pitch grid (deg): the
    proportional gains scaled by ``1 + s_r r / 20 + s_p p / 15`` (the slopes, 0 when not given)."""
    R, P = np.meshgrid(np.asarray(roll_deg, float) / 20.0, np.asarray(pitch_deg, float) / 15.0)
    scale = {axis: 1 + values.get(f"{axis}_kp_roll_slope", 0.0) * R + values.get(f"{axis}_kp_pitch_slope", 0.0) * P
             for axis in ("roll", "pitch")}
    k_roll = np.stack([values["roll_kp"] * scale["roll"], np.full(R.shape, values["roll_kd"])], axis=-1)
    k_pitch = np.stack([values["pitch_kp"] * scale["pitch"], np.full(R.shape, values["pitch_kd"]),
                        np.full(R.shape, values["pitch_ki"])], axis=-1)
    return k_roll, k_pitch


def pose_gains(values: dict[str, float], roll_deg: np.ndarray, pitch_deg: np.ndarray) -> np.ndarray:
    """The five loop gains (m, 5) (roll Kp, Kd; pitch Kp, Kd, Ki) at poses (deg), as the firmware's
    bilinear interpolation of :func:`gain_tables` gives them (exact: the design is affine)."""
    r, p = np.asarray(roll_deg, float) / 20.0, np.asarray(pitch_deg, float) / 15.0
    scale = {axis: 1 + values.get(f"{axis}_kp_roll_slope", 0.0) * np.clip(r, -1, 1)
             + values.get(f"{axis}_kp_pitch_slope", 0.0) * np.clip(p, -1, 1) for axis in ("roll", "pitch")}
    ones = np.ones_like(r)
    return np.column_stack([values["roll_kp"] * scale["roll"], values["roll_kd"] * ones,
                            values["pitch_kp"] * scale["pitch"], values["pitch_kd"] * ones, values["pitch_ki"] * ones])


def tuned_schedule(base: GainSchedule, values: dict[str, float]) -> GainSchedule:
    """``base`` (its grid, models and holding table; :func:`~rcm_kin.control.gain_schedule.schedule_gains`
    on the thesis grid, where :func:`pose_gains` and the firmware's interpolation of the tables agree)
    with the tables and feedforwards of the design ``values``."""
    if base.roll_deg.tolist() != list(THESIS_ROLL_DEG) or base.pitch_deg.tolist() != list(THESIS_PITCH_DEG):
        raise RcmKinError("a tuned design is written on the thesis grid (roll -20, 0, 20 x pitch -15, 0, 15 deg), got "
                          f"roll {base.roll_deg.tolist()} x pitch {base.pitch_deg.tolist()}", parameter="base")
    k_roll, k_pitch = gain_tables(values, base.roll_deg, base.pitch_deg)
    friction = FrictionCompensation((values["roll_friction_pwm"], values["pitch_friction_pwm"]),
                                    values["friction_ramp_deg_s"])
    A_cl = np.array([[closed_loop_matrix(base.A[j, i], base.B[j, i], k_roll[j, i], k_pitch[j, i])
                      for i in range(base.roll_deg.size)] for j in range(base.pitch_deg.size)])
    return dataclasses.replace(base, k_roll=k_roll, k_pitch=k_pitch, A_cl=A_cl, friction=friction,
                               ff_pitch=base.ff_pitch * values["pitch_feedforward"])

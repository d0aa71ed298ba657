"""Controllers of the PSM firmware, one interface: ``command(memory, sample) -> (pwm, memory)``.

A controller is a frozen dataclass of gains; what it remembers between samples (integrals,
previous errors) is the ``memory`` array it returns and is handed back, so a run is a pure
function of its inputs. Conventions of the firmware (thesis Ch. 4): roll and pitch in degrees,
insertion in metres, error ``e = r - y``, PWM with the hardware sign (a positive PWM lowers the
roll and pitch angles and extends the insertion), so ``u = -(Kp e + ...)`` for roll and pitch.
The insertion is held by the firmware's P loop (30 PWM/mm) under every controller.

The interface is :class:`Controller` (a ``typing.Protocol``). To add a controller: a dataclass
with ``name``, ``initial_memory(hold)`` and ``command``, and an entry in :func:`make_controller`.
To run it in the compiled kernel too, give it ``kernel_law(hold)``: its law as a
:class:`~rcm_kin.simulation.kernel_forms.LoopLaw` (one of the kernel's kinds with its gains and
tables). Without one it runs in the readable loop, and the runner says so with an
:class:`~rcm_kin.errors.EngineFallbackWarning`.

A run starts from the steady hold of its first pose (:class:`Hold`): a controller with an error
integral starts it where the law, at zero error and rest, sends the PWM that holds that pose. The
robot's firmware carries its holding effort in the integral once it has held a pose long enough,
and with the thesis's small ``Ki`` that charge takes minutes to build, so a run that began with an
empty integral would spend its whole length with the holding PWM missing (measured:
docs/findings.md, "How the firmware held the pitch").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from rcm_kin import thesis as thesis_reference
from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG, GainSchedule, scheduled_gains
from rcm_kin.errors import RcmKinError
from rcm_kin.firmware_rules import bilinear, conditional_integral, insertion_command, p_command
from rcm_kin.hardware import INSERTION_KP, P_GAINS
from rcm_kin.simulation.kernel_forms import PID, STATE_FEEDBACK, THESIS, LoopLaw, P, stacked

CONTROLLERS = ("p", "pid", "lqr-fixed", "scheduled", "scheduled-gravity", "scheduled-friction", "thesis")
MODEL_FREE = ("p", "pid", "thesis")        # the controllers that need no gain schedule
TUNED = "tuned"     # the state-feedback law with the tables of a gain file (default: the shipped tuned design)


@dataclass(frozen=True)
class Sample:
    """What the firmware knows at one tick; (roll deg, pitch deg, insertion m) per array."""

    position: np.ndarray                # measured (encoder counts x resolution)
    velocity: np.ndarray                # firmware estimate, deg/s, deg/s, m/s
    reference: np.ndarray
    reference_velocity: np.ndarray
    reference_acceleration: np.ndarray
    period: float                       # s
    pwm_limit: np.ndarray               # counts, for anti-windup


@dataclass(frozen=True)
class Hold:
    """The steady hold a run starts from: the first reference pose, and the PWM (hardware sign)
    that holds it at rest (the model's ``g(q) / k_u``,
    :func:`rcm_kin.dynamics.state_space.holding_pwm`)."""

    position: np.ndarray                # (3,) deg, deg, m
    pwm: np.ndarray                     # (3,) counts

    def within(self, limit: np.ndarray) -> Hold:
        """The hold with its PWM saturated at ``limit`` (3,) counts: conditional integration never
        charges an integral beyond what reaches the limit."""
        return Hold(self.position, np.clip(self.pwm, -np.asarray(limit), np.asarray(limit)))


@runtime_checkable
class Controller(Protocol):
    """What the simulated firmware runs every period (:func:`rcm_kin.simulation.loop.simulate`).

    ``command`` maps the memory and one :class:`Sample` to the PWM (3,) (counts, hardware sign,
    before saturation) and the next memory; ``initial_memory`` is the memory before the first
    sample (a float array, possibly empty): integrals charged to hold ``hold`` when given, else
    zero. Pure: no state outside ``memory``.

    Optional: ``kernel_law(hold) -> LoopLaw | None``, the same law as the arrays the compiled
    kernel runs (:class:`~rcm_kin.simulation.kernel_forms.LoopLaw`, its ``memory``
    ``initial_memory(hold)``); None, or no such method: the controller runs in the readable loop.
    The kernel's result equals ``command``'s tick for tick (the tests hold every shipped one)."""

    name: str

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        ...

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        ...


def _insertion(sample: Sample) -> float:
    return insertion_command(sample.reference[2], sample.position[2], INSERTION_KP)


def _own_law(controller, owner: type) -> bool:
    """Whether ``controller`` runs ``owner``'s law: a subclass with a ``command`` of its own has no
    kernel form until it states one (its ``kernel_law`` would describe the parent's law)."""
    return type(controller).command is owner.command


@dataclass(frozen=True)
class PController:
    """The thesis's baseline: ``u = -Kp e`` (PWM/deg), roll Kp 35, pitch Kp 60."""

    kp: tuple[float, float] = P_GAINS
    name: str = "p"

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        return np.zeros(0)

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        e = sample.reference[:2] - sample.position[:2]
        return np.array([p_command(self.kp[0], e[0]), p_command(self.kp[1], e[1]), _insertion(sample)]), memory

    def kernel_law(self, hold: Hold | None = None) -> LoopLaw | None:
        if not _own_law(self, PController):
            return None
        return LoopLaw(P, self.initial_memory(hold), gains=np.asarray(self.kp, dtype=float))


@dataclass(frozen=True)
class PIDController:
    """Thesis Table 3.4 (Ziegler-Nichols): ``u = -(Kp e + Ki E + Kd de/dt)``, ``E`` the error
    integral (deg s) with conditional anti-windup, ``de/dt`` the backward difference of the
    error (0 on the first sample). Gains per (roll, pitch): PWM/deg, PWM/(deg s), PWM/(deg/s)."""

    kp: tuple[float, float] = P_GAINS
    ki: tuple[float, float] = (50.0, 110.0)
    kd: tuple[float, float] = (5.0, 15.0)
    name: str = "pid"

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        integrals = np.zeros(2) if hold is None else -np.asarray(hold.pwm[:2]) / np.asarray(self.ki)
        return np.r_[integrals, np.nan, np.nan]          # integrals (deg s), previous errors

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        e = sample.reference[:2] - sample.position[:2]
        de = np.where(np.isnan(memory[2:]), 0.0, (e - memory[2:]) / sample.period)
        u, integral = np.zeros(3), memory[:2].copy()
        for i in range(2):
            law = lambda E, i=i: -(self.kp[i] * e[i] + self.ki[i] * E + self.kd[i] * de[i])  # noqa: E731
            u[i], integral[i] = conditional_integral(memory[i], e[i], sample.period, law, sample.pwm_limit[i])
        u[2] = _insertion(sample)
        return u, np.r_[integral, e]

    def kernel_law(self, hold: Hold | None = None) -> LoopLaw | None:
        if not _own_law(self, PIDController):
            return None
        return LoopLaw(PID, self.initial_memory(hold), gains=np.r_[self.kp, self.ki, self.kd])


@dataclass(frozen=True)
class StateFeedbackController:
    """The thesis's final structure with model-based gains: roll LQR ``u = -(Kp e + Kd w)``,
    pitch LQI ``u = -(Kp e + Kd w + Ki E) + F_v rdot + F_a rddot`` (anti-windup as the PID).

    ``w`` is the velocity error ``v - rdot`` (the LQR tracking law ``u = -K (x - x_ref)``) when
    ``track_velocity``; the thesis firmware (Listing 4.15) damps the measured ``v`` itself, which
    lags a moving reference by about ``Kd rdot / Kp`` degrees (set ``track_velocity=False``).

    ``scheduled``: gains interpolated bilinearly at the measured pose, as ``gain_schedule.h``
    does; otherwise the gains (and feedforward) at roll = pitch = 0. ``gravity``: adds the
    model's holding PWM at the reference pose (the schedule's ``u_hold`` table, interpolated).
    ``friction``: adds the sliding-friction feedforward of the schedule
    (:class:`~rcm_kin.control.friction.FrictionCompensation`) at the reference
    velocity (deg/s): ``-F tanh(rdot / v_ramp)`` counts per axis, negative for a rising reference."""

    schedule: GainSchedule
    scheduled: bool = True
    gravity: bool = False
    track_velocity: bool = True
    friction: bool = False
    name: str = "scheduled"

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        if hold is None:
            return np.zeros(1)                              # pitch error integral, deg s
        s, at = self.schedule, hold.position[:2]
        k_pitch = scheduled_gains(s, *(at if self.scheduled else np.zeros(2)))[1]
        gravity = bilinear(s.roll_deg, s.pitch_deg, s.u_hold, at[0], at[1])[1] if self.gravity else 0.0
        return np.array([-(hold.pwm[1] - gravity) / k_pitch[2]])

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        s = self.schedule
        at = sample.position[:2] if self.scheduled else np.zeros(2)
        k_roll, k_pitch = scheduled_gains(s, at[0], at[1])
        ff = bilinear(s.roll_deg, s.pitch_deg, s.ff_pitch, at[0], at[1])
        e = sample.reference[:2] - sample.position[:2]
        v = sample.velocity[:2] - (sample.reference_velocity[:2] if self.track_velocity else 0.0)
        hold = (bilinear(s.roll_deg, s.pitch_deg, s.u_hold, sample.reference[0], sample.reference[1])
                if self.gravity else np.zeros(2))
        if self.friction:
            if s.friction is None:
                raise RcmKinError("the friction-compensated controller needs a schedule with its friction feedforward")
            hold = hold + s.friction.feedforward(sample.reference_velocity[:2])
        u = np.zeros(3)
        u[0] = -(k_roll[0] * e[0] + k_roll[1] * v[0]) + hold[0]
        feedforward = ff[0] * sample.reference_velocity[1] + ff[1] * sample.reference_acceleration[1] + hold[1]
        law = lambda E: -(k_pitch[0] * e[1] + k_pitch[1] * v[1] + k_pitch[2] * E) + feedforward  # noqa: E731
        u[1], integral = conditional_integral(memory[0], e[1], sample.period, law, sample.pwm_limit[1])
        u[2] = _insertion(sample)
        return u, np.array([integral])

    def kernel_law(self, hold: Hold | None = None) -> LoopLaw | None:
        if not _own_law(self, StateFeedbackController):
            return None
        s = self.schedule
        if self.friction and s.friction is None:
            raise RcmKinError("the friction-compensated controller needs a schedule with its friction feedforward")
        roll, pitch, table = stacked(s.roll_deg, s.pitch_deg, s.k_roll, s.k_pitch, s.ff_pitch)
        extra = {"hold": s.u_hold} if self.gravity else {}
        if self.friction:
            extra["friction"] = np.r_[s.friction.pwm, s.friction.ramp_deg_s]
        return LoopLaw(STATE_FEEDBACK, self.initial_memory(hold), roll_deg=roll, pitch_deg=pitch, table=table,
                       flags=np.array([self.scheduled, self.gravity, self.track_velocity, self.friction]), **extra)


@dataclass(frozen=True)
class ThesisController:
    """The controller the thesis flashed, law and signs as in its firmware: the gain tables of
    Tables 4.4-4.8 (:mod:`rcm_kin.thesis`) interpolated bilinearly at the
    measured pose on the grid roll -20/0/20 x pitch -15/0/15 deg; roll ``u = -(Kp e + Kd v)``,
    pitch ``u = -(Kp e + Kd v + Ki E)`` with ``v`` the firmware's velocity estimate itself (not the
    velocity error) and ``E`` the error integral (conditional anti-windup); no feedforward (the
    final firmware's lambda is 0)."""

    name: str = "thesis"

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        if hold is None:
            return np.zeros(1)                              # pitch error integral, deg s
        k_pitch = bilinear(np.asarray(THESIS_ROLL_DEG), np.asarray(THESIS_PITCH_DEG), thesis_reference.K_PITCH,
                           hold.position[0], hold.position[1])
        return np.array([-hold.pwm[1] / k_pitch[2]])

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        roll, pitch = np.asarray(THESIS_ROLL_DEG), np.asarray(THESIS_PITCH_DEG)
        at = sample.position[:2]
        k_roll = bilinear(roll, pitch, thesis_reference.K_ROLL, at[0], at[1])
        k_pitch = bilinear(roll, pitch, thesis_reference.K_PITCH, at[0], at[1])
        e, v = sample.reference[:2] - sample.position[:2], sample.velocity[:2]
        u = np.zeros(3)
        u[0] = -(k_roll[0] * e[0] + k_roll[1] * v[0])
        law = lambda E: -(k_pitch[0] * e[1] + k_pitch[1] * v[1] + k_pitch[2] * E)  # noqa: E731
        u[1], integral = conditional_integral(memory[0], e[1], sample.period, law, sample.pwm_limit[1])
        u[2] = _insertion(sample)
        return u, np.array([integral])

    def kernel_law(self, hold: Hold | None = None) -> LoopLaw | None:
        if not _own_law(self, ThesisController):
            return None
        roll, pitch, table = stacked(THESIS_ROLL_DEG, THESIS_PITCH_DEG, thesis_reference.K_ROLL,
                                     thesis_reference.K_PITCH)
        return LoopLaw(THESIS, self.initial_memory(hold), roll_deg=roll, pitch_deg=pitch, table=table)


def make_controller(name: str, schedule: GainSchedule | None = None) -> Controller:
    """The controller called ``name`` (one of :data:`CONTROLLERS`); the model-based ones need the
    gain schedule (:func:`rcm_kin.control.gain_schedule.schedule_gains`)."""
    if name in MODEL_FREE:
        return {"p": PController, "pid": PIDController, "thesis": ThesisController}[name]()
    if name not in CONTROLLERS:
        raise RcmKinError(f"unknown controller '{name}' (choose from {', '.join(CONTROLLERS)})")
    if schedule is None:
        raise RcmKinError(f"the '{name}' controller needs a gain schedule")
    return StateFeedbackController(schedule, scheduled=name != "lqr-fixed",
                                   gravity=name in ("scheduled-gravity", "scheduled-friction"),
                                   friction=name == "scheduled-friction", name=name)

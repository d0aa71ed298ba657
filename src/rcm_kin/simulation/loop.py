"""The sampled closed loop: encoder -> velocity estimate -> controller -> PWM (held) -> plant.

The readable reference of the closed loop, and the fallback of the compiled kernel
(:mod:`rcm_kin.simulation.compiled_loop`) where a controller or a plant has no kernel form; the
firmware's rules it applies are stated in :mod:`rcm_kin.firmware_rules`.

At tick ``k`` (time ``k T``) the firmware reads the encoders, estimates the velocities, runs
the controller and sends the PWM, which the plant integrates over ``[k T, (k + 1) T)``. Before
``t = 0`` the loop holds the reference's first pose for ``settle`` s, so every experiment starts
from the pose the controller holds (with its steady error), as the robot's did; given the
:class:`~rcm_kin.simulation.controllers.Hold` of that pose, the controller's integrals start
charged with the holding PWM (the steady state the robot's slow integrals had reached).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from tqdm import tqdm

from rcm_kin.errors import NonFiniteResultError, RcmKinError, as_number
from rcm_kin.simulation.controllers import Controller, Hold, Sample
from rcm_kin.simulation.firmware import FirmwareSettings, encoder_reading, firmware_velocity, sent_pwm
from rcm_kin.simulation.references import Reference

FIRMWARE_SCALE = np.array([np.degrees(1.0), np.degrees(1.0), 1.0])     # (rad, rad, m) -> (deg, deg, m)
AXES = ("roll", "pitch")


@dataclass(frozen=True)
class SimulationResult:
    """A run from t = 0 (the settling phase is not kept). (roll deg, pitch deg, insertion m)."""

    controller: str
    time: np.ndarray            # (N,) s
    reference: np.ndarray       # (N, 3)
    measured: np.ndarray        # (N, 3) what the firmware read (encoder counts)
    position: np.ndarray        # (N, 3) true
    command: np.ndarray         # (N, 3) controller output before saturation, counts
    pwm: np.ndarray             # (N, 3) sent to the drivers, counts
    settings: FirmwareSettings
    engine: str = "readable"    # which loop ran it: "readable" (simulate) or "compiled" (the kernel)

    @property
    def error(self) -> np.ndarray:
        """``reference - measured`` (N, 3), as the thesis logged it."""
        return self.reference - self.measured


def firmware_units(q: np.ndarray) -> np.ndarray:
    """(rad, rad, m) -> (deg, deg, m), for one pose (3,) or a stack (N, 3)."""
    return np.asarray(q) * FIRMWARE_SCALE


def si_units(q: np.ndarray) -> np.ndarray:
    """(deg, deg, m) -> (rad, rad, m), for one pose (3,) or a stack (N, 3)."""
    return np.asarray(q) / FIRMWARE_SCALE


def check_run(reference: Reference, settings: FirmwareSettings, settle: float) -> None:
    """Raise :class:`RcmKinError` unless ``reference`` is sampled at the controller period and the
    settling time ``settle`` (s) is >= 0."""
    if reference.time.size < 2 or not np.isclose(reference.time[1] - reference.time[0], settings.period, rtol=1e-9):
        raise RcmKinError("the reference must be sampled at the controller period")
    if not (np.isfinite(settle) and settle >= 0):
        raise RcmKinError(f"the settling time must be >= 0 s, got {settle}")


def simulate(step: Callable[[np.ndarray, np.ndarray], np.ndarray], controller: Controller, reference: Reference,
             settings: FirmwareSettings | None = None, seed: int = 0, settle: float = 1.0,
             progress: bool = False, initial: Callable[[np.ndarray], np.ndarray] | None = None,
             hold: Hold | None = None) -> SimulationResult:
    """Run ``controller`` on the plant ``step(x, u) -> x`` (one period; ``x[:3]`` the positions the
    encoders see, SI) along ``reference``, from rest at the first reference pose: ``initial(q)``
    when given, else ``x = [q; 0]``; the controller's memory ``initial_memory(hold)``, the hold's
    PWM saturated at the limits. A state that leaves the finite numbers raises
    :class:`~rcm_kin.errors.NonFiniteResultError` (the simulation diverged).
    Deterministic for a given ``seed`` (which only drives the optional encoder noise)."""
    for value, kind, name in ((controller, Controller, "controller"), (reference, Reference, "reference"),
                              (settings or FirmwareSettings(), FirmwareSettings, "settings")):
        if not isinstance(value, kind):
            raise RcmKinError(f"`{name}` is a {kind.__name__}, got {type(value).__name__}", parameter=name)
    if not callable(step):
        raise RcmKinError(f"`step` is a function step(x, u) -> x, got {type(step).__name__}", parameter="step")
    settings = settings or FirmwareSettings()
    check_run(reference, settings, settle)
    rng = np.random.default_rng(seed)
    n_settle, n = int(round(settle / settings.period)), reference.time.size
    x = initial(reference.position[0]) if initial else np.r_[reference.position[0], np.zeros(3)]
    ref_fw, vel_fw, acc_fw = (firmware_units(a) for a in (reference.position, reference.velocity,
                                                            reference.acceleration))
    zero = np.zeros(3)
    previous = encoder_reading(settings, firmware_units(x[:3]), rng)
    filtered = np.zeros(3)
    memory = controller.initial_memory(hold.within(settings.pwm_limit) if hold else None)
    log = {key: np.empty((n, 3)) for key in ("measured", "position", "command", "pwm")}
    for k in tqdm(range(-n_settle, n), desc=f"simulate {controller.name}", unit="tick", disable=not progress,
                  leave=False):
        i = max(k, 0)
        moving = k >= 0
        true = firmware_units(x[:3])
        measured = encoder_reading(settings, true, rng)
        filtered = firmware_velocity(settings, measured, previous, filtered)
        sample = Sample(measured, filtered, ref_fw[i], vel_fw[i] if moving else zero,
                        acc_fw[i] if moving else zero, settings.period, settings.pwm_limit)
        command, memory = controller.command(memory, sample)
        u = sent_pwm(settings, command)
        if moving:
            for key, value in (("measured", measured), ("position", true), ("command", command), ("pwm", u)):
                log[key][k] = value
        x = step(x, u)
        if not np.all(np.isfinite(x)):
            raise diverged(k, settings.period, controller.name)
        previous = measured
    return SimulationResult(controller.name, reference.time, ref_fw, log["measured"], log["position"],
                            log["command"], log["pwm"], settings)


@dataclass(frozen=True)
class AxisMetrics:
    max_error_deg: float
    mean_error_deg: float       # mean absolute error
    rms_error_deg: float
    rms_pwm: float              # control effort, counts
    mean_abs_pwm: float
    saturation_s: float         # time with the command at or beyond the PWM limit


def tracking_metrics(result: SimulationResult, skip: float = 0.0) -> dict[str, AxisMetrics]:
    """Per axis (roll, pitch): error statistics of ``reference - measured`` and the effort, from
    ``skip`` s on (e.g. past the start of a sinusoid that begins at full speed)."""
    if not isinstance(result, SimulationResult):
        raise RcmKinError(f"`result` is a SimulationResult (rk.simulate, rk.run_experiment), got "
                          f"{type(result).__name__}", parameter="result")
    skip = as_number(skip, "skip", "s", 0.0, float(result.time[-1]))
    keep = result.time >= skip
    if not keep.any():
        raise RcmKinError(f"the statistics start within the run (0 <= skip < {result.time[-1]:g} s), got {skip}",
                          parameter="skip")
    out = {}
    for i, axis in enumerate(AXES):
        e, u = result.error[keep, i], result.pwm[keep, i]
        saturated = np.abs(result.command[keep, i]) >= result.settings.pwm_limit[i]
        out[axis] = AxisMetrics(float(np.max(np.abs(e))), float(np.mean(np.abs(e))), float(np.sqrt(np.mean(e**2))),
                                float(np.sqrt(np.mean(u**2))), float(np.mean(np.abs(u))),
                                float(np.count_nonzero(saturated) * result.settings.period))
    return out


def diverged(tick: int, period: float, name: str) -> NonFiniteResultError:
    """The error of a run (controller ``name``) whose state left the finite numbers at ``tick``
    (period ``period`` s): one message for the readable loop and the compiled kernel."""
    where = f"t = {tick * period:.3f} s"
    return NonFiniteResultError(f"the simulation diverged at {where} ({name})", where=where)

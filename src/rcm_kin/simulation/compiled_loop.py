"""The whole closed loop in one compiled kernel: encoders, velocity estimate, controller law,
saturation and the plant, tick after tick inside one C function
(:func:`rcm_kin.simulation.kernel.run`, built and cached with the plant's CasADi functions: no
numba in the process).

The readable loop stays the reference (:func:`rcm_kin.simulation.loop.simulate` with the
controllers of :mod:`rcm_kin.simulation.controllers` on a :class:`~rcm_kin.simulation.plant.Plant`);
the kernel repeats its arithmetic operation for operation (each firmware rule a declared twin of
:mod:`rcm_kin.firmware_rules`), and ``tests/simulation/test_compiled_loop.py`` holds the two to
each other tick for tick.

Nothing here knows the concrete controllers or plants: :func:`loop_law` asks the controller for
its kernel form (``kernel_law(hold)``, a :class:`~rcm_kin.simulation.kernel_forms.LoopLaw`),
:func:`kernel_plant` asks the plant (``kernel_plant()``, a
:class:`~rcm_kin.simulation.compiled_plant.CompiledPlant`). :func:`run_closed_loop` runs the kernel
when both have one, else the readable loop with one :class:`~rcm_kin.errors.EngineFallbackWarning` (a controller
without a kernel form, or no C compiler for the plant's functions): never silently slower.

Encoder noise is drawn in Python from the run's generator in the reference's order (3 values for
the first reading, then 3 per tick), so both engines see the same counts.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from tqdm import tqdm

from rcm_kin.errors import EngineFallbackWarning, RcmKinError, warn
from rcm_kin.hardware import INSERTION_KP
from rcm_kin.simulation.compiled_plant import CompiledPlant
from rcm_kin.simulation.controllers import Controller, Hold
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.kernel import quantise, run
from rcm_kin.simulation.kernel_forms import LoopLaw
from rcm_kin.simulation.loop import FIRMWARE_SCALE, SimulationResult, check_run, diverged, firmware_units, simulate
from rcm_kin.simulation.plant import Plant
from rcm_kin.simulation.references import Reference

CHUNK = 4000                                       # ticks per kernel call (the progress bar's step)


def loop_law(controller: Controller, hold: Hold | None = None) -> LoopLaw | None:
    """``controller``'s kernel form with the memory ``initial_memory(hold)``: what its
    ``kernel_law(hold)`` gives; None for a controller without one (it then runs in Python)."""
    kernel_law = getattr(controller, "kernel_law", None)
    return None if kernel_law is None else kernel_law(hold)


def kernel_plant(plant: Plant) -> CompiledPlant | None:
    """``plant``'s kernel form (its ``kernel_plant()``), or None for a plant without one or whose
    functions cannot be compiled."""
    form = getattr(plant, "kernel_plant", None)
    return None if form is None else form()


def run_closed_loop(plant: Plant, controller: Controller, reference: Reference,
                    settings: FirmwareSettings | None = None, seed: int = 0, progress: bool = False,
                    hold: Hold | None = None) -> SimulationResult:
    """:func:`~rcm_kin.simulation.loop.simulate` of ``controller`` on ``plant`` from ``hold``, in the
    compiled kernel when the controller and the plant both have a kernel form (the result's
    ``engine`` is then ``"compiled"``), else in the readable loop with one
    :class:`~rcm_kin.errors.EngineFallbackWarning` saying why."""
    settings = settings or FirmwareSettings()
    law = loop_law(controller, hold.within(settings.pwm_limit) if hold else None)
    compiled = kernel_plant(plant) if law is not None else None
    if law is not None and compiled is not None:
        return simulate_compiled(compiled, law, controller.name, reference, settings, seed=seed, progress=progress)
    reason = (f"the controller '{controller.name}' has no kernel form (kernel_law)" if law is None else
              f"the plant {type(plant).__name__} has no compiled form (no kernel_plant, or no C compiler)")
    warn(f"{reason}: the closed loop runs tick by tick in the readable Python loop, slower", EngineFallbackWarning)
    return simulate(plant.step, controller, reference, settings, seed=seed, progress=progress,
                    initial=plant.initial, hold=hold)


def simulate_compiled(plant: CompiledPlant, law: LoopLaw, name: str, reference: Reference,
                      settings: FirmwareSettings | None = None, seed: int = 0, settle: float = 1.0,
                      progress: bool = False) -> SimulationResult:
    """:func:`rcm_kin.simulation.loop.simulate` of the controller ``law`` (called ``name``) on
    ``plant``, from rest at the first reference pose, in the compiled kernel: the same result."""
    settings = settings or FirmwareSettings()
    check_run(reference, settings, settle)
    if not np.isclose(plant.period, settings.period, rtol=1e-12):
        raise RcmKinError(f"the plant steps {plant.period} s, the controller {settings.period} s")
    rng = np.random.default_rng(seed)
    n_settle, n = int(round(settle / settings.period)), reference.time.size
    noise = np.zeros((n_settle + n + 1, 3))
    if settings.noise_counts:       # the reference's draws in its order, 3 per reading (one bulk draw fills
        noise = np.round(rng.normal(0.0, settings.noise_counts, noise.shape))   # row by row: tests hold it)
    x = plant.initial(reference.position[0])
    ref_fw, vel_fw, acc_fw = (np.ascontiguousarray(firmware_units(a)) for a in
                              (reference.position, reference.velocity, reference.acceleration))
    count = np.asarray(settings.encoder_count, dtype=float)
    limit = np.asarray(settings.pwm_limit, dtype=float)
    previous = np.empty(3)
    quantise(firmware_units(x[:3]), count, noise[0], previous)
    filtered, memory = np.zeros(3), np.array(law.memory, dtype=float)
    logs = [np.empty((n, 3)) for _ in range(4)]
    ticks = tqdm(total=n_settle + n, desc=f"simulate {name}", unit="tick", disable=not progress, leave=False)
    with ticks:
        for first in range(-n_settle, n, CHUNK):
            stop = min(first + CHUNK, n)
            end = run(first, stop, x, previous, filtered, memory, ref_fw, vel_fw, acc_fw, noise, settings.period,
                      limit, count, settings.roll_filter, settings.quantise_pwm, FIRMWARE_SCALE, INSERTION_KP,
                      law.kind, law.flags, law.gains, law.roll_deg, law.pitch_deg, law.table, law.hold, law.friction,
                      *plant.kernel_arguments[:-2], plant.substeps, *logs)   # the period given above
            if end != stop:
                raise diverged(end, settings.period, name)
            ticks.update(stop - first)
    return replace(SimulationResult(name, reference.time, ref_fw, *logs, settings), engine="compiled")

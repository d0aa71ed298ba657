"""A controller added in one file (here): a frozen dataclass with ``name``, ``initial_memory``,
``command`` and ``kernel_law``. Its law, a P controller with gains of its own, is one of the
kernel's kinds, so it runs in the compiled engine with no change to the package, and equals the
readable loop tick for tick."""

from __future__ import annotations

import os
import shutil
import warnings
from dataclasses import dataclass, replace

import numpy as np
import pytest
from oracles.same_run import assert_same_run

from rcm_kin.errors import EngineFallbackWarning
from rcm_kin.hardware import INSERTION_KP
from rcm_kin.simulation.controllers import Hold, Sample
from rcm_kin.simulation.experiments import closed_loop, psm_plant
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.kernel_forms import LoopLaw, P
from rcm_kin.simulation.loop import simulate
from rcm_kin.simulation.references import sine_reference, step_reference

T = 1.0 / 400.0


@dataclass(frozen=True)
class SoftP:
    """``u = -Kp e`` with gains of its own (roll 20, pitch 45 PWM/deg); the insertion by the
    firmware's P loop."""

    kp: tuple[float, float] = (20.0, 45.0)
    name: str = "soft-p"

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        return np.zeros(0)

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        e = sample.reference - sample.position
        return np.array([-self.kp[0] * e[0], -self.kp[1] * e[1], INSERTION_KP * e[2]]), memory

    def kernel_law(self, hold: Hold | None = None) -> LoopLaw:
        return LoopLaw(P, self.initial_memory(hold), gains=np.array(self.kp))


@pytest.mark.skipif(shutil.which(os.environ.get("CC") or "cc") is None, reason="no C compiler")
@pytest.mark.parametrize("drive_train", [True, False])
@pytest.mark.parametrize("experiment", ["sine", "step"])
def test_a_controller_from_one_file_runs_compiled_and_equals_the_readable_loop(params, drive_train, experiment):
    p = params if drive_train else replace(params, drive_train={})
    readable, compiled = psm_plant(p, T), psm_plant(p, T, fast=True)
    assert type(compiled).__name__ == "CompiledPlant"
    ref = sine_reference(0.8, T) if experiment == "sine" else step_reference(0.8, T, at=0.3)
    settings = FirmwareSettings(noise_counts=1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", EngineFallbackWarning)          # a fallback fails the test
        fast = closed_loop(compiled, SoftP(), ref, settings, seed=5)
    slow = simulate(readable.step, SoftP(), ref, settings, seed=5, initial=readable.initial)
    assert fast.controller == "soft-p"
    assert_same_run(fast, slow)
    # and it is its own law, not the shipped P controller's (roll 35, pitch 60)
    np.testing.assert_allclose(fast.command[:, 1], -45.0 * (fast.reference[:, 1] - fast.measured[:, 1]),
                               rtol=1e-12, atol=1e-9)

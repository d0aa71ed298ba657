"""The closed loop in one compiled kernel (issue 16) against the readable reference: the loop of
``loop.simulate`` with the controller classes on ``DriveTrainPlant.step`` and on the smooth
model's period map, tick for tick."""

from __future__ import annotations

import os
import shutil
from dataclasses import replace

import numpy as np
import pytest
from oracles.same_run import assert_same_run

from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.errors import CompilerFallbackWarning, EngineFallbackWarning, RcmKinWarning
from rcm_kin.simulation import compiled_loop, kernel_forms
from rcm_kin.simulation.compiled_loop import loop_law, run_closed_loop, simulate_compiled
from rcm_kin.simulation.compiled_plant import compiled_drive_train, compiled_smooth
from rcm_kin.simulation.controllers import CONTROLLERS, Hold, make_controller
from rcm_kin.simulation.experiments import psm_plant_and_schedule
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import firmware_units, simulate
from rcm_kin.simulation.plant import drive_train_plant, period_map
from rcm_kin.simulation.references import sine_reference, step_reference

T = 1.0 / 400.0
needs_compiler = pytest.mark.skipif(shutil.which(os.environ.get("CC") or "cc") is None,
                                    reason="no C compiler (CC hidden): the fallback run")


@pytest.fixture(scope="module")
def reference_plant(psm, params):
    """The shipped plant as the readable class, its model functions interpreted by CasADi."""
    assert params.drive_train, "the shipped parameters carry identified drive trains"
    return drive_train_plant(psm, params, T)


@pytest.fixture(scope="module", params=["drive-train", "smooth"])
def plants(request, psm, params, reference_plant):
    """(reference step, initial, compiled plant, gain schedule) of the shipped drive-train plant
    and of the smooth model (the drive trains stripped), the reference interpreted by CasADi."""
    if request.param == "drive-train":
        compiled = compiled_drive_train(reference_plant)
        return reference_plant.step, reference_plant.initial, compiled, psm_plant_and_schedule(params)[1]
    smooth_params = replace(params, drive_train={})
    smooth = period_map(driven_dynamics(psm, smooth_params).forward, T)
    compiled = compiled_smooth(smooth, T)
    return (lambda x, u: np.array(smooth(x, u)).ravel(), compiled.initial, compiled,
            psm_plant_and_schedule(smooth_params)[1])


@needs_compiler
def test_plant_step_equals_the_reference_plant(plants):
    """One period from varied states and PWMs: the C model functions called from the C kernel (and its
    stick-slip twin), against ``DriveTrainPlant.step`` or the smooth period map (interpreted
    CasADi), to 1e-12."""
    step, initial, fast, _ = plants
    rng = np.random.default_rng(1)
    x = initial([0.2, -0.25, 0.09])
    for _ in range(200):
        u = rng.uniform(-150, 150, 3)
        expected = step(x, u)
        got = fast.step(x, u)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
        x = expected
    assert np.ptp(x[3:6]) > 0.1                      # the plant moved (rad/s)


@needs_compiler
@pytest.mark.parametrize("noise", [0.0, 1.0])
@pytest.mark.parametrize("experiment", ["sine", "step"])
def test_compiled_loop_equals_the_reference_tick_for_tick(plants, experiment, noise):
    """Every controller, with and without encoder noise, on a moving reference (feedforward and
    friction compensation act) and on steps: positions within 1e-9 rad (the insertion 1e-9 m),
    the sent PWM identical, the commands within 1e-9 counts. The integrals start charged with a
    holding PWM (not the model's, so that a wrong charge shows)."""
    step, initial, fast_plant, schedule = plants
    settings = FirmwareSettings(noise_counts=noise)
    ref = sine_reference(0.8, T) if experiment == "sine" else step_reference(0.8, T, at=0.3)
    hold = Hold(firmware_units(ref.position[0]), np.array([9.0, -40.0, 0.0]))
    for name in CONTROLLERS:
        law = make_controller(name, schedule)
        slow = simulate(step, law, ref, settings, seed=7, settle=0.5, initial=initial, hold=hold)
        fast = simulate_compiled(fast_plant, loop_law(law, hold), law.name, ref, settings, seed=7, settle=0.5)
        assert fast.controller == name
        assert_same_run(fast, slow)
        if noise:                                                       # the noise reached the encoders
            assert np.any(np.abs(fast.measured[:, 1] / settings.encoder_count[1] - fast.position[:, 1]
                                 / settings.encoder_count[1]) > 0.6)


@needs_compiler
def test_the_insertion_gain_is_an_argument_not_frozen_in_the_cached_kernel(plants, monkeypatch):
    """``hardware.INSERTION_KP`` changed after the kernel was compiled (and cached on disk): the
    compiled loop follows it as the reference does (a constant frozen into numba's machine code
    would not)."""
    from rcm_kin.simulation import controllers
    from rcm_kin.simulation.controllers import PController

    step, initial, fast_plant, _ = plants
    ref = step_reference(0.3, T, at=0.1)
    shipped = simulate_compiled(fast_plant, loop_law(PController()), "p", ref, settle=0.05)
    halved = 0.5 * compiled_loop.INSERTION_KP
    for module in (compiled_loop, controllers):
        monkeypatch.setattr(module, "INSERTION_KP", halved)
    slow = simulate(step, PController(), ref, settle=0.05, initial=initial)
    fast = simulate_compiled(fast_plant, loop_law(PController()), "p", ref, settle=0.05)
    np.testing.assert_allclose(fast.command, slow.command, rtol=0, atol=1e-9)
    # the P law with the halved gain, on the logged reference and reading (counts/m * m)
    np.testing.assert_allclose(fast.command[:, 2], halved * (fast.reference[:, 2] - fast.measured[:, 2]),
                               rtol=1e-12, atol=1e-9)
    assert np.abs(fast.command[:, 2] - shipped.command[:, 2]).max() > 10    # and it acted (counts)


@needs_compiler
def test_divergence_is_an_error_at_the_same_tick():
    """A plant that blows up (x -> 1e200 x + 1 per period): both loops stop with the same message."""
    import casadi as ca

    from rcm_kin import RcmKinError
    from rcm_kin.simulation.controllers import PController

    x, u = ca.SX.sym("x", 6), ca.SX.sym("u", 3)
    blowup = ca.Function("blowup", [x, u], [1e200 * x + 1])
    plant = compiled_smooth(blowup, T)
    ref = step_reference(0.5, T)
    with pytest.raises(RcmKinError) as slow:
        simulate(lambda x, u: np.array(blowup(x, u)).ravel(), PController(), ref, settle=0.01, initial=plant.initial)
    with pytest.raises(RcmKinError) as fast:
        simulate_compiled(plant, loop_law(PController()), "p", ref, settle=0.01)
    # settling from k = -4: the first period gives 1e200 * 0.08 + 1 (finite), the second overflows
    assert f"diverged at t = {-3 * T:.3f} s (p)" in str(slow.value)
    assert str(fast.value) == str(slow.value)


@needs_compiler
def test_a_controller_without_a_kernel_form_runs_readable_with_one_warning(plants):
    """A controller with no ``kernel_law`` (or a subclass with a ``command`` of its own) is not
    translated: the runner runs it in the readable loop and says so with one warning; a subclass
    that only renames a shipped controller keeps its kernel form."""
    from dataclasses import dataclass

    from rcm_kin.simulation.controllers import PController, Sample

    @dataclass(frozen=True)
    class Doubled(PController):
        name: str = "doubled"

        def command(self, memory: np.ndarray, sample: Sample):
            u, memory = PController.command(self, memory, sample)
            return np.r_[2 * u[:2], u[2]], memory

    @dataclass(frozen=True)
    class Renamed(PController):
        name: str = "renamed"

    @dataclass(frozen=True)
    class Lawless:
        name: str = "lawless"

        def initial_memory(self, hold=None):
            return np.zeros(0)

        def command(self, memory, sample):
            return PController().command(memory, sample)

    assert loop_law(Doubled()) is None and loop_law(Lawless()) is None
    assert loop_law(PController()).kind == kernel_forms.P and loop_law(Renamed()).kind == kernel_forms.P
    step, initial, fast_plant, _ = plants
    ref = step_reference(0.2, T, at=0.05)
    for controller in (Doubled(), Lawless()):
        with pytest.warns(EngineFallbackWarning) as caught:
            result = run_closed_loop(fast_plant, controller, ref)
        assert len(caught) == 1 and "no kernel form" in str(caught[0].message)
        assert caught[0].filename == __file__ and issubclass(caught[0].category, RcmKinWarning)   # the user's line
        assert compiled_loop.EngineFallbackWarning is EngineFallbackWarning
        assert result.engine == "readable" and result.controller == controller.name
        slow = simulate(step, controller, ref, initial=initial)
        np.testing.assert_array_equal(result.pwm, slow.pwm)


def test_no_compiler_falls_back_with_one_line(reference_plant, tmp_path, monkeypatch, capsys):
    """With the compiler hidden there is no compiled plant, the compiled functions say so once (a
    warning), and the runner runs the readable loop with one warning (the same numbers)."""
    from rcm_kin.simulation.controllers import PController

    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    with pytest.warns(CompilerFallbackWarning) as said:
        assert compiled_drive_train(reference_plant) is None
        assert compiled_drive_train(reference_plant) is None
        assert reference_plant.kernel_plant() is None
    assert len(said) == 1 and str(said[0].message).startswith("no C compiler")
    assert capsys.readouterr().err == ""
    ref = step_reference(0.1, T, at=0.05)
    with pytest.warns(EngineFallbackWarning) as caught:
        result = run_closed_loop(reference_plant, PController(), ref)
    assert len(caught) == 1 and "no compiled form" in str(caught[0].message)
    assert result.engine == "readable"
    slow = simulate(reference_plant.step, PController(), ref, initial=reference_plant.initial)
    np.testing.assert_array_equal(result.pwm, slow.pwm)

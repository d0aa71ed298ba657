"""The plant family (one compiled parametric library for every parameter set) against the plant
built for each set (``psm_plant``, its numbers compiled in): the same states bit for bit, drive
trains and smooth model, kernel and readable forms; and no compiler run for a second set."""

from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from rcm_kin.dynamics import parametric
from rcm_kin.dynamics.parametric import shared_model
from rcm_kin.errors import RcmKinError
from rcm_kin.model import load_robot
from rcm_kin.robustness.sampling import draw, sample_seeds, uncertain_parameters, with_values
from rcm_kin.robustness.task import sample_model, sample_plant
from rcm_kin.simulation.compiled_plant import CompiledPlant
from rcm_kin.simulation.experiments import psm_plant
from rcm_kin.simulation.plant_family import family_of, plant_family
from rcm_kin.symbolic import compiled as compiled_module

PERIOD = 0.0025
needs_compiler = pytest.mark.skipif(shutil.which(os.environ.get("CC") or "cc") is None,
                                    reason="no C compiler (CC hidden): the plants are the readable ones")


def smooth(params):
    """``params`` without drive trains (and so without their fold sets): the smooth model's plant."""
    return replace(params, drive_train={}, uncertainty=replace(params.uncertainty, folds={}))


def drawn(params, seed: int, count: int = 2):
    uncertain = uncertain_parameters(params)
    return [with_values(params, uncertain, draw(uncertain, s)) for s in sample_seeds(seed, count)]


def run(plant, steps: int = 300) -> np.ndarray:
    """The plant's state after ``steps`` periods of a seeded random PWM from a pose."""
    rng = np.random.default_rng(11)
    x = plant.initial([0.15, -0.2, 0.08])
    for _ in range(steps):
        x = plant.step(x, rng.normal(size=3) * 40)
    return x


@needs_compiler
@pytest.mark.parametrize("shape", ["drive trains", "smooth"])
def test_family_plants_equal_the_plants_built_per_set(params, shape):
    base = params if shape == "drive trains" else smooth(params)
    family = plant_family(base, PERIOD)
    assert family.drive_trains == (shape == "drive trains")
    for one in drawn(base, seed=5):
        fast, readable = family.plant(one), family.plant(one, fast=False)
        assert isinstance(fast, CompiledPlant) and fast.parameters.size == family.model.size
        expected = run(psm_plant(one, PERIOD, fast=True))
        np.testing.assert_array_equal(run(fast), expected)
        np.testing.assert_array_equal(run(readable), run(psm_plant(one, PERIOD)))


def test_a_second_set_runs_without_the_compiler(params, monkeypatch):
    first, second = drawn(params, seed=21)
    family_of(first, PERIOD).plant(first)            # built (and compiled, or loaded) once
    calls = []
    real = subprocess.run
    monkeypatch.setattr(compiled_module.subprocess, "run", lambda *a, **k: calls.append(a) or real(*a, **k))
    plant = family_of(second, PERIOD).plant(second)
    run(plant, steps=20)
    assert calls == []
    assert family_of(second, PERIOD) is family_of(first, PERIOD)


def counted_builds(monkeypatch) -> list:
    """Empty model and family caches, and the list that each parametric model's build appends to
    (its symbolic functions, :func:`~rcm_kin.dynamics.state_space.model_functions` with ``p``)."""
    monkeypatch.setattr("rcm_kin.dynamics.parametric._SHARED", {})
    monkeypatch.setattr("rcm_kin.simulation.plant_family._FAMILIES", {})
    builds, real = [], parametric.model_functions
    monkeypatch.setattr(parametric, "model_functions", lambda *a, **k: builds.append(a[1]) or real(*a, **k))
    return builds


def test_a_robustness_sample_builds_one_model_per_structure(params, monkeypatch):
    """A worker's sample takes its plant (the family's model, drive trains: no Coulomb) and its
    margins' model (no Coulomb, gravity and Jacobians compiled): one parametric model built for both,
    and none for the next set of the structure."""
    builds = counted_builds(monkeypatch)
    first, second = drawn(params, seed=3)
    for one in (first, second):
        sample_plant(one, PERIOD)
        sample_model(one)
    assert len(builds) == 1
    assert family_of(first, PERIOD).model is shared_model(load_robot("psm"), first, coulomb=False)


def test_a_smooth_family_shares_the_model_with_coulomb(params, monkeypatch):
    builds = counted_builds(monkeypatch)
    family = plant_family(smooth(params), PERIOD)
    assert shared_model(load_robot("psm"), smooth(params)) is family.model
    shared_model(load_robot("psm"), smooth(params), compile_names=("gravity",))
    assert len(builds) == 1


def test_a_set_of_the_other_kind_is_refused(params):
    family = family_of(params, PERIOD)
    with pytest.raises(RcmKinError, match="with identified drive trains") as error:
        family.plant(smooth(params))
    assert error.value.parameter == "params"


@needs_compiler
def test_a_compiled_plant_that_does_not_fit_its_kind_is_refused(params):
    """The C kernel reads what the functions' shapes say, unchecked: a hand-made plant with a
    function short, parameters of the wrong size or no drive train is refused before any call."""
    good = family_of(params, PERIOD).plant(params)
    cases = [(dict(functions=good.functions[:1]), "functions"),
             (dict(parameters=good.parameters[:2]), "parameters"),
             (dict(parameters=np.zeros(0)), "parameters"),
             (dict(drive_train=None), "drive_train"),
             (dict(functions=good.functions[::-1]), "functions")]
    for change, parameter in cases:
        with pytest.raises(RcmKinError) as error:
            replace(good, **change)
        assert error.value.parameter == parameter, change


@pytest.mark.parametrize("params_arg, period, parameter", [("params.toml", PERIOD, "params"), (None, "abc", "period"),
                                                           (None, -PERIOD, "period"), (None, float("nan"), "period")])
def test_bad_family_arguments_are_one_line_errors(params, params_arg, period, parameter):
    with pytest.raises(RcmKinError) as error:
        plant_family(params if params_arg is None else params_arg, period)
    assert error.value.parameter == parameter and "\n" not in str(error.value)
    with pytest.raises(RcmKinError):
        family_of(params if params_arg is None else params_arg, period)

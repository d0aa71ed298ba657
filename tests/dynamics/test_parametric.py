"""The parametric model (drive constants and first moments as an input) against the model built
with the numbers in it (``driven_dynamics``): the same values bit for bit, interpreted and compiled,
for drawn parameter sets; and the errors for a set of another structure."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rcm_kin.control.linearization import linearize_grid
from rcm_kin.dynamics.drive import with_joint
from rcm_kin.dynamics.parametric import FUNCTIONS, parametric_dynamics, shared_model, structure_key
from rcm_kin.dynamics.state_space import TERM_NAMES, driven_dynamics
from rcm_kin.errors import RcmKinError
from rcm_kin.robustness.sampling import draw, sample_seeds, uncertain_parameters, with_values


def outputs(model, name, q, v, u):
    """Every output of ``model.<name>`` at the state as NumPy arrays."""
    args = {"forward": (np.r_[q, v], u), "jacobians": (np.r_[q, v], u), "mass_matrix": (q,), "bias": (q, v),
            "gravity": (q,), "rest": (q,)}[name]
    out = getattr(model, name)(*args)
    return [np.array(o) for o in (out if isinstance(out, (list, tuple)) else [out])]


@pytest.fixture(scope="module")
def drawn_sets(params):
    uncertain = uncertain_parameters(params)
    return [with_values(params, uncertain, draw(uncertain, s)) for s in sample_seeds(7, 3)]


@pytest.mark.parametrize("coulomb", [True, False])
def test_bound_model_equals_the_model_built_with_the_numbers(psm, params, drawn_sets, coulomb):
    parametric = parametric_dynamics(psm, params, coulomb=coulomb)
    rng = np.random.default_rng(3)
    for drawn in drawn_sets:
        reference, bound = driven_dynamics(psm, drawn, coulomb=coulomb), parametric.bind(drawn)
        assert bound.model_label == reference.model_label and bound.joints == reference.joints
        for name in ("input_gain", "damping", "coulomb", "coulomb_velocity", "reflected_inertia"):
            np.testing.assert_array_equal(getattr(bound.drive, name), getattr(reference.drive, name))
        for _ in range(5):
            q, v, u = rng.uniform(reference.lower, reference.upper), rng.normal(size=3), rng.normal(size=3) * 60
            for name in FUNCTIONS:
                for got, want in zip(outputs(bound, name, q, v, u), outputs(reference, name, q, v, u)):
                    np.testing.assert_array_equal(got, want, err_msg=name)


def test_compiled_parametric_model_equals_the_interpreted_one(psm, params, drawn_sets):
    parametric = parametric_dynamics(psm, params, coulomb=False)
    compiled = parametric.compiled("gravity", "jacobians")
    q, v, u = np.array([0.2, -0.3, 0.09]), np.array([0.4, -0.1, 0.02]), np.array([30.0, -20.0, 5.0])
    for drawn in drawn_sets:
        p = parametric.values(drawn)
        for name, args in (("gravity", (q, p)), ("jacobians", (np.r_[q, v], u, p))):
            got, want = getattr(compiled, name)(*args), getattr(parametric, name)(*args)
            for a, b in zip(got if isinstance(got, tuple) else [got], want if isinstance(want, tuple) else [want]):
                np.testing.assert_allclose(np.array(a), np.array(b), rtol=1e-13, atol=1e-13, err_msg=name)


def test_values_lay_out_the_drive_constants_then_the_moments(psm, params):
    parametric = parametric_dynamics(psm, params)
    p = parametric.values(params)
    n = len(params.driven)
    assert p.size == parametric.size == len(TERM_NAMES) * n + 3 * len(parametric.moment_joints)
    reference = driven_dynamics(psm, params)
    np.testing.assert_array_equal(p[:n], reference.drive.input_gain)                  # first the gains
    np.testing.assert_array_equal(p[4 * n:5 * n], reference.drive.reflected_inertia)  # the inertias fifth


def test_a_set_of_another_structure_is_refused_by_name(psm, params):
    parametric = parametric_dynamics(psm, replace(params, gravity_offsets={}))
    with pytest.raises(RcmKinError, match="offsets on links") as error:
        parametric.values(params)                  # the shipped set has offsets the model lacks
    assert error.value.parameter == "params"
    with pytest.raises(RcmKinError, match="drive parameters of roll, pitch, insertion"):
        parametric.values("params.toml")
    with pytest.raises(RcmKinError, match="`names` are of"):
        parametric.compiled("mass")


def test_a_robot_without_a_drive_has_no_parametric_model(mtm):
    with pytest.raises(RcmKinError, match="has none: give `params`"):
        parametric_dynamics(mtm)


def test_sets_of_one_structure_share_one_model(psm, params):
    other = with_joint(params, "roll", volts_per_pwm=params["roll"].volts_per_pwm * 1.1)
    assert structure_key(psm, other) == structure_key(psm, params)
    assert shared_model(psm, params, coulomb=False) is shared_model(psm, other, coulomb=False)
    assert shared_model(psm, params, coulomb=False) is not shared_model(psm, params, coulomb=True)


def test_a_bound_compiled_model_linearises_compiled_or_not(psm, params, drawn_sets):
    """A bound model calls compiled code already: ``linearize_grid`` with its default ``compile``
    uses it as it is (no second code generation), the same matrices as the model built per set."""
    model = shared_model(psm, params, coulomb=False, compile_names=("gravity", "jacobians")).bind(drawn_sets[0])
    Q = np.array([[0.1, -0.2, 0.08], [-0.3, 0.25, 0.1]])
    reference = linearize_grid(driven_dynamics(psm, drawn_sets[0], coulomb=False), Q, compile=False)
    for compile_ in (True, False):
        grid = linearize_grid(model, Q, compile=compile_)
        np.testing.assert_array_equal(grid.A, reference.A)
        np.testing.assert_array_equal(grid.B, reference.B)
        np.testing.assert_array_equal(grid.u0, reference.u0)

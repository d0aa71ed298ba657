"""python-control interoperability: linear models and identified transfer functions as
``control.StateSpace`` / ``control.TransferFunction``, checked against NumPy on their matrices
and coefficients."""

from __future__ import annotations

import control
import numpy as np
import pytest

from rcm_kin.control.linearization import linearize
from rcm_kin.identification.transfer_function import fit_transfer_function, simulate_transfer_function

POSITIONS = ["roll [rad]", "pitch [rad]", "insertion [m]"]


@pytest.fixture(scope="module")
def linearization(psm, params):
    from rcm_kin.dynamics.state_space import driven_dynamics
    return linearize(driven_dynamics(psm, params, coulomb=False), [0.2, -0.1, 0.1])


def test_state_space_carries_the_matrices_and_labelled_si_signals(linearization):
    sys = linearization.to_ss()
    assert isinstance(sys, control.StateSpace) and sys.isctime()
    for name in "ABCD":
        np.testing.assert_array_equal(getattr(sys, name), getattr(linearization, name))
    assert sys.state_labels == POSITIONS + ["roll rate [rad/s]", "pitch rate [rad/s]", "insertion rate [m/s]"]
    assert sys.input_labels == ["roll PWM [counts]", "pitch PWM [counts]", "insertion PWM [counts]"]
    assert sys.output_labels == POSITIONS
    # a signal by name is its column / row of the model
    np.testing.assert_array_equal(sys[["pitch [rad]"], ["roll PWM [counts]"]].B, linearization.B[:, [0]])


def test_state_space_poles_are_the_eigenvalues_of_a(linearization):
    poles = np.sort_complex(linearization.to_ss().poles())
    np.testing.assert_allclose(poles, np.sort_complex(np.linalg.eigvals(linearization.A)), rtol=1e-12, atol=1e-12)


def test_state_space_dc_gain_is_minus_c_a_inverse_b_plus_d(linearization):
    """``G(0) = -C A^-1 B + D`` by a NumPy solve, here where gravity stiffens every joint."""
    lin = linearization
    expected = -lin.C @ np.linalg.solve(lin.A, lin.B) + lin.D
    np.testing.assert_allclose(lin.to_ss().dcgain(), expected, rtol=1e-9, atol=1e-15)


@pytest.fixture(scope="module")
def fit():
    """A 2-pole, 1-zero fit of a noisy step through (4 s - 8) / (s^2 + 6 s + 16) at 2 ms."""
    rng = np.random.default_rng(3)
    u = np.r_[np.zeros(20), np.full(280, 10.0)]
    y = simulate_transfer_function([4.0, -8.0], [1.0, 6.0, 16.0], u, 0.002) + 1e-3 * rng.normal(size=u.size)
    return fit_transfer_function(u, y, 0.002, 2)


def test_transfer_function_has_the_fit_coefficients_and_names(fit):
    G = fit.to_tf()
    assert isinstance(G, control.TransferFunction) and G.isctime()
    np.testing.assert_array_equal(G.num_array[0, 0], fit.num)
    np.testing.assert_array_equal(G.den_array[0, 0], fit.den)
    assert (G.input_labels, G.output_labels) == (["PWM [counts]"], ["angle [deg]"])
    named = fit.to_tf("roll PWM [counts]", "roll [deg]")
    assert (named.input_labels, named.output_labels) == (["roll PWM [counts]"], ["roll [deg]"])


def test_transfer_function_poles_and_dc_gain_from_the_coefficients(fit):
    np.testing.assert_allclose(np.sort_complex(fit.poles), np.sort_complex(np.roots(fit.den)), rtol=1e-12)
    assert fit.dc_gain == pytest.approx(fit.num[-1] / fit.den[-1], rel=1e-12)
    assert fit.dc_gain == pytest.approx(-8.0 / 16.0, rel=0.05)          # the true model's, through the noise

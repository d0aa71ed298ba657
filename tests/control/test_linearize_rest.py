"""linearize_grid's closed form at rest (torque-input models), compiled into one C loop with the mass
matrix inverted by its Cholesky factor: the same matrices as the NumPy closed form from the model's
(g, M, dg/dq) with LAPACK's inverse (1e-12 of each matrix's size, the numbers before the C loop), as
the interpreted function, and as Pinocchio's ABA derivatives on the UR5's open tree."""

from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest
from oracles.dyn_robots import write_ur5

import rcm_kin as rk
from rcm_kin import RcmKinError
from rcm_kin.control.linearization import linearize_grid
from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.symbolic.compiled import map_points


def numpy_closed_form(model, Q):
    """(u0, A, B) from the interpreted (g, M, dg/dq), ``np.linalg.inv`` and batched products."""
    n, drive = len(model.joints), model.drive
    g, M, dg = map_points(model.rest, Q)
    damping = drive.damping + (drive.coulomb / drive.coulomb_velocity if model.coulomb else 0.0)
    Minv = np.linalg.inv(M)
    A = np.zeros((len(Q), 2 * n, 2 * n))
    A[:, :n, n:] = np.eye(n)
    A[:, n:, :n], A[:, n:, n:] = -Minv @ dg, -Minv * damping
    B = np.zeros((len(Q), 2 * n, n))
    B[:, n:] = Minv * drive.input_gain
    return g.reshape(len(Q), n) / drive.input_gain, A, B


def assert_per_pose_close(got, want, rel=1e-12):
    scale = np.abs(want).reshape(len(want), -1).max(axis=1)
    error = np.abs(got - want).reshape(len(want), -1).max(axis=1)
    assert np.all(error <= rel * scale), (error / scale).max()


@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    return rk.load_robot(write_ur5(tmp_path_factory.mktemp("ur5")))


@pytest.mark.parametrize("coulomb", [False, True])
def test_compiled_rest_equals_numpy_closed_form_and_interpreted(mtm, ur5, coulomb):
    rng = np.random.default_rng(5)
    for robot in (mtm, ur5):
        model = driven_dynamics(robot, coulomb=coulomb)
        Q = rng.uniform(model.lower, model.upper, (300, len(model.joints))) * 0.95
        Q = np.asfortranarray(Q)                                        # any layout in, C loop inside
        grid = linearize_grid(model, Q)
        assert grid.A.shape == (300, 2 * len(model.joints), 2 * len(model.joints))
        for got, want in zip((grid.u0, grid.A, grid.B), numpy_closed_form(model, Q)):
            assert_per_pose_close(got, want)
        interpreted = linearize_grid(model, Q[:40], compile=False, chunk=16)
        for field in ("u0", "A", "B"):
            assert_per_pose_close(getattr(interpreted, field), getattr(grid, field)[:40])


def test_compiled_rest_equals_pinocchio_aba_derivatives_on_the_ur5(ur5):
    """A serial arm: tree q = actuated q, torque input, no damping: A = [[0, I], [da/dq, da/dv]],
    B = [0; M^-1] of ``computeABADerivatives`` at v = 0 and tau = g(q)."""
    model = driven_dynamics(ur5)
    Q = np.random.default_rng(2).uniform(-2.5, 2.5, (50, ur5.nq))
    grid = linearize_grid(model, Q)
    tree, n = ur5.tree, ur5.nq
    data = tree.createData()
    for q, u0, A, B in zip(Q, grid.u0, grid.A, grid.B):
        tau = pin.computeGeneralizedGravity(tree, data, q)
        da_dq, da_dv, Minv = (np.array(x) for x in pin.computeABADerivatives(tree, data, q, np.zeros(n), tau))
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        np.testing.assert_allclose(u0, tau, rtol=0, atol=1e-10 * np.abs(tau).max())
        want_A = np.block([[np.zeros((n, n)), np.eye(n)], [da_dq, da_dv]])
        np.testing.assert_allclose(A, want_A, rtol=0, atol=1e-9 * np.abs(want_A).max())
        np.testing.assert_allclose(B, np.vstack([np.zeros((n, n)), Minv]), rtol=0, atol=1e-9 * np.abs(Minv).max())


def test_mass_matrix_not_positive_definite_is_an_error(mtm):
    model = driven_dynamics(mtm)
    q = ca.SX.sym("q", len(model.joints))
    g, M, dg = model.rest(q)
    broken = dataclasses.replace(model, rest=ca.Function("rest", [q], [g, -M, dg], ["q"], ["g", "M", "dg"]))
    for compile in (True, False):
        with pytest.raises(RcmKinError, match="mass matrix is not positive definite at pose 0"):
            linearize_grid(broken, np.zeros((3, len(model.joints))), compile=compile)


def test_the_failing_pose_is_named(mtm):
    model = driven_dynamics(mtm)
    q = ca.SX.sym("q", len(model.joints))
    g, M, dg = model.rest(q)
    flipped = ca.if_else(q[0] > 0.5, -1.0, 1.0) * M                   # not definite beyond j1 = 0.5 rad
    broken = dataclasses.replace(model, rest=ca.Function("rest", [q], [g, flipped, dg], ["q"], ["g", "M", "dg"]))
    Q = np.zeros((5, len(model.joints)))
    Q[3:, 0] = 0.6
    with pytest.raises(RcmKinError, match="at pose 3 "):
        linearize_grid(broken, Q)
    assert np.isfinite(linearize_grid(broken, Q[:3]).B).all()

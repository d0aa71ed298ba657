"""The closed chain: the constrained model (Pinocchio constraint models joining the cut bars)
and the reduced model (mimic joints) agree on passive joints, static torques and mass matrix."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from rcm_kin.errors import RcmKinError
from rcm_kin.model import constrained, reduced

TOL = 1e-9


def _random_q(robot, n, seed):
    rng = np.random.default_rng(seed)
    return [rng.uniform(robot.lower, robot.upper) for _ in range(n)]


def test_loop_solve_matches_linear_relations(psm):
    for q in _random_q(psm, 50, 0):
        q_tree = constrained.solve_loops(psm, q)
        np.testing.assert_allclose(q_tree, reduced.tree_configuration(psm, q), atol=TOL)
        assert np.max(np.abs(constrained.closure_residual(psm, q_tree))) < 1e-12


def test_loop_solve_from_a_poor_guess(psm):
    """Newton converges from a guess far from the solution (passive joints 0.3 rad off)."""
    q = np.array([0.2, -0.45, 0.1, 0, 0, 0, 0])
    guess = reduced.tree_configuration(psm, q)
    guess[psm.tree_q_passive] += 0.3
    np.testing.assert_allclose(constrained.solve_loops(psm, q, guess), reduced.tree_configuration(psm, q), atol=TOL)


def test_residual_is_nonzero_off_the_manifold(psm):
    """The constraint sees a broken loop (so the agreement above is not vacuous)."""
    q_tree = reduced.tree_configuration(psm, np.zeros(psm.nq))
    q_tree[psm.tree_q_passive[0]] += 0.01
    assert np.max(np.abs(constrained.closure_residual(psm, q_tree))) > 1e-4


def test_constraint_jacobian_is_the_derivative_of_the_residual(psm):
    q_tree = reduced.tree_configuration(psm, _random_q(psm, 1, 3)[0])
    q_tree[psm.tree_q_passive] += 0.05  # off the manifold too
    J = constrained.constraint_jacobian(psm, q_tree)
    h = 1e-6
    for k in range(psm.tree.nv):
        dq = np.zeros(psm.tree.nv)
        dq[k] = h
        fd = (constrained.closure_residual(psm, pin.integrate(psm.tree, q_tree, dq))
              - constrained.closure_residual(psm, pin.integrate(psm.tree, q_tree, -dq))) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, atol=1e-8)


def test_actuation_jacobian_matches_relations(psm):
    for q in _random_q(psm, 10, 4):
        S = constrained.actuation_jacobian(psm, constrained.solve_loops(psm, q))
        np.testing.assert_allclose(S, reduced.relation_jacobian(psm), atol=TOL)


def test_static_torques_agree(psm):
    for q in _random_q(psm, 50, 5):
        q_tree = constrained.solve_loops(psm, q)
        g_tree = pin.computeGeneralizedGravity(psm.tree, psm.tree_data, q_tree)
        tau = constrained.project_torques(psm, q_tree, g_tree).tau
        np.testing.assert_allclose(tau, reduced.reduced_gravity(psm, q), atol=TOL)


def test_projection_is_virtual_work(psm):
    """tau_actuated . dq = tau_tree . S dq for any admissible velocity: the projection does
    no work of its own (an identity independent of how lambda is solved)."""
    rng = np.random.default_rng(6)
    for q in _random_q(psm, 10, 6):
        q_tree = constrained.solve_loops(psm, q)
        tau_tree = rng.normal(size=psm.tree.nv)
        S = constrained.actuation_jacobian(psm, q_tree)
        tau = constrained.project_torques(psm, q_tree, tau_tree).tau
        np.testing.assert_allclose(tau, S.T @ tau_tree, atol=TOL)


def test_mass_matrices_agree(psm):
    for q in _random_q(psm, 50, 7):
        M_c = constrained.mass_matrix(psm, constrained.solve_loops(psm, q))
        M_r = reduced.reduced_mass_matrix(psm, q)
        np.testing.assert_allclose(M_c, M_r, atol=TOL)
        assert np.all(np.linalg.eigvalsh(M_r) > 0)


def test_reduced_mass_matrix_is_repeatable(psm):
    """Guards the Pinocchio 4.1 mimic-joint CRBA (LOCAL convention) drift across calls."""
    q = _random_q(psm, 1, 8)[0]
    first = reduced.reduced_mass_matrix(psm, q)
    for other in _random_q(psm, 5, 9):
        reduced.reduced_mass_matrix(psm, other)
    np.testing.assert_array_equal(reduced.reduced_mass_matrix(psm, q), first)


def test_reduced_gravity_is_the_potential_gradient(psm):
    """Independent of both models: g(q) = dV/dq, V = -sum m_i g . c_i, by central differences."""
    data = psm.tree.createData()

    def potential(q):  # J, of the open tree with the loops closed by the linear relations
        return pin.computePotentialEnergy(psm.tree, data, reduced.tree_configuration(psm, q))

    h = 1e-6
    for q in _random_q(psm, 5, 10):
        fd = np.array([(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(psm.nq)])
        np.testing.assert_allclose(reduced.reduced_gravity(psm, q), fd, atol=1e-7)


def test_mtm_has_no_loops(mtm):
    assert mtm.constraints == []
    assert constrained.closure_residual(mtm, np.zeros(mtm.tree.nq)).size == 0


def test_closure_error_is_the_largest_residual_in_plain_floats(psm, mtm):
    """The twin forward kinematics reports (plain floats) against the residual's arrays, bit for bit,
    at open configurations whose loops do not close."""
    rng = np.random.default_rng(4)
    for _ in range(200):
        q_tree = rng.uniform(-1.0, 1.0, psm.tree.nq)
        assert constrained.closure_error(psm, q_tree) == np.max(np.abs(constrained.closure_residual(psm, q_tree)))
    assert constrained.closure_error(mtm, np.zeros(mtm.tree.nq)) == 0.0


def test_the_reduced_models_placements_give_the_trees_closure_error(psm):
    """Forward kinematics reads the closure error off the reduced model's placements (its passive
    joints are mimics at the tree's joint ids): the same number as the open tree's at the linear
    relations' configuration, bit for bit, inside and outside the limits."""
    rng = np.random.default_rng(7)
    data = psm.create_data()
    for _ in range(300):
        q = rng.uniform(psm.lower - 0.5, psm.upper + 0.5)
        pin.forwardKinematics(psm.reduced, data.reduced, q)
        from_reduced = constrained.placed_closure_error(psm, psm.reduced, data.reduced, data)
        assert from_reduced == constrained.closure_error(psm, reduced.tree_configuration(psm, q), data)
        assert from_reduced == np.max(np.abs(constrained.closure_residual(psm, reduced.tree_configuration(psm, q))))


def test_the_position_errors_are_read_in_place(psm):
    """``RobotData.position_errors`` are views that follow each ``calc`` (a Pinocchio that returned
    copies would leave them stale, and the closure error silently zero)."""
    data = psm.create_data()
    q_tree = np.random.default_rng(3).uniform(-1.0, 1.0, psm.tree.nq)
    pin.forwardKinematics(psm.tree, data.tree, q_tree)
    for c, c_data, in_place in zip(psm.constraints, data.constraints, data.position_errors, strict=True):
        c.model.calc(psm.tree, data.tree, c_data)
        assert np.any(in_place != 0.0)
        np.testing.assert_array_equal(in_place, c_data.constraint_position_error)


def test_placed_closure_error_refuses_another_model(psm, mtm):
    with pytest.raises(RcmKinError, match="`model` must be psm's open tree or reduced model"):
        constrained.placed_closure_error(psm, mtm.reduced, mtm.reduced.createData())


def test_a_workspace_kept_loop_terms_follow_the_robot_it_serves(psm):
    """A workspace keeps its constraints' terms for the closure error (``RobotData.loop_terms``)
    only while the same robot's checks ask: one workspace used in turn by the PSM and by a copy
    whose loop rows are doubled gives each robot the error a fresh workspace gives it."""
    doubled = dataclasses.replace(psm, constraints=[dataclasses.replace(c, rows=2.0 * c.rows) for c in psm.constraints])
    shared = psm.create_data()
    q_tree = np.random.default_rng(5).uniform(-1.0, 1.0, psm.tree.nq)
    alone = constrained.closure_error(psm, q_tree, psm.create_data())
    assert alone > 0.0
    for _ in range(2):
        assert constrained.closure_error(psm, q_tree, shared) == alone
        assert constrained.closure_error(doubled, q_tree, shared) == constrained.closure_error(
            doubled, q_tree, doubled.create_data()) == 2.0 * alone

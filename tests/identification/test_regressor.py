"""The closed-chain joint-torque regressor: ``tau = Y(q, v, a) theta`` against Pinocchio's RNEA
through the loop closure and against the project's gravity functions, the pseudo-inertia test of
physical consistency, the base parameters of the PSM, and the LMI-constrained fit."""

from __future__ import annotations

import dataclasses
import sys

import numpy as np
import pinocchio as pin
import pytest

from rcm_kin.errors import RcmKinError
from rcm_kin.identification import regressor as reg
from rcm_kin.model.gravity import gravity_batch, gravity_torque
from rcm_kin.model.reduced import relation_jacobian, tree_configuration

TOL = 1e-9          # N m (N): absolute, on torques of order 1-10 N m


def _states(robot, n, seed, accel=1.0):
    """``n`` random states within the joint limits: positions uniform, v and a standard normal."""
    rng = np.random.default_rng(seed)
    return (rng.uniform(robot.lower, robot.upper, (n, robot.nq)), rng.normal(size=(n, robot.nq)),
            accel * rng.normal(size=(n, robot.nq)))


def _rnea_through_closure(robot, q, v, a):
    """``S^T RNEA_tree(S q + offsets, S v, S a)`` on the open tree as built (armature included)."""
    S = relation_jacobian(robot)
    return S.T @ pin.rnea(robot.tree, robot.tree_data, tree_configuration(robot, q), S @ v, S @ a)


def test_regressor_identity_through_the_closure(psm):
    """Y(q, v, a) theta_CAD = S^T RNEA_tree to 1e-9 N m at 20 states, and = the mimic model's RNEA.

    Pinocchio's RNEA adds ``armature * a``, the regressor does not: the PSM's tree carries zero
    armature (asserted), and ``armature_torque`` is added anyway so the identity stays exact."""
    assert not np.any(psm.tree.armature), "the PSM tree now has armature: armature_torque carries it"
    theta = reg.dynamic_parameters(psm)
    assert theta.shape == (10 * (psm.tree.njoints - 1),)
    worst = 0.0
    for q, v, a in zip(*_states(psm, 20, 0)):
        Y = reg.closed_chain_regressor(psm, q, v, a)
        assert Y.shape == (psm.nq, theta.size)
        tau = Y @ theta + reg.armature_torque(psm, a)
        worst = max(worst, np.max(np.abs(tau - _rnea_through_closure(psm, q, v, a))))
        mimic = psm.from_reduced(pin.rnea(psm.reduced, psm.reduced_data, psm.to_reduced(q), psm.to_reduced(v),
                                          psm.to_reduced(a)))
        np.testing.assert_allclose(tau, mimic, rtol=0, atol=TOL)
    assert worst < TOL


def test_armature_is_set_aside(psm):
    """On a tree with rotor armature, RNEA = Y theta + S^T diag(armature) S a (and Y theta alone is short)."""
    tree = pin.Model(psm.tree)
    tree.armature = np.linspace(0.01, 0.1, tree.nv)
    robot = dataclasses.replace(psm, tree=tree)
    theta = reg.dynamic_parameters(robot)
    for q, v, a in zip(*_states(robot, 5, 1)):
        rnea = _rnea_through_closure(robot, q, v, a)
        Y_theta = reg.closed_chain_regressor(robot, q, v, a) @ theta
        np.testing.assert_allclose(Y_theta + reg.armature_torque(robot, a), rnea, rtol=0, atol=TOL)
        assert np.max(np.abs(Y_theta - rnea)) > 1e-3


def test_gravity_part_matches_the_gravity_functions(psm):
    """Y(q, 0, 0) theta against the NumPy gravity (gravity_batch, independent of Pinocchio's
    algorithms) and the reduced (mimic) and constrained (loop solve) holding torques."""
    Q = _states(psm, 20, 2)[0]
    zero = np.zeros(psm.nq)
    theta = reg.dynamic_parameters(psm)
    g = np.array([reg.closed_chain_regressor(psm, q, zero, zero) @ theta for q in Q])
    np.testing.assert_allclose(g, gravity_batch(psm, Q), rtol=0, atol=TOL)
    for q, g_q in zip(Q, g):
        np.testing.assert_allclose(g_q, gravity_torque(psm, q, "reduced"), rtol=0, atol=TOL)
        np.testing.assert_allclose(g_q, gravity_torque(psm, q, "constrained"), rtol=0, atol=TOL)


def test_the_cad_set_is_physical(psm):
    """Every body's pseudo-inertia equals Pinocchio's and is positive definite."""
    theta = reg.dynamic_parameters(psm)
    for i, pi in enumerate(theta.reshape(-1, 10)):
        J = reg.pseudo_inertia(pi)
        np.testing.assert_allclose(J, psm.tree.inertias[i + 1].toPseudoInertia().toMatrix(), rtol=0, atol=1e-15)
        assert np.linalg.eigvalsh(J)[0] > 0, psm.tree.names[i + 1]
    assert reg.physically_consistent(theta)
    assert reg.inconsistent_bodies(theta) == []


@pytest.mark.parametrize("body", [
    pin.Inertia(-0.1, np.zeros(3), 1e-4 * np.eye(3)).toDynamicParameters(),     # negative mass
    pin.Inertia(0.1, np.array([0.0, 0.0, 0.05]), np.diag([3e-4, 1e-4, 1e-4])).toDynamicParameters(),
    np.array([0.1, 0, 0, 0, -1e-5, 0, 1e-4, 0, 0, 1e-4]),                      # a negative moment
], ids=["negative mass", "I_xx > I_yy + I_zz", "negative I_xx"])
def test_unphysical_bodies_are_flagged(psm, body):
    theta = reg.dynamic_parameters(psm)
    jaw = list(psm.tree.names).index("jaw") - 1
    theta[10 * jaw:10 * jaw + 10] = body
    assert not reg.physically_consistent(theta)
    assert reg.inconsistent_bodies(theta) == [jaw]


def test_base_parameters_of_the_psm(psm):
    """Identifiable combinations: 44 of the 110 with every joint moving; 16 from the roll,
    pitch and insertion torques with the instrument held; 13 and 5 from gravity alone. The base
    columns reproduce ``Y theta`` exactly (they span the regressor's range)."""
    Q, V, A = _states(psm, 120, 3)
    Y, sample = reg.stacked_regressor(psm, Q, V, A)
    assert Y.shape == (120 * psm.nq, 110) and sample[-1] == 119
    held = np.arange(psm.nq) >= 3
    Qh, Vh, Ah = (np.where(held, 0.0, X) for X in (Q, V, A))
    first3 = np.tile(~held, 120)
    cases = {"all": (Y, 44), "roll/pitch/insertion": (reg.stacked_regressor(psm, Qh, Vh, Ah)[0][first3], 16),
             "gravity": (reg.stacked_regressor(psm, Q, 0 * V, 0 * A)[0], 13),
             "gravity, roll/pitch/insertion": (reg.stacked_regressor(psm, Qh, 0 * V, 0 * A)[0][first3], 5)}
    theta = reg.dynamic_parameters(psm)
    for name, (Y_case, expected) in cases.items():
        columns = reg.base_columns(Y_case)
        assert len(columns) == expected == np.linalg.matrix_rank(Y_case), name
        beta = reg.base_parameters(Y_case, columns, theta)
        np.testing.assert_allclose(Y_case[:, columns] @ beta, Y_case @ theta, rtol=0, atol=1e-10)


def _bodies(robot, seed, rel, fat=0.0):
    """The CAD set with each body's mass, centre of mass and inertia perturbed by ~``rel``
    (scaled masses and inertias, shifted centres: always physical); ``fat`` (m) adds an
    isotropic ``m fat^2`` to each central inertia, moving the body inside the consistent cone."""
    rng = np.random.default_rng(seed)
    bodies = []
    for inertia in robot.tree.inertias[1:]:
        radius = np.sqrt(np.trace(inertia.inertia) / inertia.mass) + fat
        central = inertia.inertia + inertia.mass * fat**2 * np.eye(3)
        mass, lever = inertia.mass * np.exp(rel * rng.normal()), inertia.lever + rel * radius * rng.normal(size=3)
        bodies.append(pin.Inertia(mass, lever, central * np.exp(rel * rng.normal())).toDynamicParameters())
    return np.concatenate(bodies)


def _synthetic(robot, n, seed, noise, theta=None):
    """Stacked regressor of ``n`` random states and torques ``Y theta + noise`` (theta: CAD)."""
    Y, _ = reg.stacked_regressor(robot, *_states(robot, n, seed, accel=3.0))
    theta = reg.dynamic_parameters(robot) if theta is None else theta
    rng = np.random.default_rng(seed + 100)
    return Y, Y @ theta + noise * rng.normal(size=len(Y))


def _ridge(Y, tau, prior, weight):
    """The same objective as fit_consistent without the LMIs (closed form)."""
    A = np.vstack([Y, np.diag(np.sqrt(weight))])
    return np.linalg.lstsq(A, np.concatenate([tau, np.sqrt(weight) * prior]), rcond=None)[0]


def test_consistent_fit_recovers_the_base_parameters(psm):
    """40 states, sigma = 1e-3 N m noise, a 20 %-off prior: every base parameter within 5
    standard errors (sigma^2 (Y_b^T Y_b)^-1) of the truth, fresh torques predicted to 1e-3
    relative, and the estimate physical."""
    theta_true, prior, noise = reg.dynamic_parameters(psm), _bodies(psm, 5, 0.2), 1e-3
    Y, tau = _synthetic(psm, 40, 2, noise)
    theta = reg.fit_consistent(Y, tau, prior, weight=1e-6 / reg.parameter_scales(prior) ** 2)
    assert reg.physically_consistent(theta)
    columns = reg.base_columns(Y)
    assert len(columns) == 44
    Y_b = Y[:, columns]
    standard_error = noise * np.sqrt(np.diag(np.linalg.inv(Y_b.T @ Y_b)))
    z = (reg.base_parameters(Y, columns, theta) - reg.base_parameters(Y, columns, theta_true)) / standard_error
    assert np.max(np.abs(z)) < 5
    Y_fresh, tau_fresh = _synthetic(psm, 50, 9, 0.0)
    assert np.linalg.norm(Y_fresh @ theta - tau_fresh) < 1e-3 * np.linalg.norm(tau_fresh)


def test_consistent_fit_is_physical_where_least_squares_is_not(psm):
    """3 states (21 equations for 110 parameters), sigma = 0.05 N m: plain least squares and the
    same regularised objective without the LMIs give non-physical bodies; the LMI fit does not,
    fits the data as well as the unconstrained optimum allows, and predicts fresh torques to 10 %."""
    theta_true, prior = reg.dynamic_parameters(psm), _bodies(psm, 5, 0.2)
    Y, tau = _synthetic(psm, 3, 2, 0.05)
    weight = 1e-3 / reg.parameter_scales(prior) ** 2
    assert reg.inconsistent_bodies(np.linalg.lstsq(Y, tau, rcond=None)[0])
    ridge = _ridge(Y, tau, prior, weight)
    assert reg.inconsistent_bodies(ridge)
    theta = reg.fit_consistent(Y, tau, prior, weight)
    assert reg.physically_consistent(theta)

    def cost(t):
        return np.sum((Y @ t - tau) ** 2) + np.sum(weight * (t - prior) ** 2)

    assert cost(ridge) <= cost(theta) < 2 * cost(ridge)
    Y_fresh, tau_fresh = _synthetic(psm, 50, 9, 0.0)
    assert np.linalg.norm(Y_fresh @ (theta - theta_true)) < 0.1 * np.linalg.norm(tau_fresh)


def test_consistent_fit_is_the_unconstrained_optimum_when_that_is_physical(psm):
    """Bodies well inside the cone (CAD + 10 cm of isotropic gyration), a 5 %-off prior: the ridge
    estimate is physical, the LMIs are inactive and the cvxpy/Clarabel solution must equal the
    closed form (a check of the scaled formulation), though the data move it off the prior."""
    truth, prior = _bodies(psm, 0, 0.0, fat=0.1), _bodies(psm, 6, 0.05, fat=0.1)
    Y, tau = _synthetic(psm, 10, 4, 1e-2, theta=truth)
    scales = reg.parameter_scales(prior)
    weight = 1.0 / scales**2
    ridge = _ridge(Y, tau, prior, weight)
    assert reg.physically_consistent(ridge)
    assert np.max(np.abs(ridge - prior) / scales) > 0.02
    theta = reg.fit_consistent(Y, tau, prior, weight)
    np.testing.assert_allclose(theta / scales, ridge / scales, rtol=0, atol=1e-6)


def test_bad_inputs_are_refused(psm, monkeypatch):
    prior = reg.dynamic_parameters(psm)
    with pytest.raises(RcmKinError, match="do not match"):
        reg.fit_consistent(np.zeros((7, 110)), np.zeros(6), prior, 1.0)
    with pytest.raises(RcmKinError, match="10 per body"):
        reg.physically_consistent(np.zeros(11))
    with pytest.raises(RcmKinError, match="joint values"):
        reg.closed_chain_regressor(psm, np.zeros(3), np.zeros(7), np.zeros(7))
    monkeypatch.setitem(sys.modules, "cvxpy", None)
    with pytest.raises(RcmKinError, match=r"pip install '\.\[sos\]'"):
        reg.fit_consistent(np.zeros((7, 110)), np.zeros(7), prior, 1.0)

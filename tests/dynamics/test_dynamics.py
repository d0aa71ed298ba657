"""CasADi transcription of the dynamics and the driven-joint linear models (the linearisation issue)."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from rcm_kin import RcmKinError
from rcm_kin.control.linearization import (
    equilibrium,
    linearize,
    linearize_finite_differences,
    linearize_grid,
    linearize_pinocchio,
)
from rcm_kin.dynamics.drive import drive_effort
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm
from rcm_kin.model.gravity import gravity_batch
from rcm_kin.model.reduced import reduced_mass_matrix, relation_jacobian, tree_configuration
from rcm_kin.symbolic.closed_chain import closed_chain_rnea, linear_closure
from rcm_kin.symbolic.tree import tree_functions, tree_joints

TOL = 1e-10


def example_robot(name):
    erd = pytest.importorskip("example_robot_data")
    return erd.load(name).model


def random_state(model, rng):
    q = rng.uniform(np.maximum(model.lowerPositionLimit, -3), np.minimum(model.upperPositionLimit, 3))
    return q, rng.normal(size=model.nv), rng.normal(size=model.nv)


def check_transcription(model, seed, samples=20):
    model = pin.Model(model)
    rng = np.random.default_rng(seed)
    model.armature[:] = rng.uniform(0, 0.1, model.nv)     # Pinocchio's RNEA and CRBA include it
    data = model.createData()
    f = tree_functions(model)
    for _ in range(samples):
        q, v, a = random_state(model, rng)
        tau = np.array(f.rnea(q, v, a)).ravel()
        np.testing.assert_allclose(tau, pin.rnea(model, data, q, v, a), rtol=0, atol=TOL)
        M = pin.crba(model, data, q)
        np.testing.assert_allclose(np.array(f.mass_matrix(q)), np.triu(M) + np.triu(M, 1).T, rtol=0, atol=TOL)
        np.testing.assert_allclose(np.array(f.gravity(q)).ravel(), pin.computeGeneralizedGravity(model, data, q),
                                   rtol=0, atol=TOL)


@pytest.mark.parametrize("name", ["psm", "mtm"])
def test_transcription_matches_pinocchio_on_bundled_trees(name, request):
    check_transcription(request.getfixturevalue(name).tree, seed=1)


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_transcription_matches_pinocchio_on_example_robot_data(name):
    model = example_robot(name)
    assert {j.shortname() for j in model.joints[1:]} - {"JointModelRZ", "JointModelRY", "JointModelPY",
                                                        "JointModelPrismaticUnaligned"} == set()
    check_transcription(model, seed=2)


def test_transcription_against_pinocchio_casadi_when_available(psm):
    cpin = pytest.importorskip("pinocchio.casadi", reason="the PyPI pin wheel has no pinocchio.casadi")
    model = cpin.Model(psm.tree)
    data = model.createData()
    q, v, a = ca.SX.sym("q", psm.tree.nq), ca.SX.sym("v", psm.tree.nv), ca.SX.sym("a", psm.tree.nv)
    theirs = ca.Function("rnea", [q, v, a], [cpin.rnea(model, data, q, v, a)])
    ours = tree_functions(psm.tree).rnea
    rng = np.random.default_rng(3)
    for _ in range(10):
        x = random_state(psm.tree, rng)
        np.testing.assert_allclose(np.array(ours(*x)), np.array(theirs(*x)), rtol=0, atol=TOL)


def test_transcription_refuses_unsupported_joints():
    with pytest.raises(RcmKinError, match="not supported|1-DOF"):
        tree_functions(pin.buildSampleModelHumanoid())


def test_closed_chain_rnea_matches_the_mimic_model(psm):
    """J^T tau_tree(phi(q), J v, J a + Jdot v) against Pinocchio's RNEA of the reduced (mimic) model."""
    n = psm.nq
    q, v, a = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("a", n)
    S = relation_jacobian(psm)
    phi = linear_closure(S, tree_configuration(psm, np.zeros(n)), q)
    tau = ca.Function("tau", [q, v, a], [closed_chain_rnea(tree_joints(psm.tree), np.array(psm.tree.gravity.linear),
                                                           phi, q, v, a)])
    rng = np.random.default_rng(4)
    for _ in range(20):
        qa, va, aa = rng.uniform(psm.lower, psm.upper), rng.normal(size=n), rng.normal(size=n)
        expected = psm.from_reduced(pin.rnea(psm.reduced, psm.reduced_data, psm.to_reduced(qa),
                                             psm.to_reduced(va), psm.to_reduced(aa)))
        np.testing.assert_allclose(np.array(tau(qa, va, aa)).ravel(), expected, rtol=0, atol=TOL)


def driven_poses(n, seed):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-0.52, 0.52, (n, 2)), rng.uniform(0, 0.16, n)])


def test_driven_model_matches_reduced_inertia_and_calibrated_gravity(psm, params, model):
    Q = driven_poses(20, 5)
    full = np.hstack([Q, np.zeros((len(Q), 4))])
    g = gravity_batch(psm, full, params.gravity_offsets)[:, :3]
    for q, qa, gq in zip(Q, full, g):
        expected_M = reduced_mass_matrix(psm, qa)[:3, :3] + np.diag(model.drive.reflected_inertia)
        np.testing.assert_allclose(np.array(model.mass_matrix(q)), expected_M, rtol=0, atol=TOL)
        np.testing.assert_allclose(np.array(model.gravity(q)).ravel(), gq, rtol=0, atol=TOL)
        np.testing.assert_allclose(holding_pwm(model, q), drive_effort(params, gq).pwm, rtol=0, atol=1e-9)


def test_equilibrium_is_at_rest(model):
    for q in driven_poses(10, 6):
        x0, u0 = equilibrium(model, q)
        np.testing.assert_allclose(np.array(model.forward(x0, u0)).ravel(), 0, atol=1e-10)


def test_drive_terms_by_hand(model):
    """At the home pose, one extra PWM count on roll accelerates it by k_u / M; velocity brakes it
    by back-EMF plus the Coulomb slope F_c / v_c (here computed from the constants, not the model)."""
    d = model.drive
    lin = linearize(model, [0, 0, 0.08])
    M = np.array(model.mass_matrix([0, 0, 0.08]))
    np.testing.assert_allclose(lin.B[3:], np.linalg.solve(M, np.diag(d.input_gain)), rtol=1e-12)
    brake = np.diag(d.damping + d.coulomb / d.coulomb_velocity)
    dv = lin.A[3:, 3:]
    # at rest the Coriolis terms vanish: the velocity block is the drive's braking alone
    np.testing.assert_allclose(dv, -np.linalg.solve(M, brake), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("coulomb", [True, False])
def test_ad_pinocchio_and_finite_difference_jacobians_agree(psm, params, coulomb):
    model = driven_dynamics(psm, params, coulomb=coulomb)
    rng = np.random.default_rng(7)
    for q in driven_poses(8, 8):
        x, u = np.r_[q, rng.normal(scale=0.5, size=3)], rng.uniform(-100, 100, 3)
        A, B = (np.array(m) for m in model.jacobians(x, u))
        A_pin, B_pin = linearize_pinocchio(psm, model, params.gravity_offsets, x, u)
        np.testing.assert_allclose(A, A_pin, rtol=0, atol=TOL * max(1, np.abs(A).max()))
        np.testing.assert_allclose(B, B_pin, rtol=0, atol=TOL)
        A_fd, B_fd = linearize_finite_differences(model, x, u)
        # central differences, step 1e-6: truncation ~ 1e-12 f''', rounding ~ 1e-16 |f| / 1e-6
        np.testing.assert_allclose(A, A_fd, rtol=0, atol=1e-7 * max(1, np.abs(A).max()))
        np.testing.assert_allclose(B, B_fd, rtol=0, atol=1e-9)


def test_mapped_grid_equals_single_linearisations(model):
    Q = driven_poses(37, 9)
    grid = linearize_grid(model, Q, chunk=16)             # 3 chunks, a short last one
    for k in (0, 15, 16, 36):
        lin = linearize(model, Q[k])
        np.testing.assert_array_equal(grid.u0[k], lin.u0)
        np.testing.assert_allclose(grid.A[k], lin.A, rtol=0, atol=1e-13)
        np.testing.assert_allclose(grid.B[k], lin.B, rtol=0, atol=1e-13)


def test_bad_poses_are_refused(model):
    with pytest.raises(RcmKinError, match="3 finite"):
        equilibrium(model, [0, 0])
    with pytest.raises(RcmKinError, match="row of 3"):
        linearize_grid(model, np.zeros((4, 2)))


def test_mtm_has_a_torque_model_and_refuses_the_psm_drive(mtm, params):
    """The MTM has no drive file: its model has torque input over all its actuated joints; the
    PSM's calibration applied to it is a one-line error."""
    model = driven_dynamics(mtm)
    assert model.joints == mtm.actuated and model.input_unit.startswith("torque") and not model.coulomb
    assert model.model_label == "CAD (URDF inertias)" and model.inputs[0] == "tau_j1"
    with pytest.raises(RcmKinError, match="describes robot 'psm', not 'mtm'"):
        driven_dynamics(mtm, params)

"""Equation-error identification of the rigid-body parameters through the loop closure.

The inverse dynamics of a rigid tree is linear in the ten standard parameters of each body,
``tau_tree = Y_tree(q_tree, v_tree, a_tree) pi`` (Pinocchio's ``computeJointTorqueRegressor``).
The closed chain in actuated coordinates moves the open tree by the sidecar's linear relations
``q_tree = S q + offsets`` (``S`` constant, so ``v_tree = S v`` and ``a_tree = S a``), and by
virtual work its generalised forces are ``tau = S^T tau_tree``. Hence

    tau = Y(q, v, a) theta,    Y = S^T Y_tree(S q + offsets, S v, S a),

with ``theta`` the stacked parameters of every open-tree body (the passive links of the
parallelograms included). Units: ``q`` rad or m, ``v`` rad/s or m/s, ``a`` rad/s^2 or m/s^2,
``tau`` N m or N, in actuated order.

Parameters, per body, in Pinocchio's order and in the frame of the body's parent joint (origin
at the joint, not at the centre of mass): ``[m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz,
I_yz, I_zz]`` (kg, kg m, kg m^2), ``I`` the rotational inertia about the joint-frame origin.

Rotor inertia (Pinocchio's ``model.armature``) is *not* a body parameter: ``pin.rnea`` adds
``armature * a`` but the regressor does not. :func:`armature_torque` gives that term so it can
be set aside; the bundled models carry zero armature (the drives' reflected rotor inertia lives
in :mod:`rcm_kin.dynamics.drive`).

A body is physically consistent when its pseudo-inertia (Wensing, Kim, Slotine 2017)

    J = [[0.5 tr(Ibar) 1 - Ibar, h], [h^T, m]]  =  integral of [p; 1][p; 1]^T dm

is positive semidefinite (a positive mass, a centre of mass that a density can produce, and
principal moments obeying the triangle inequality). :func:`fit_consistent` imposes it as one
linear matrix inequality per body (cvxpy, as in the dVRK identification packages); cvxpy is an
optional extra: ``pip install '.[sos]'``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
import scipy.linalg

from rcm_kin.errors import RcmKinError
from rcm_kin.model.reduced import relation_jacobian, tree_configuration

if TYPE_CHECKING:
    from rcm_kin.model import Robot

N_PARAMETERS = 10   # standard parameters per body


def _pseudo_basis() -> np.ndarray:
    """(10, 4, 4): ``J(pi) = sum_k pi_k E_k``, linear in the parameters (numbers or cvxpy)."""
    E = np.zeros((N_PARAMETERS, 4, 4))
    E[0, 3, 3] = 1.0                                    # m
    for k in range(3):                                  # h = m c
        E[1 + k, k, 3] = E[1 + k, 3, k] = 1.0
    # Sigma = 0.5 tr(Ibar) 1 - Ibar: diagonal 0.5 (-I_kk + I_ll + I_nn), off-diagonal -I_kl
    diagonal = {4: 0, 6: 1, 9: 2}                       # parameter index -> axis of I_kk
    for p, k in diagonal.items():
        for axis in range(3):
            E[p, axis, axis] = -0.5 if axis == k else 0.5
    for p, (k, l) in {5: (0, 1), 7: (0, 2), 8: (1, 2)}.items():
        E[p, k, l] = E[p, l, k] = -1.0
    return E


_PSEUDO_BASIS = _pseudo_basis()


def closed_chain_regressor(robot: Robot, q, v, a) -> np.ndarray:
    """``Y`` (n_actuated, 10 n_bodies) with ``tau = Y theta`` (N m, N), actuated order.

    ``q``, ``v``, ``a``: actuated positions (rad, m), velocities and accelerations. Columns are
    the open tree's bodies in joint order (1 .. njoints-1), ten parameters each. Armature is
    excluded (see :func:`armature_torque`)."""
    q, v, a = (robot.check_q(x) for x in (q, v, a))
    S = relation_jacobian(robot)
    Y_tree = pin.computeJointTorqueRegressor(robot.tree, robot.tree_data, tree_configuration(robot, q), S @ v, S @ a)
    return S.T @ Y_tree


def stacked_regressor(robot: Robot, Q, V, A) -> tuple[np.ndarray, np.ndarray]:
    """Regressors of N samples stacked row-wise: ``(N n_actuated, 10 n_bodies)``, and the
    sample index of each row. ``Q``, ``V``, ``A``: (N, n_actuated) arrays."""
    Q, V, A = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (Q, V, A))
    if not Q.shape == V.shape == A.shape:
        raise RcmKinError(f"positions, velocities and accelerations differ in shape: {Q.shape}, {V.shape}, {A.shape}")
    Y = np.vstack([closed_chain_regressor(robot, q, v, a) for q, v, a in zip(Q, V, A)])
    return Y, np.repeat(np.arange(len(Q)), robot.nq)


def armature_torque(robot: Robot, a) -> np.ndarray:
    """``S^T diag(armature) S a`` (N m, N): the rotor-inertia torque Pinocchio's RNEA adds
    and the body regressor leaves out; zero for the bundled models."""
    S = relation_jacobian(robot)
    return S.T @ (np.asarray(robot.tree.armature) * (S @ robot.check_q(a)))


def dynamic_parameters(robot: Robot) -> np.ndarray:
    """The model's (CAD) parameters ``theta`` (10 n_bodies,), stacked in the regressor's
    column order (kg, kg m, kg m^2; joint frames)."""
    return np.concatenate([robot.tree.inertias[j].toDynamicParameters() for j in range(1, robot.tree.njoints)])


def parameter_names(robot: Robot) -> list[str]:
    """``body.parameter`` labels of the columns, e.g. ``pitch.m``, ``pitch.Ixx``."""
    short = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
    return [f"{robot.tree.names[j]}.{s}" for j in range(1, robot.tree.njoints) for s in short]


def _bodies(theta) -> np.ndarray:
    theta = np.asarray(theta, dtype=float)
    if theta.ndim != 1 or theta.size % N_PARAMETERS:
        raise RcmKinError(f"parameters must be a flat vector of 10 per body, got shape {theta.shape}")
    return theta.reshape(-1, N_PARAMETERS)


def pseudo_inertia(pi10) -> np.ndarray:
    """The 4x4 pseudo-inertia ``[[0.5 tr(Ibar) 1 - Ibar, h], [h^T, m]]`` of one body's ten
    parameters (kg m^2 / kg m / kg, in the parameters' joint frame)."""
    pi10 = np.asarray(pi10, dtype=float)
    if pi10.shape != (N_PARAMETERS,):
        raise RcmKinError(f"one body has 10 parameters, got shape {pi10.shape}")
    return np.tensordot(pi10, _PSEUDO_BASIS, axes=1)


def physically_consistent(theta, tol: float = 0.0) -> bool:
    """Every body's pseudo-inertia is positive semidefinite: smallest eigenvalue >= ``-tol``
    (kg m^2; the bundled PSM's smallest is ~1e-9, the jaw's)."""
    return all(np.linalg.eigvalsh(pseudo_inertia(p))[0] >= -tol for p in _bodies(theta))


def inconsistent_bodies(theta, tol: float = 0.0) -> list[int]:
    """Indices (0-based, regressor order) of the bodies whose pseudo-inertia is not PSD."""
    return [i for i, p in enumerate(_bodies(theta)) if np.linalg.eigvalsh(pseudo_inertia(p))[0] < -tol]


def base_columns(Y_stack: np.ndarray, tol: float = 1e-8) -> np.ndarray:
    """Identifiable (base) parameter columns of a stacked regressor, sorted.

    QR with column pivoting ``Y P = Q R``: the first ``r`` pivots with ``|R_kk| > tol |R_00|``
    are independent columns spanning the range of ``Y``; every other column (parameters that
    do not move the joints, or only in combination) is a linear combination of them."""
    Y_stack = np.asarray(Y_stack, dtype=float)
    R, pivots = scipy.linalg.qr(Y_stack, mode="r", pivoting=True)
    diagonal = np.abs(np.diag(R))
    if diagonal.size == 0 or diagonal[0] == 0.0:
        return np.zeros(0, dtype=int)
    return np.sort(pivots[:int(np.sum(diagonal > tol * diagonal[0]))])


def base_parameters(Y_stack: np.ndarray, columns: np.ndarray, theta) -> np.ndarray:
    """The base parameters of ``theta``: the coordinates ``beta`` of ``Y theta`` in the basis
    ``Y[:, columns]`` (``beta = theta_b + K theta_d``), what the data can determine."""
    Y_b = np.asarray(Y_stack)[:, columns]
    return np.linalg.lstsq(Y_b, np.asarray(Y_stack) @ np.asarray(theta, dtype=float), rcond=None)[0]


def _body_scales(prior: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per body of the prior: mass ``m`` (kg) and radius of gyration about the joint origin
    ``L = sqrt(tr Sigma / m)`` (m), floored at 1e-9 kg and 1 mm. The PSM bodies weigh 1 g to
    3.5 kg, their inertias reach down to 1e-9 kg m^2: the fit works in ``m``, ``m L``, ``m L^2``."""
    bodies = _bodies(prior)
    mass = np.maximum(np.abs(bodies[:, 0]), 1e-9)
    trace_sigma = np.abs(0.5 * (bodies[:, 4] + bodies[:, 6] + bodies[:, 9]))
    return mass, np.sqrt(np.maximum(trace_sigma / mass, 1e-6))


def parameter_scales(prior) -> np.ndarray:
    """Natural size of each parameter of ``prior``: ``m``, ``m L`` and ``m L^2`` per body (kg,
    kg m, kg m^2; see :func:`_body_scales`). ``weight = lam / parameter_scales(prior)**2``
    penalises relative deviations from the prior in :func:`fit_consistent`."""
    mass, length = _body_scales(prior)
    return (mass[:, None] * length[:, None] ** np.array([0, 1, 1, 1, 2, 2, 2, 2, 2, 2])).ravel()


def _pseudo_inertia_lmis(x, prior: np.ndarray, margin: float) -> list:
    """``D_i J_i(prior + s x) D_i >> margin 1`` per body, ``D_i = diag(m L^2 (x3), m)^-1/2``:
    a congruence (same definiteness as ``J_i``) that makes every body's LMI of order one."""
    mass, length = _body_scales(prior)
    s = parameter_scales(prior)
    constraints = []
    for i in range(len(mass)):
        d = 1.0 / np.sqrt(mass[i] * np.array([length[i] ** 2] * 3 + [1.0]))
        E = d[None, :, None] * _PSEUDO_BASIS * d[None, None, :]
        rows = slice(N_PARAMETERS * i, N_PARAMETERS * (i + 1))
        J = np.tensordot(prior[rows], E, axes=1) + sum(x[rows][k] * (s[rows][k] * E[k]) for k in range(N_PARAMETERS))
        constraints.append(0.5 * (J + J.T) >> margin * np.eye(4))
    return constraints


def fit_consistent(Y: np.ndarray, tau: np.ndarray, prior, weight, margin: float = 0.0,
                   solver: str = "CLARABEL") -> np.ndarray:
    """Physically consistent least squares (one LMI per body, cvxpy):

        min |Y theta - tau|^2 + sum_k weight_k (theta_k - prior_k)^2   s.t.   J_i(theta) >> 0.

    ``Y`` (rows, 10 n_bodies) and ``tau`` (rows,) in N m or N, e.g. :func:`stacked_regressor`
    rows; ``prior`` (10 n_bodies,), e.g. :func:`dynamic_parameters`; ``weight``: scalar or per
    parameter, (N m)^2 per squared parameter unit. It alone decides the directions the data
    leave undetermined, and the bodies' parameters span nine decades: ``weight = lam /
    parameter_scales(prior)**2`` penalises *relative* deviations, a uniform scalar leaves the
    small bodies nearly free. ``margin > 0`` asks ``D_i J_i D_i >> margin 1``, ``D_i =
    diag(m L^2, m L^2, m L^2, m)^-1/2`` of the prior (a margin relative to the body's size).
    Solved in scaled deviations from the prior. Returns ``theta`` (10 n_bodies,)."""
    try:
        import cvxpy as cp
    except ImportError:
        raise RcmKinError("the physically consistent fit needs cvxpy: pip install '.[sos]'") from None
    Y, tau, prior = np.asarray(Y, dtype=float), np.asarray(tau, dtype=float).ravel(), _bodies(prior).ravel()
    if Y.ndim != 2 or Y.shape != (tau.size, prior.size):
        raise RcmKinError(f"regressor {Y.shape}, torques ({tau.size},) and prior ({prior.size},) do not match")
    weight = np.broadcast_to(np.asarray(weight, dtype=float), prior.shape)
    if np.any(weight < 0) or not margin >= 0:
        raise RcmKinError("weight and margin must be non-negative")
    s = parameter_scales(prior)                                   # theta = prior + s * x
    x = cp.Variable(prior.size)
    residual = tau - Y @ prior
    norm = max(np.linalg.norm(residual), 1e-3 * np.linalg.norm(tau), 1e-12)   # objective of order one
    objective = cp.sum_squares((Y * s) @ x - residual) + cp.sum_squares(cp.multiply(np.sqrt(weight) * s, x))
    problem = cp.Problem(cp.Minimize(objective / norm**2), _pseudo_inertia_lmis(x, prior, margin))
    try:
        problem.solve(solver=solver)
    except cp.error.SolverError as exc:
        raise RcmKinError(f"the consistent fit failed in {solver}: {exc}") from None
    if problem.status not in (cp.OPTIMAL, cp.OPTIMAL_INACCURATE) or x.value is None:
        raise RcmKinError(f"the consistent fit did not converge ({problem.status})")
    return prior + s * np.asarray(x.value)

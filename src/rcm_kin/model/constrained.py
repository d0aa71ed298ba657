"""The constrained model: the open tree plus Pinocchio constraint models joining each cut bar.

Sign conventions follow Pinocchio's ``PointAnchorConstraintModel``: the residual of a loop is
``R_A^T (p_B - p_A)`` in the constraint frame A (the link_a frame moved to point_a), in metres,
and its Jacobian maps the tree velocity to that frame. Planar loops keep only their two
in-plane rows. Generalised forces are those of the open tree (N m or N), and constraint
forces ``lambda`` act on link_b at the cut point, in frame A (N).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.model.description import LoopClosure
from rcm_kin.model.robot import Robot, RobotData


@dataclass(frozen=True)
class LoopConstraint:
    loop: LoopClosure
    model: pin.PointAnchorConstraintModel   # its data lives in the caller's RobotData.constraints
    rows: np.ndarray   # (k, 3): independent directions of the residual, in frame A


@dataclass(frozen=True)
class ProjectedTorques:
    """Generalised forces of the open tree carried by the actuated joints alone."""

    tau: np.ndarray                 # actuated joints, actuated order (N m or N)
    constraint_forces: np.ndarray   # stacked independent loop forces (N), rows of constraint_jacobian


def _independent_rows(normal: np.ndarray | None) -> np.ndarray:
    if normal is None:
        return np.eye(3)
    # two unit vectors spanning the plane orthogonal to the normal
    helper = np.eye(3)[np.argmin(np.abs(normal))]
    t1 = np.cross(normal, helper)
    t1 /= np.linalg.norm(t1)
    return np.vstack([t1, np.cross(normal, t1)])


def build_constraint_models(tree: pin.Model, loops: tuple[LoopClosure, ...]) -> list[LoopConstraint]:
    """One Pinocchio point-anchor constraint per loop, cut at the loop's joining point."""
    constraints = []
    for loop in loops:
        placements = []
        for link, point in ((loop.link_a, loop.point_a), (loop.link_b, loop.point_b)):
            if not tree.existFrame(link):
                raise RcmKinError(f"loop '{loop.name}': link '{link}' is not in the URDF")
            frame = tree.frames[tree.getFrameId(link)]
            placements.append((frame.parentJoint, frame.placement * pin.SE3(np.eye(3), point)))
        (joint_a, placement_a), (joint_b, placement_b) = placements
        model = pin.PointAnchorConstraintModel(tree, joint_a, placement_a, joint_b, placement_b)
        constraints.append(LoopConstraint(loop, model, _independent_rows(loop.plane_normal)))
    return constraints


def closure_residual(robot: Robot, q_tree: np.ndarray, data: RobotData | None = None) -> np.ndarray:
    """Stacked independent loop-closure errors at ``q_tree`` (m); empty for a serial robot.
    ``data``: the caller's workspace, default this thread's own."""
    data = robot.workspace(data)
    pin.forwardKinematics(robot.tree, data.tree, q_tree)
    parts = []
    for c, c_data in zip(robot.constraints, data.constraints, strict=True):
        c.model.calc(robot.tree, data.tree, c_data)
        parts.append(c.rows @ c_data.constraint_position_error)
    return np.concatenate(parts) if parts else np.zeros(0)


def closure_error(robot: Robot, q_tree: np.ndarray, data: RobotData | None = None) -> float:
    """``max |closure_residual(robot, q_tree)|`` (m; 0 for a serial robot), its declared twin in
    plain floats: the same products and sums in the same order, without the arrays' per-call cost
    on 2 or 3 values (tests/model/test_closure.py holds the two equal)."""
    data = robot.workspace(data)
    pin.forwardKinematics(robot.tree, data.tree, q_tree)
    return placed_closure_error(robot, robot.tree, data.tree, data)


def placed_closure_error(robot: Robot, model: pin.Model, model_data: pin.Data, data: RobotData | None = None) -> float:
    """:func:`closure_error` of the joint placements already in ``model_data`` (after
    ``pin.forwardKinematics(model, model_data, ...)``), for ``model`` the open tree or the reduced
    model: the reduced model's passive joints are mimics at the tree's own joint ids
    (:func:`rcm_kin.model.reduced.build_reduced_model`), so its placements at actuated ``q`` are the
    tree's at ``tree_configuration(robot, q)`` and the loops' constraint models read them unchanged
    (forward kinematics' check number, without a second pass over the tree; tests/model/test_closure.py
    holds it equal to the tree's)."""
    if model is not robot.tree and model is not robot.reduced:
        raise RcmKinError(f"`model` must be {robot.name}'s open tree or reduced model", parameter="model")
    return loops_error(loop_checks(robot), model, model_data, robot.workspace(data))


def loops_error(checks: tuple, model: pin.Model, model_data: pin.Data, data: RobotData) -> float:
    """The body of :func:`placed_closure_error`, for a caller that has checked its arguments:
    ``checks`` = :func:`loop_checks` of the robot whose checked workspace ``data`` is
    (:meth:`Robot.workspace`) and whose open tree or reduced model ``model`` is."""
    kept = data.loop_terms                           # the workspace's constraints are the robot's, one each
    if kept is None or kept[0] is not checks:
        kept = data.keep_loop_terms(checks)
    worst = 0.0
    for calc, rows, c_data, position_error in kept[1]:
        calc(model, model_data, c_data)
        e0, e1, e2 = position_error.tolist()
        for r0, r1, r2 in rows:
            error = abs(r0 * e0 + r1 * e1 + r2 * e2)
            if not error <= worst:          # NaN taken, and kept, as NumPy's max does
                worst = error if worst == worst else worst
    return worst


@functools.lru_cache(maxsize=64)
def loop_checks(robot: Robot) -> tuple[tuple[Callable, list[list[float]]], ...]:
    """Each constraint's ``calc`` and its independent rows as Python floats (built once per robot)."""
    return tuple((c.model.calc, c.rows.tolist()) for c in robot.constraints)


def constraint_jacobian(robot: Robot, q_tree: np.ndarray, data: RobotData | None = None) -> np.ndarray:
    """``d closure_residual / d q_tree``: (independent rows) x (tree nv)."""
    workspace = robot.workspace(data)
    model, tree_data = robot.tree, workspace.tree
    pin.computeJointJacobians(model, tree_data, q_tree)
    blocks = []
    for c, c_data in zip(robot.constraints, workspace.constraints, strict=True):
        c.model.calc(model, tree_data, c_data)
        blocks.append(c.rows @ c.model.jacobian(model, tree_data, c_data))
    return np.vstack(blocks) if blocks else np.zeros((0, model.nv))


def solve_loops(robot: Robot, q: np.ndarray, q_tree_guess: np.ndarray | None = None,
                tol: float = 1e-13, max_iter: int = 50, data: RobotData | None = None) -> np.ndarray:
    """Passive joints that close every loop, given actuated ``q`` (Newton on the residual).

    Returns the open-tree configuration. The default guess puts every passive joint at 0.
    """
    q_tree = np.zeros(robot.tree.nq) if q_tree_guess is None else np.array(q_tree_guess, dtype=float)
    q_tree[robot.tree_q_actuated] = q
    passive = robot.tree_q_passive
    for _ in range(max_iter):
        r = closure_residual(robot, q_tree, data)
        if r.size == 0 or np.max(np.abs(r)) < tol:
            return q_tree
        J_p = constraint_jacobian(robot, q_tree, data)[:, passive]
        q_tree[passive] -= np.linalg.lstsq(J_p, r, rcond=None)[0]
    raise RcmKinError(f"the loops of {robot.name} do not close at q = {np.round(q, 6).tolist()} "
                      f"(residual {np.max(np.abs(r)):.2e} m after {max_iter} Newton steps)")


def actuation_jacobian(robot: Robot, q_tree: np.ndarray, data: RobotData | None = None) -> np.ndarray:
    """``S = d q_tree / d q`` on the constraint manifold: (tree nv) x (actuated).

    Rows of actuated joints are the identity; passive rows are ``-J_p^+ J_a``.
    """
    S = np.zeros((robot.tree.nv, robot.nq))
    S[robot.tree_q_actuated, np.arange(robot.nq)] = 1.0
    if robot.constraints:
        J = constraint_jacobian(robot, q_tree, data)
        S[robot.tree_q_passive] = -np.linalg.lstsq(J[:, robot.tree_q_passive], J[:, robot.tree_q_actuated],
                                                   rcond=None)[0]
    return S


def project_torques(robot: Robot, q_tree: np.ndarray, tau_tree: np.ndarray,
                    data: RobotData | None = None) -> ProjectedTorques:
    """Actuator forces that supply the open tree's generalised forces ``tau_tree``.

    Passive joints carry no actuator: the loop forces ``lambda`` take their share,
    ``J_p^T lambda = tau_p``, and the actuated joints the rest, ``tau_a - J_a^T lambda``.
    """
    tau_tree = np.asarray(tau_tree, dtype=float)
    if not robot.constraints:
        return ProjectedTorques(tau_tree[robot.tree_q_actuated], np.zeros(0))
    J = constraint_jacobian(robot, q_tree, data)
    lam = np.linalg.lstsq(J[:, robot.tree_q_passive].T, tau_tree[robot.tree_q_passive], rcond=None)[0]
    tau = tau_tree[robot.tree_q_actuated] - J[:, robot.tree_q_actuated].T @ lam
    return ProjectedTorques(tau, lam)


def mass_matrix(robot: Robot, q_tree: np.ndarray, data: RobotData | None = None) -> np.ndarray:
    """Joint-space inertia in actuated coordinates, ``S^T M_tree S`` (kg m^2, kg)."""
    S = actuation_jacobian(robot, q_tree, data)
    M = pin.crba(robot.tree, robot.workspace(data).tree, q_tree, pin.Convention.WORLD)
    M = np.triu(M) + np.triu(M, 1).T
    return S.T @ M @ S

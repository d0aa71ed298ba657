"""Gravity torques on the actuated joints, single pose and vectorised over many poses.

``tau`` is the generalised gravity ``g(q) = dV/dq`` in actuated coordinates: the torque (N m) or
force (N) each actuated joint must supply to hold the pose. Three ways to the same number:

- :func:`gravity_torque` on the reduced model (Pinocchio's mimic-joint gravity), or on the
  constrained model (open-tree gravity projected through the loop-closure Jacobian);
- :func:`gravity_batch`: a NumPy evaluation over ``(N, nq)`` poses at once, from the open tree's
  joint placements, axes and inertias and the sidecar's linear loop relations. It is what the
  torque maps use; the tests hold it to Pinocchio at 1e-12.

Both refuse a robot without inertial data and warn when some links have none
(:func:`rcm_kin.model.masses.require_masses`), unless ``allow_massless`` says the caller knows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.model import constrained
from rcm_kin.model.masses import require_masses
from rcm_kin.model.reduced import relation_jacobian, tree_configuration
from rcm_kin.model.robot import Robot, RobotData, check_robot
from rcm_kin.progress import over_blocks
from rcm_kin.symbolic.tree import joint_axis


def gravity_torque(robot: Robot, q, method: str = "reduced", data: RobotData | None = None, *,
                   allow_massless: bool = False, allow_outside_limits: bool = False) -> np.ndarray:
    """Holding torques of the actuated joints at actuated ``q`` (N m, N), actuated order.

    ``method``: ``"reduced"`` (mimic model) or ``"constrained"`` (loop solve + projection);
    ``data``: the caller's workspace (:meth:`Robot.create_data`), default this thread's own;
    ``allow_massless``: take links without ``<inertial>`` as massless without a word (else a
    robot without any masses is refused, one with some missing warned about once);
    ``allow_outside_limits``: evaluate a pose outside the joint limits (refused by default,
    :meth:`Robot.check_pose`).
    """
    robot = check_robot(robot)
    if robot.massless_links and not allow_massless:
        require_masses(robot, "gravity")
    q = robot.check_pose(q, allow_outside_limits=allow_outside_limits)
    data = robot.workspace(data)
    if method == "reduced":
        g = pin.computeGeneralizedGravity(robot.reduced, data.reduced, robot.to_reduced(q))
        return robot.from_reduced(g).copy()
    if method == "constrained":
        q_tree = constrained.solve_loops(robot, q, data=data)
        g_tree = pin.computeGeneralizedGravity(robot.tree, data.tree, q_tree)
        return constrained.project_torques(robot, q_tree, g_tree, data).tau
    raise RcmKinError(f"unknown gravity method '{method}': use 'reduced' or 'constrained'")


@dataclass(frozen=True)
class TreeKinematicsBatch:
    """World placements of every open-tree joint over N poses (base frame, m).

    Pose index last ("structure of arrays"), so that every operation is a NumPy loop over N."""

    rotation: list[np.ndarray]   # per joint (3, 3, N); index 0 is the universe
    origin: list[np.ndarray]     # per joint (3, N)
    axis: list[np.ndarray]       # per joint (3, N): unit joint axis in the base frame
    prismatic: np.ndarray    # (njoints,) bool


def _times_constant(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """(3, 3, N) stack times one (3, 3) matrix (the identity costs nothing)."""
    if np.array_equal(B, np.eye(3)):
        return A
    return np.einsum("ijn,jk->ikn", A, B, optimize=True)


def _apply(A: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(3, 3, N) stack applied to (3,) or (3, N) vectors."""
    v = v[:, None] if v.ndim == 1 else v
    return A[:, 0] * v[0] + A[:, 1] * v[1] + A[:, 2] * v[2]


def _rotation_about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: (3, 3, N) rotations by ``angle`` (N,) about the unit ``axis``."""
    K = pin.skew(axis)
    return np.eye(3)[:, :, None] + K[:, :, None] * np.sin(angle) + (K @ K)[:, :, None] * (1 - np.cos(angle))


def _rotate(R: np.ndarray, axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """``R @ rot(axis, angle)`` pose-wise for (3, 3, N) ``R``. An axis along +-x, y or z only
    mixes two columns; any other axis takes the full Rodrigues product."""
    k = int(np.argmax(np.abs(axis)))
    if abs(abs(axis[k]) - 1.0) < 1e-15:
        i, j = (k + 1) % 3, (k + 2) % 3
        c, s = np.cos(angle), np.sign(axis[k]) * np.sin(angle)
        out = np.empty_like(R)
        out[:, k] = R[:, k]
        out[:, i] = R[:, i] * c + R[:, j] * s
        out[:, j] = R[:, j] * c - R[:, i] * s
        return out
    B = _rotation_about(axis, angle)
    return R[:, 0, None] * B[0] + R[:, 1, None] * B[1] + R[:, 2, None] * B[2]


def tree_kinematics_batch(robot: Robot, Q: np.ndarray) -> TreeKinematicsBatch:
    """Placements of all open-tree joints at (N, nq) actuated poses."""
    model = robot.tree
    Qt = tree_configuration(robot, Q)
    n = len(Q)
    R = [np.broadcast_to(np.eye(3)[:, :, None], (3, 3, n))]
    p = [np.zeros((3, n))]
    axes = [np.zeros((3, n))]
    prismatic = np.zeros(model.njoints, dtype=bool)
    for j in range(1, model.njoints):
        joint, parent, placement = model.joints[j], model.parents[j], model.jointPlacements[j]
        axis, prismatic[j] = joint_axis(joint)
        qj = Qt[:, joint.idx_q]
        R_fixed = _times_constant(R[parent], placement.rotation)     # joint frame before its motion
        origin = p[parent] + _apply(R[parent], placement.translation)
        axes.append(_apply(R_fixed, axis))
        if prismatic[j]:
            R.append(R_fixed)
            p.append(origin + qj * axes[j])
        else:
            R.append(_rotate(R_fixed, axis, qj))
            p.append(origin)
    return TreeKinematicsBatch(R, p, axes, prismatic)


def _subtree_torques(robot: Robot, kin: TreeKinematicsBatch, mass: np.ndarray, first_moment: np.ndarray) -> np.ndarray:
    """Actuated gravity torques (N, nq) of per-joint masses (njoints,) and world first
    moments (njoints, 3, N) (kg, kg m), accumulated over subtrees."""
    model = robot.tree
    g = np.asarray(model.gravity.linear)
    M = mass.astype(float).copy()
    H = list(first_moment)
    for j in range(model.njoints - 1, 0, -1):          # children before parents
        parent = model.parents[j]
        if parent > 0:
            M[parent] += M[j]
            H[parent] = H[parent] + H[j]
    tau_tree = np.zeros((kin.origin[0].shape[1], model.nv))
    for j in range(1, model.njoints):
        iv = model.joints[j].idx_v
        if kin.prismatic[j]:
            tau_tree[:, iv] = -M[j] * (g @ kin.axis[j])
        else:
            # -g . (axis x lever) = -lever . (g x axis)
            tau_tree[:, iv] = -np.einsum("in,in->n", np.cross(g, kin.axis[j], axisb=0, axisc=0),
                                         H[j] - M[j] * kin.origin[j])
    return tau_tree @ relation_jacobian(robot)


def _poses(robot: Robot, Q) -> np.ndarray:
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    if Q.ndim != 2 or Q.shape[1] != robot.nq or not np.all(np.isfinite(Q)):
        raise RcmKinError(f"poses must be finite rows of {robot.nq} joint values, got shape {Q.shape}")
    return Q


def gravity_batch(robot: Robot, Q, offsets: dict | None = None, chunk: int = 8192,
                  progress: bool = False, *, allow_massless: bool = False) -> np.ndarray:
    """Holding torques (N, nq) at (N, nq) actuated poses (N m, N), vectorised over poses in
    chunks of ``chunk`` poses (cache-sized); ``progress`` shows a bar over the chunks.

    ``offsets``: extra first moments {link: (3,) kg m in the link's frame}, e.g. the calibrated
    ``DriveParameters.gravity_offsets``; they add torque but no mass. ``allow_massless`` as in
    :func:`gravity_torque`."""
    if robot.massless_links and not allow_massless:
        require_masses(robot, "gravity")
    Q = _poses(robot, Q)
    moments = offset_moments(robot, offsets or {})
    starts = over_blocks(range(0, len(Q), chunk), progress, "gravity", "chunk")
    return np.concatenate([_gravity_chunk(robot, Q[i:i + chunk], moments) for i in starts])


def offset_moments(robot: Robot, offsets: dict) -> dict[int, np.ndarray]:
    """{joint index: first moment in the joint's frame (kg m)} of link first moments."""
    moments = {}
    for link, h in offsets.items():
        if not robot.tree.existFrame(link):
            raise RcmKinError(f"gravity offset on '{link}': {robot.name} has no such link")
        frame = robot.tree.frames[robot.tree.getFrameId(link)]
        moments[frame.parentJoint] = moments.get(frame.parentJoint, 0.0) + frame.placement.rotation @ np.asarray(h)
    return moments


def _gravity_chunk(robot: Robot, Q: np.ndarray, moments: dict[int, np.ndarray]) -> np.ndarray:
    kin = tree_kinematics_batch(robot, Q)
    model = robot.tree
    mass = np.array([model.inertias[j].mass for j in range(model.njoints)])
    H = np.zeros((model.njoints, 3, len(Q)))
    for j in range(1, model.njoints):
        H[j] = mass[j] * (kin.origin[j] + _apply(kin.rotation[j], model.inertias[j].lever))
        if j in moments:
            H[j] += _apply(kin.rotation[j], moments[j])
    return _subtree_torques(robot, kin, mass, H)


def point_mass_gravity_batch(robot: Robot, Q, link: str, point) -> np.ndarray:
    """Holding torques (N, nq) of 1 kg at ``point`` (m, in ``link``'s frame) at poses ``Q``.

    Gravity is linear in mass, so a counterweight of mass m adds m times this."""
    Q = _poses(robot, Q)
    model = robot.tree
    if not model.existFrame(link):
        raise RcmKinError(f"{robot.name} has no link '{link}'")
    frame = model.frames[model.getFrameId(link)]
    kin = tree_kinematics_batch(robot, Q)
    j = frame.parentJoint
    mass = np.zeros(model.njoints)
    mass[j] = 1.0
    H = np.zeros((model.njoints, 3, len(Q)))
    H[j] = kin.origin[j] + _apply(kin.rotation[j], frame.placement * np.asarray(point, dtype=float))
    return _subtree_torques(robot, kin, mass, H)

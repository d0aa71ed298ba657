"""Numeric inverse kinematics: damped least squares with the joint limits respected.

Each step ``dq = J^T (J J^T + lambda^2 I)^-1 e`` is capped at ``max_step`` (rad or m per joint),
projected back into the limits and shortened until the error decreases. When no start reaches
the tolerance (a fixed ``lambda`` stalls next to a singularity), the closest attempt goes on with
``lambda`` equal to the error's norm, which vanishes with it (Sugihara 2011). A
solution is returned only when the error is below tolerance; otherwise the best attempt is
reported in the error, never returned as if it were a solution.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError

if TYPE_CHECKING:
    from rcm_kin.model import Robot


@dataclass(frozen=True)
class IKResult:
    q: np.ndarray               # actuated joints (rad, m)
    position_error: float       # m
    orientation_error: float    # rad (0 when only the position was asked for)
    iterations: int             # of the search that reached it (a continued search's own: see solve_ik)


def _pose_error(robot: Robot, q, fid, position, rotation) -> tuple[np.ndarray, pin.SE3]:
    pin.forwardKinematics(robot.reduced, robot.reduced_data, robot.to_reduced(q))
    placement = pin.updateFramePlacement(robot.reduced, robot.reduced_data, fid)
    e = position - placement.translation
    if rotation is not None:
        # orientation error as a base-frame rotation vector
        e = np.concatenate([e, placement.rotation @ pin.log3(placement.rotation.T @ rotation)])
    return e, placement


def solve_ik(robot: Robot, frame: str, position, rotation: np.ndarray | None = None, q0=None,
             joints: tuple[str, ...] | None = None, tol: float = 1e-10, max_iter: int = 500,
             damping: float = 1e-4, max_step: float = 0.2, restarts: int = 16,
             seed: int = 0) -> IKResult:
    """Actuated ``q`` putting ``frame`` at ``position`` (m, base frame), and at ``rotation``
    when given, moving only ``joints`` (default: all actuated joints).

    Starts from ``q0`` (default: mid-range), then from seeded random configurations within
    the limits. Raises RcmKinError when no start reaches ``tol`` (norm of the position error in m,
    stacked with the orientation error in rad).
    """
    position = np.asarray(position, dtype=float)
    if position.shape != (3,) or not np.all(np.isfinite(position)):
        raise RcmKinError(f"a target is 3 finite numbers x y z in metres, got {np.asarray(position).tolist()}")
    fid = robot.frame_id(frame)
    joints = robot.actuated if joints is None else joints
    cols = np.array([robot.actuated.index(j) for j in joints])
    red_cols = robot.reduced_q_actuated[cols]
    lower, upper = robot.lower[cols], robot.upper[cols]
    mid = np.zeros(robot.nq)
    mid[cols] = 0.5 * (lower + upper)
    rng = np.random.default_rng(seed)
    starts = [robot.check_q(q0) if q0 is not None else mid]
    for _ in range(restarts):
        start = starts[0].copy()
        start[cols] = rng.uniform(lower, upper)
        starts.append(start)

    best = (np.inf, None)
    steps = (fid, position, rotation, cols, red_cols, lower, upper, tol, max_iter, max_step)
    for start in starts:
        q = start.copy()
        q[cols] = np.clip(q[cols], lower, upper)
        q, e, it, reached = _descend(robot, q, steps, damping)
        if reached:
            return _result(robot, q, fid, position, rotation, it)
        if np.linalg.norm(e) < best[0]:
            best = (np.linalg.norm(e), q.copy())
    # a fixed damping stalls next to a singularity (it damps away the step along the weak direction):
    # from the closest attempt, a damping that is the error's norm, and vanishes with it (Sugihara 2011)
    closest, q = best
    if q is not None:
        q, e, it, reached = _descend(robot, q, steps, None)
        if reached:
            return _result(robot, q, fid, position, rotation, it)
        q = best[1] if not np.linalg.norm(e) < closest else q
    near = frame_reached(robot, q if q is not None else starts[0], fid)
    raise RcmKinError(f"no configuration within the joint limits puts {frame} at "
                      f"({', '.join(f'{x:.4f}' for x in position)}) m"
                      + (" with that orientation" if rotation is not None else "")
                      + f"; the closest reached {np.linalg.norm(near - position) * 1e3:.2f} mm away")


def _descend(robot: Robot, q: np.ndarray, steps: tuple,
             damping: float | None) -> tuple[np.ndarray, np.ndarray, int, bool]:
    """Damped least-squares steps from ``q`` (``steps``: the frame id, target, joint columns, limits,
    tolerance, iterations and step cap of :func:`solve_ik`) until the error is below tolerance, a
    step no longer lowers it, or the iterations run out: ``(q, error, iteration, reached)``.
    ``damping`` None: the error's norm at each step (Levenberg-Marquardt's adaptive damping)."""
    fid, position, rotation, cols, red_cols, lower, upper, tol, max_iter, max_step = steps
    rows = slice(None) if rotation is not None else slice(0, 3)
    e, _ = _pose_error(robot, q, fid, position, rotation)
    it = 0
    for it in range(1, max_iter + 1):
        if np.linalg.norm(e) < tol:
            return q, e, it, True
        J = pin.computeFrameJacobian(robot.reduced, robot.reduced_data, robot.to_reduced(q), fid,
                                     pin.LOCAL_WORLD_ALIGNED)[rows][:, red_cols]
        lam = np.linalg.norm(e) if damping is None else damping
        if not lam:
            break  # no error left to scale the damping by (a tolerance of 0 is never reached)
        dq = _limited_step(J, e, q[cols], lower, upper, lam)
        dq *= min(1.0, max_step / max(np.max(np.abs(dq)), 1e-300))
        # backtracking: accept the first step length that lowers the error
        for alpha in 0.5 ** np.arange(12):
            trial = q.copy()
            trial[cols] = np.clip(q[cols] + alpha * dq, lower, upper)
            e_trial, _ = _pose_error(robot, trial, fid, position, rotation)
            if np.linalg.norm(e_trial) < np.linalg.norm(e):
                break
        else:
            break  # stuck at a limit or a local minimum
        q, e = trial, e_trial
    return q, e, it, False


def _limited_step(J, e, q, lower, upper, damping) -> np.ndarray:
    """Damped least-squares step over the joints free to move: a joint at a limit that the
    step would push further out is held (its column dropped) and the step solved again."""
    free = np.ones(J.shape[1], dtype=bool)
    while True:
        Jf = J[:, free]
        dq = np.zeros(J.shape[1])
        dq[free] = Jf.T @ np.linalg.solve(Jf @ Jf.T + damping**2 * np.eye(J.shape[0]), e)
        blocked = free & (((q <= lower) & (dq < 0)) | ((q >= upper) & (dq > 0)))
        if not blocked.any():
            return dq
        free &= ~blocked


def frame_reached(robot: Robot, q, fid) -> np.ndarray:
    pin.forwardKinematics(robot.reduced, robot.reduced_data, robot.to_reduced(q))
    return pin.updateFramePlacement(robot.reduced, robot.reduced_data, fid).translation.copy()


def _result(robot: Robot, q, fid, position, rotation, iterations) -> IKResult:
    _, placement = _pose_error(robot, q, fid, position, rotation)
    rot_err = 0.0 if rotation is None else float(np.linalg.norm(pin.log3(placement.rotation.T @ rotation)))
    return IKResult(q, float(np.linalg.norm(placement.translation - position)), rot_err, iterations)

"""Closed-form inverse kinematics of any arm whose description declares a remote centre of motion.

The sidecar's ``[rcm]`` names the instrument shaft (the z axis of ``shaft_frame``) and the two
pivot joints that turn it about the RCM; the insertion is the actuated prismatic joint that slides
``shaft_frame`` along the shaft at every pivot angle (found in the model). Everything else is read
from the model's Jacobians at the rest pose (pivots and insertion at 0, the other joints at ``q0``):

- the RCM: the point of the rest shaft line that neither pivot joint moves;
- each pivot's unit axis and rate (rad of shaft rotation per unit of the joint), and which of the two
  is nearer the base (its axis does not turn with the other);
- the insertion's rate along the shaft and the shaft frame's offset from the RCM.

A target ``p`` then fixes the shaft direction ``u = +-(p - rcm) / |p - rcm|``; Paden-Kahan
subproblem 2 (two intersecting axes rotating the rest shaft direction onto ``u``) gives the pivot
angles, and the distance the insertion. No robot is named: the bundled PSM's own closed form
(:func:`rcm_kin.kinematics.psm_ik.shaft_tip_ik`) is its twin, tested against this one.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.kinematics.fk import frame_placement

if TYPE_CHECKING:
    from rcm_kin.model import Robot

AT_RCM = 1e-9      # m: a target this close to the RCM leaves the shaft direction undetermined
LIMIT_TOL = 1e-12  # rad or m: a solution this far beyond a limit still counts as within it


@dataclass(frozen=True)
class RcmChain:
    """An RCM arm's geometry at its rest pose, in the base frame."""

    shaft_frame: str
    joints: tuple[str, str, str]   # the two pivot joints ([rcm] order), then the insertion
    index: np.ndarray              # their positions in the actuated order
    rest: np.ndarray               # actuated q the geometry is taken at (the three joints at 0)
    rcm: np.ndarray                # m
    axes: np.ndarray               # (2, 3) unit axes of the pivot joints at rest
    rates: np.ndarray              # (2,) rad of shaft rotation per unit of each pivot joint
    outer: int                     # 0 or 1: the pivot nearer the base
    shaft: np.ndarray              # unit z axis of shaft_frame at rest
    offset: float                  # m, shaft_frame origin - rcm along ``shaft`` at rest
    insertion_rate: float          # m of travel along the shaft per unit of the insertion joint
    line_error: float              # m, how far the pivots move the rest shaft line's RCM point (first order)
    lower: np.ndarray              # (3,) limits of ``joints``
    upper: np.ndarray
    revolute: np.ndarray           # (2,) whether each pivot is revolute (its angle wraps)


def _jacobian(robot: Robot, q: np.ndarray, fid: int) -> np.ndarray:
    """6 x nq frame Jacobian (linear rows first, base-frame axes) over the actuated joints."""
    J = pin.computeFrameJacobian(robot.reduced, robot.reduced_data, robot.to_reduced(q), fid,
                                 pin.LOCAL_WORLD_ALIGNED)
    return J[:, robot.reduced_q_actuated]


def rcm_chain(robot: Robot, q0=None) -> RcmChain:
    """The geometry of ``robot``'s ``[rcm]`` with the joints other than the pivots and the
    insertion at ``q0`` (actuated order, default 0). Raises RcmKinError when the description has
    no ``[rcm]`` or the model does not fit it."""
    if robot.description.rcm is None:
        raise RcmKinError(f"{robot.name}: its description has no [rcm]; the closed-form RCM IK needs one")
    rest = np.zeros(robot.nq) if q0 is None else robot.check_q(q0, allow_short=True)
    return _chain(robot, tuple(rest.tolist()))


@functools.lru_cache(maxsize=64)
def _chain(robot: Robot, rest: tuple[float, ...]) -> RcmChain:
    rcm = robot.description.rcm
    pivots = [robot.actuated.index(j) for j in rcm.joints]
    fid = robot.frame_id(rcm.shaft_frame)
    q = np.array(rest)
    q[pivots] = 0.0
    insertion = _insertion(robot, q, fid, pivots)
    q[insertion] = 0.0
    M = frame_placement(robot, q, rcm.shaft_frame)
    shaft = M.rotation[:, 2]
    J = _jacobian(robot, q, fid)
    v, w = J[:3, pivots].T, J[3:, pivots].T
    rates = np.linalg.norm(w, axis=1)
    if np.any(rates < 1e-9):
        raise RcmKinError(f"{robot.name}: [rcm] joint '{rcm.joints[int(np.argmin(rates))]}' does not turn "
                          f"{rcm.shaft_frame}")
    a = np.cross(w, shaft)
    s = -float(np.sum(v * a) / np.sum(a * a))    # shaft_frame origin + s * shaft is still under both pivots
    line_error = float(np.max(np.linalg.norm(v + s * a, axis=1) / rates))
    axes = w / rates[:, None]
    # the outer pivot carries the inner one: turning it turns the inner pivot's axis
    turned = q.copy()
    turned[pivots[0]] = 0.3 / rates[0]
    w1 = _jacobian(robot, turned, fid)[3:, pivots[1]]
    outer = 0 if np.linalg.norm(w1 / rates[1] - axes[1]) > 1e-9 else 1
    insertion_rate = float(J[:3, insertion] @ shaft)
    index = np.array([*pivots, insertion])
    revolute = np.array([robot.joint_kind(rcm.joints[j]) == "revolute" for j in (0, 1)])
    return RcmChain(rcm.shaft_frame, (*rcm.joints, robot.actuated[insertion]), index, np.array(rest),
                    M.translation + s * shaft, axes, rates, outer, shaft, -s, insertion_rate, line_error,
                    robot.lower[index].copy(), robot.upper[index].copy(), revolute)


def _insertion(robot: Robot, q: np.ndarray, fid: int, pivots: list[int]) -> int:
    """Index of the one actuated prismatic joint sliding the shaft frame along its z axis, at rest
    and with the pivots turned (a joint before the pivots slides it along a fixed line instead)."""
    tilted = q.copy()
    tilted[pivots] = 0.2, 0.3
    found = []
    for k, name in enumerate(robot.actuated):
        if k in pivots or robot.joint_kind(name) != "prismatic":
            continue
        along = True
        for pose in (q, tilted):
            column = _jacobian(robot, pose, fid)[:, k]
            z = frame_placement(robot, pose, robot.description.rcm.shaft_frame).rotation[:, 2]
            speed = np.linalg.norm(column[:3])
            along &= bool(speed > 1e-9 and np.linalg.norm(column[3:]) < 1e-9
                          and np.linalg.norm(np.cross(column[:3], z)) < 1e-9 * speed)
        if along:
            found.append(k)
    shaft_frame = robot.description.rcm.shaft_frame
    if len(found) != 1:
        raise RcmKinError(f"{robot.name}: the closed-form RCM IK needs one actuated prismatic joint sliding "
                          f"{shaft_frame} along its z axis (the shaft); found "
                          f"{', '.join(robot.actuated[k] for k in found) or 'none'}")
    return found[0]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two 3-vectors (numpy's general one costs ten times more)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _rotation_angle(axis: np.ndarray, p: np.ndarray, q: np.ndarray) -> float:
    """Paden-Kahan subproblem 1: the angle about unit ``axis`` turning ``p`` onto ``q``."""
    p_perp, q_perp = p - axis * (axis @ p), q - axis * (axis @ q)
    return float(np.arctan2(axis @ _cross(p_perp, q_perp), p_perp @ q_perp))


def pivot_angles(axis_outer: np.ndarray, axis_inner: np.ndarray, p: np.ndarray, q: np.ndarray,
                 tol: float = 1e-12) -> list[tuple[float, float]]:
    """Paden-Kahan subproblem 2: every ``(theta_outer, theta_inner)`` (rad) with
    ``exp(axis_outer theta_outer) exp(axis_inner theta_inner) p = q`` (unit axes through one point,
    ``|p| = |q|``); none, one or two pairs."""
    c = float(axis_outer @ axis_inner)
    normal = _cross(axis_outer, axis_inner)
    if normal @ normal < 1e-18:
        raise RcmKinError("the two [rcm] joints turn the shaft about parallel axes")
    alpha = (q @ axis_outer - c * (p @ axis_inner)) / (1 - c * c)
    beta = (p @ axis_inner - c * (q @ axis_outer)) / (1 - c * c)
    gamma2 = (p @ p - alpha**2 - beta**2 - 2 * alpha * beta * c) / (normal @ normal)
    if gamma2 < -tol:
        return []
    gammas = (0.0,) if gamma2 <= tol else (np.sqrt(gamma2), -np.sqrt(gamma2))
    pairs = []
    for gamma in gammas:
        z = alpha * axis_outer + beta * axis_inner + gamma * normal
        pairs.append((_rotation_angle(axis_outer, z, q), _rotation_angle(axis_inner, p, z)))
    return pairs


def broken_limits(robot: Robot, names, values, tol: float = LIMIT_TOL) -> list[str]:
    """The limits that ``values`` of joints ``names`` break, as text for people (empty when all are
    within ``tol``)."""
    broken = []
    for name, value in zip(names, values):
        i = robot.actuated.index(name)
        lo, hi = robot.lower[i], robot.upper[i]
        if not lo - tol <= value <= hi + tol:
            if robot.joint_kind(name) == "prismatic":
                broken.append(f"{name} {value * 1e3:.2f} mm outside [{lo * 1e3:.1f}, {hi * 1e3:.1f}] mm")
            else:
                broken.append(f"{name} {np.degrees(value):.2f} deg outside "
                              f"[{np.degrees(lo):.1f}, {np.degrees(hi):.1f}] deg")
    return broken


def _candidates(chain: RcmChain, d: np.ndarray, side: float, wraps: bool) -> list[np.ndarray]:
    """Pivot and insertion values pointing the shaft along ``side * d``, the pivots' principal values
    first (then, with ``wraps``, the revolute pivots' values 2 pi / rate apart)."""
    dist = float(np.linalg.norm(d))
    u = side * d / dist
    q_ins = (side * dist - chain.offset) / chain.insertion_rate
    outer, inner = chain.outer, 1 - chain.outer
    found = []
    for th_outer, th_inner in pivot_angles(chain.axes[outer], chain.axes[inner], chain.shaft, u):
        theta = np.empty(2)
        theta[outer], theta[inner] = th_outer, th_inner
        found.append(np.array([*(theta / chain.rates), q_ins]))
    found.sort(key=lambda c: (abs(c[inner]), abs(c[outer])))
    if not wraps:
        return found
    wrapped = []
    for c in found:
        for k in (1, -1, 2, -2):
            for j in (0, 1):
                if chain.revolute[j]:
                    variant = c.copy()
                    variant[j] += k * 2 * np.pi / chain.rates[j]
                    wrapped.append(variant)
    return found + wrapped


def rcm_ik(robot: Robot, target, q0=None) -> tuple[np.ndarray, RcmChain]:
    """Actuated ``q`` putting the origin of ``[rcm] shaft_frame`` at ``target`` (m, base frame):
    the pivot joints and the insertion in closed form, the other joints at ``q0`` (default 0).

    Of the solutions within the joint limits, the one nearest ``q0`` when given, else the one with
    the shaft frame on its usual side of the RCM and the smallest inner pivot angle. Returns
    ``(q, chain)``; raises RcmKinError (one line, saying why) when none is within the limits or the
    target is the RCM itself. Exact for a true RCM (``chain.line_error`` ~ 0); for a chain whose
    shaft lines only nearly meet, a start for a numeric solver.
    """
    target = np.asarray(target, dtype=float)
    if target.shape != (3,) or not np.all(np.isfinite(target)):
        raise RcmKinError(f"a target is 3 finite numbers x y z in metres, got {np.asarray(target).tolist()}",
                          parameter="position")
    chain = rcm_chain(robot, q0)
    d = target - chain.rcm
    if np.linalg.norm(d) < AT_RCM:
        raise RcmKinError(f"{chain.shaft_frame} target {_shown(target)} is the remote centre of motion itself: "
                          "the shaft direction is undetermined there", parameter="position")
    i = robot.actuated.index(chain.joints[2])
    mid = chain.offset + chain.insertion_rate * 0.5 * (robot.lower[i] + robot.upper[i])
    usual = 1.0 if mid >= 0 else -1.0
    for wraps in (False, True) if q0 is None else (True,):
        ranked = [(side, c) for side in (usual, -usual) for c in _candidates(chain, d, side, wraps)]
        valid = [c for _, c in ranked
                 if np.all(chain.lower - LIMIT_TOL <= c) and np.all(c <= chain.upper + LIMIT_TOL)]
        if valid:
            break
    else:
        raise _out_of_reach(robot, chain, d, usual, ranked, _shown(target))
    best = valid[0] if q0 is None else min(valid, key=lambda c: np.linalg.norm(c - chain.rest[chain.index]))
    q = chain.rest.copy()
    q[chain.index] = best
    return q, chain


def _shown(target: np.ndarray) -> str:
    return f"({', '.join(f'{x:.4f}' for x in target)}) m"


def _out_of_reach(robot, chain, d, usual, ranked, shown) -> RcmKinError:
    principal = [c for side, c in ranked if side == usual][:1] or [c for _, c in ranked][:1]
    if not principal:
        return RcmKinError(f"{chain.shaft_frame} target {shown} is out of reach: no turn of "
                           f"{chain.joints[0]} and {chain.joints[1]} points the shaft at it", parameter="position")
    needs = ", ".join(broken_limits(robot, chain.joints, principal[0]))
    behind = usual * float(d @ chain.shaft) < 0
    where = " (it lies on the far side of the remote centre from the instrument)" if behind else ""
    return RcmKinError(f"{chain.shaft_frame} target {shown} is out of reach{where}: it needs {needs}",
                       parameter="position")

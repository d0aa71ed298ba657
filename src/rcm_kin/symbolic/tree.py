"""A fixed-base Pinocchio tree transcribed into CasADi expressions.

The PyPI ``pin`` wheel has no ``pinocchio.casadi``, so the joint placements, axes, inertias and
armature of a :class:`pinocchio.Model` are read once and the recursive Newton-Euler algorithm
is written out on CasADi symbols. Conventions are Pinocchio's: spatial motions and forces are
expressed in each joint's local frame, linear part first; gravity is ``model.gravity``.

Supported joints: the 1-DOF revolute and prismatic ones (``RX/RY/RZ``, ``PX/PY/PZ``,
``RevoluteUnaligned``, ``PrismaticUnaligned``). Anything else (free flyer, spherical,
unbounded revolute, mimic) raises :class:`~rcm_kin.errors.RcmKinError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError


@dataclass(frozen=True)
class JointKinematics:
    """One joint of the tree, as constants: where it sits on its parent and how it moves."""

    parent: int
    rotation: np.ndarray      # (3, 3) joint placement in the parent joint's frame
    translation: np.ndarray   # (3,) m
    axis: np.ndarray          # (3,) unit axis in the joint frame
    prismatic: bool
    mass: float               # kg
    lever: np.ndarray         # (3,) centre of mass in the joint frame, m
    inertia: np.ndarray       # (3, 3) rotational inertia about the centre of mass, kg m^2
    armature: float           # kg m^2 (kg): added to the joint's own acceleration torque


def tree_joints(model: pin.Model) -> list[JointKinematics]:
    """The constants of every joint (index 0, the universe, excluded), in Pinocchio's order."""
    if model.nq != model.nv:
        raise RcmKinError("the CasADi transcription needs nq == nv (1-DOF joints only)")
    joints = []
    for j in range(1, model.njoints):
        joint = model.joints[j]
        axis, prismatic = joint_axis(joint)
        placement, inertia = model.jointPlacements[j], model.inertias[j]
        if joint.idx_q != j - 1:
            raise RcmKinError("the CasADi transcription needs joints stored depth-first, one coordinate each")
        joints.append(JointKinematics(
            parent=int(model.parents[j]), rotation=np.array(placement.rotation),
            translation=np.array(placement.translation), axis=axis, prismatic=prismatic,
            mass=float(inertia.mass), lever=np.array(inertia.lever), inertia=np.array(inertia.inertia),
            armature=float(model.armature[joint.idx_v])))
    return joints


def joint_axis(joint) -> tuple[np.ndarray, bool]:
    """Unit axis (in the joint frame) of a 1-DOF revolute or prismatic joint, and whether it slides."""
    name = joint.shortname()
    if name in ("JointModelRevoluteUnaligned", "JointModelPrismaticUnaligned"):
        return np.asarray(joint.extract().axis, dtype=float), "Prismatic" in name
    for prefix, prismatic in (("JointModelR", False), ("JointModelP", True)):
        if name in (prefix + "X", prefix + "Y", prefix + "Z"):
            return np.eye(3)["XYZ".index(name[-1])], prismatic
    raise RcmKinError(f"joint type {name} is not supported (1-DOF revolute and prismatic joints only)")


def _rotation(axis: np.ndarray, angle) -> ca.SX:
    """Rodrigues' rotation about a constant unit axis by a symbolic angle."""
    K = ca.DM(pin.skew(axis))
    return ca.DM.eye(3) + ca.sin(angle) * K + (1 - ca.cos(angle)) * (K @ K)


def _joint_motion(joint: JointKinematics, qj) -> tuple[ca.SX, ca.SX]:
    """Placement (R, p) of the joint's moving frame in its parent's frame at coordinate ``qj``."""
    R0, p0 = ca.DM(joint.rotation), ca.DM(joint.translation)
    if joint.prismatic:
        return R0, p0 + R0 @ (ca.DM(joint.axis) * qj)
    return R0 @ _rotation(joint.axis, qj), p0


def world_placements(joints: list[JointKinematics], q) -> list[tuple[ca.SX, ca.SX]]:
    """World (base-frame) placements ``(R, p)`` of every joint frame, universe first."""
    out = [(ca.DM.eye(3), ca.DM.zeros(3))]
    for j, joint in enumerate(joints, start=1):
        R, p = _joint_motion(joint, q[j - 1])
        R_parent, p_parent = out[joint.parent]
        out.append((R_parent @ R, p_parent + R_parent @ p))
    return out


def rnea(joints: list[JointKinematics], gravity: np.ndarray, q, v, a) -> ca.SX:
    """Inverse dynamics ``tau = M(q) a + C(q, v) v + g(q)`` (N m, N), Pinocchio's RNEA.

    ``gravity``: (3,) m/s^2 in the base frame. ``q, v, a``: CasADi column vectors of length nv."""
    n = len(joints)
    lin, ang = [ca.DM.zeros(3)], [ca.DM.zeros(3)]                     # body velocity
    acc_lin, acc_ang = [ca.DM(-np.asarray(gravity, float))], [ca.DM.zeros(3)]
    frames, f_lin, f_ang = [None], [None], [None]
    for j, joint in enumerate(joints, start=1):
        R, p = _joint_motion(joint, q[j - 1])
        frames.append((R, p))
        s = ca.DM(joint.axis)
        i = joint.parent
        # parent motion seen in this joint's frame: X^-1 (v, w) = (R^T (v - p x w), R^T w)
        w = R.T @ ang[i]
        vl = R.T @ (lin[i] - ca.cross(p, ang[i]))
        dw = R.T @ acc_ang[i]
        dvl = R.T @ (acc_lin[i] - ca.cross(p, acc_ang[i]))
        qd, qdd = v[j - 1], a[j - 1]
        if joint.prismatic:
            vl = vl + s * qd
            dvl = dvl + s * qdd + ca.cross(w, s * qd)      # (vl, w) x (s qd, 0)
        else:
            w = w + s * qd
            dw = dw + s * qdd + ca.cross(w, s * qd)        # (vl, w) x (0, s qd)
            dvl = dvl + ca.cross(vl, s * qd)
        lin.append(vl)
        ang.append(w)
        acc_lin.append(dvl)
        acc_ang.append(dw)
        # f = I a + v x* (I v), I about the frame origin through the centre of mass c
        m, c, Ic = joint.mass, ca.DM(joint.lever), ca.DM(joint.inertia)
        h = m * (vl + ca.cross(w, c))
        hdot = m * (dvl + ca.cross(dw, c))
        n_ang = Ic @ w + ca.cross(c, h)
        f_lin.append(hdot + ca.cross(w, h))
        f_ang.append(Ic @ dw + ca.cross(c, hdot) + ca.cross(w, n_ang) + ca.cross(vl, h))
    tau = [None] * n
    for j in range(n, 0, -1):
        joint = joints[j - 1]
        s = ca.DM(joint.axis)
        tau[j - 1] = ca.dot(s, f_lin[j] if joint.prismatic else f_ang[j]) + joint.armature * a[j - 1]
        i = joint.parent
        if i > 0:
            R, p = frames[j]
            fl = R @ f_lin[j]
            f_lin[i] = f_lin[i] + fl
            f_ang[i] = f_ang[i] + R @ f_ang[j] + ca.cross(p, fl)
    return ca.vertcat(*tau)


@dataclass(frozen=True)
class TreeFunctions:
    """CasADi functions of a transcribed tree (SX, evaluate with NumPy or symbols)."""

    rnea: ca.Function            # (q, v, a) -> tau
    mass_matrix: ca.Function     # q -> M (nv x nv)
    gravity: ca.Function         # q -> g
    nv: int


def tree_functions(model: pin.Model) -> TreeFunctions:
    """RNEA, mass matrix (the Jacobian of RNEA in ``a``: RNEA is linear in ``a``) and gravity."""
    joints = tree_joints(model)
    n = model.nv
    q, v, a = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("a", n)
    gravity = np.array(model.gravity.linear)
    tau = rnea(joints, gravity, q, v, a)
    zero = ca.DM.zeros(n)
    M = ca.jacobian(rnea(joints, np.zeros(3), q, zero, a), a)
    g = rnea(joints, gravity, q, zero, zero)
    return TreeFunctions(
        rnea=ca.Function("rnea", [q, v, a], [tau], ["q", "v", "a"], ["tau"]),
        mass_matrix=ca.Function("mass_matrix", [q], [ca.simplify(M)], ["q"], ["M"]),
        gravity=ca.Function("gravity", [q], [g], ["q"], ["g"]),
        nv=n)

"""Forward dynamics of the PSM's driven joints (roll, pitch, insertion) with PWM as input.

State ``x = [q; v]`` with ``q = (roll rad, pitch rad, insertion m)`` and ``v`` their rates;
input ``u`` = PWM counts of the three drivers (hardware sign, not saturated). The instrument
joints are held at fixed values. The model, on CasADi symbols:

    (M(q) + diag(N^2 J_rotor + J_extra)) a = k_u u - (k_t^2 N^2 / R + b) v - F_c tanh(v / v_c) - c(q, v) - g(q)

- ``M, c, g``: rigid-body dynamics of the closed chain (the parallelogram included), from the
  open tree transcribed into CasADi (:mod:`rcm_kin.symbolic.tree`) and the loop-closure map
  (:mod:`rcm_kin.symbolic.closed_chain`); ``g`` also carries the calibrated first-moment
  offsets of the drive parameters, so the holding PWM equals the gravity maps';
- ``k_u = pwm_sign k_t N V_pwm / R`` (N m per count): the driver's voltage through the
  motor's resistance and torque constant and the transmission ``N``;
- back-EMF damping ``k_t^2 N^2 / R``, viscous ``b``, smoothed Coulomb ``F_c`` (drive parameters);
- ``J_extra``: inertia at the joint the CAD lacks, identified (:mod:`rcm_kin.identification.greybox`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, load_drive_parameters
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import DRIVER_PWM_RANGE
from rcm_kin.model.gravity import offset_moments
from rcm_kin.model.reduced import relation_jacobian, tree_configuration
from rcm_kin.symbolic.closed_chain import closed_chain_rnea, linear_closure
from rcm_kin.symbolic.tree import tree_joints, world_placements

if TYPE_CHECKING:
    from rcm_kin.model import Robot


@dataclass(frozen=True)
class DriveConstants:
    """Per driven joint, in DRIVEN order (SI)."""

    input_gain: np.ndarray         # k_u: N m (N) per PWM count, hardware sign included
    damping: np.ndarray            # back-EMF + viscous: N m s/rad (N s/m)
    coulomb: np.ndarray            # N m (N)
    coulomb_velocity: np.ndarray   # rad/s (m/s)
    reflected_inertia: np.ndarray  # kg m^2 (kg)


def drive_constants(params: DriveParameters) -> DriveConstants:
    d = [params[j] for j in DRIVEN]
    return DriveConstants(
        input_gain=np.array([1.0 / x.pwm_per_torque for x in d]),
        damping=np.array([x.torque_constant**2 * x.gear_ratio**2 / x.resistance + x.viscous for x in d]),
        coulomb=np.array([x.coulomb for x in d]),
        coulomb_velocity=np.array([x.coulomb_velocity for x in d]),
        reflected_inertia=np.array([x.reflected_inertia for x in d]))


@dataclass(frozen=True, eq=False)
class DrivenDynamics:
    """The driven-joint model as CasADi functions (evaluate with NumPy arrays or symbols)."""

    joints: tuple[str, ...]        # ("roll", "pitch", "insertion")
    q_fixed: np.ndarray            # the robot's actuated q; driven entries are overwritten
    lower: np.ndarray              # (3,) joint limits of the driven joints (rad, rad, m)
    upper: np.ndarray
    drive: DriveConstants
    coulomb: bool                  # whether the smoothed Coulomb term is in ``forward``
    forward: ca.Function           # (x, u) -> xdot
    jacobians: ca.Function         # (x, u) -> (A, B) = (d xdot/dx, d xdot/du), by AD
    mass_matrix: ca.Function       # q -> M + diag(N^2 J_rotor)   (kg m^2, kg)
    bias: ca.Function              # (q, v) -> c(q, v) + g(q)     (N m, N)
    gravity: ca.Function           # q -> g(q), offsets included  (N m, N)

    @property
    def state(self) -> list[str]:
        return [f"q_{j}" for j in self.joints] + [f"v_{j}" for j in self.joints]

    @property
    def inputs(self) -> list[str]:
        return [f"pwm_{j}" for j in self.joints]


def driven_dynamics(robot: Robot, params: DriveParameters | None = None, q_fixed=None,
                    coulomb: bool = True) -> DrivenDynamics:
    """Build the CasADi model of ``robot``'s driven joints (the PSM).

    ``q_fixed``: actuated configuration (robot order) giving the held instrument joints
    (default all zero). ``coulomb=False`` leaves the smoothed Coulomb friction out, e.g. for
    controller design (its slope at rest, ``F_c / v_c``, is a property of the smoothing only).
    """
    if not set(DRIVEN) <= set(robot.actuated):
        raise RcmKinError(f"{robot.name} has no driven joints {', '.join(DRIVEN)}: the drive model is the PSM's")
    params = params if params is not None else load_drive_parameters()
    q_fixed = robot.check_q(np.zeros(robot.nq) if q_fixed is None else q_fixed)
    index = [robot.actuated.index(j) for j in DRIVEN]
    drive = drive_constants(params)
    joints = tree_joints(robot.tree)
    gravity = np.array(robot.tree.gravity.linear)
    q, v, a, u = (ca.SX.sym(s, 3) for s in ("q", "v", "a", "u"))
    phi = _driven_closure(robot, q_fixed, q)

    rigid = closed_chain_rnea(joints, gravity, phi, q, v, a)
    zero = ca.DM.zeros(3)
    g_rigid = ca.substitute(rigid, ca.vertcat(v, a), ca.vertcat(zero, zero))
    g_offsets = _offset_gravity(robot, joints, gravity, params.gravity_offsets, phi, q)
    M = ca.jacobian(rigid, a) + ca.diag(ca.DM(drive.reflected_inertia))
    bias = ca.substitute(rigid, a, zero) + g_offsets

    tau = ca.DM(drive.input_gain) * u - ca.DM(drive.damping) * v
    if coulomb:
        tau -= ca.DM(drive.coulomb) * ca.tanh(v / ca.DM(drive.coulomb_velocity))
    x = ca.vertcat(q, v)
    xdot = ca.vertcat(v, ca.solve(M, tau - bias))
    return DrivenDynamics(
        joints=DRIVEN, q_fixed=q_fixed, lower=robot.lower[index], upper=robot.upper[index], drive=drive,
        coulomb=coulomb,
        forward=ca.Function("forward", [x, u], [xdot], ["x", "u"], ["xdot"]),
        jacobians=ca.Function("jacobians", [x, u], [ca.jacobian(xdot, x), ca.jacobian(xdot, u)],
                              ["x", "u"], ["A", "B"]),
        mass_matrix=ca.Function("mass_matrix", [q], [M], ["q"], ["M"]),
        bias=ca.Function("bias", [q, v], [bias], ["q", "v"], ["h"]),
        gravity=ca.Function("gravity", [q], [g_rigid + g_offsets], ["q"], ["g"]))


def _driven_closure(robot: Robot, q_fixed: np.ndarray, q) -> ca.SX:
    """Open-tree configuration of the driven coordinates ``q``: ``S (E q + q_rest) + offsets``,
    the other actuated joints held at ``q_fixed``."""
    index = [robot.actuated.index(j) for j in DRIVEN]
    rest = q_fixed.copy()
    rest[index] = 0.0
    return linear_closure(relation_jacobian(robot)[:, index], tree_configuration(robot, rest), q)


def driven_gravity_function(robot: Robot, offsets: dict, q_fixed=None) -> ca.Function:
    """``q -> g(q)`` (N m, N) of the driven joints with the first-moment ``offsets`` ({link: (3,)
    kg m}, e.g. ``DriveParameters.gravity_offsets``): the ``gravity`` of :func:`driven_dynamics`
    without building the rest of the model."""
    if not set(DRIVEN) <= set(robot.actuated):
        raise RcmKinError(f"{robot.name} has no driven joints {', '.join(DRIVEN)}: the drive model is the PSM's")
    q_fixed = robot.check_q(np.zeros(robot.nq) if q_fixed is None else q_fixed)
    joints = tree_joints(robot.tree)
    gravity = np.array(robot.tree.gravity.linear)
    q, zero = ca.SX.sym("q", 3), ca.DM.zeros(3)
    phi = _driven_closure(robot, q_fixed, q)
    g = (closed_chain_rnea(joints, gravity, phi, q, zero, zero)
         + _offset_gravity(robot, joints, gravity, offsets, phi, q))
    return ca.Function("driven_gravity", [q], [g], ["q"], ["g"])


def _offset_gravity(robot: Robot, joints, gravity, offsets: dict, phi, q) -> ca.SX:
    """Generalised gravity of the calibrated first moments (mass-free, kg m in link frames):
    the gradient of their potential ``-g . (R_j h_j)``."""
    moments = offset_moments(robot, offsets)
    if not moments:
        return ca.SX.zeros(3)
    placements = world_placements(joints, phi)
    potential = sum(-ca.dot(ca.DM(gravity), placements[j][0] @ ca.DM(h)) for j, h in moments.items())
    return ca.gradient(potential, q)


def holding_pwm(model: DrivenDynamics, q) -> np.ndarray:
    """PWM (3,) that holds the driven joints still at ``q`` (rad, rad, m): ``g(q) / k_u``."""
    return np.array(model.gravity(q)).ravel() / model.drive.input_gain


def check_state(x, u) -> tuple[np.ndarray, np.ndarray]:
    """``x`` (6,) and ``u`` (3,) as float arrays, or a clear error (PWM within the driver's range)."""
    x, u = np.asarray(x, dtype=float).ravel(), np.asarray(u, dtype=float).ravel()
    if x.size != 6 or u.size != 3:
        raise RcmKinError(f"the driven-joint state has 6 values (q, v of {', '.join(DRIVEN)}) and the input 3 "
                          f"PWM values, got {x.size} and {u.size}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(u))):
        raise RcmKinError("state and PWM must be finite numbers")
    if np.any(np.abs(u) > DRIVER_PWM_RANGE):
        raise RcmKinError(f"PWM beyond the 8-bit driver's range (|u| <= {DRIVER_PWM_RANGE:.0f} counts): {u.tolist()}")
    return x, u

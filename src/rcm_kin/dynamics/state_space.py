"""Forward dynamics of a robot's modelled joints: PWM input through the robot's drive, or joint
torque where it has none.

With a drive (the bundled PSM: roll, pitch, insertion) the state is ``x = [q; v]`` of the drive's
joints (rad or m, and their rates) and the input ``u`` the PWM counts of their drivers (hardware
sign, not saturated); the other joints are held at fixed values. Without a drive the model covers
the chosen joints (default all actuated) on the URDF inertias, with the joint torques (N m, N)
as input (``k_u = 1``, no drive terms). The model, on CasADi symbols:

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

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, model_label, resolve_drive
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import DRIVER_PWM_RANGE
from rcm_kin.model.gravity import offset_moments
from rcm_kin.model.masses import require_masses
from rcm_kin.model.reduced import relation_jacobian, tree_configuration
from rcm_kin.model.robot import check_robot, check_within_limits
from rcm_kin.symbolic.closed_chain import closed_chain_rnea, linear_closure
from rcm_kin.symbolic.tree import tree_joints, world_placements

if TYPE_CHECKING:
    from rcm_kin.model import Robot

PWM_UNIT = "PWM [counts]"           # DrivenDynamics.input_unit of a model with a drive
TORQUE_UNIT = "torque [N m / N]"    # ... of a torque-input model (N m revolute, N prismatic)


@dataclass(frozen=True)
class DriveConstants:
    """Per modelled joint, in the model's joint order (SI). A torque-input model has unit gains
    and no drive terms (zeros)."""

    input_gain: np.ndarray         # k_u: N m (N) per PWM count, hardware sign included; 1 for torque input
    damping: np.ndarray            # back-EMF + viscous: N m s/rad (N s/m)
    coulomb: np.ndarray            # N m (N)
    coulomb_velocity: np.ndarray   # rad/s (m/s)
    reflected_inertia: np.ndarray  # kg m^2 (kg)


def drive_constants(params: DriveParameters) -> DriveConstants:
    """The model constants of each driven joint of ``params`` (``params.driven`` order)."""
    d = [params[j] for j in params.driven]
    return DriveConstants(
        input_gain=np.array([1.0 / x.pwm_per_torque for x in d]),
        damping=np.array([x.torque_constant**2 * x.gear_ratio**2 / x.resistance + x.viscous for x in d]),
        coulomb=np.array([x.coulomb for x in d]),
        coulomb_velocity=np.array([x.coulomb_velocity for x in d]),
        reflected_inertia=np.array([x.reflected_inertia for x in d]))


def torque_constants(n: int) -> DriveConstants:
    """The constants of a torque-input model of ``n`` joints: ``u`` is the joint torque itself."""
    zero = np.zeros(n)
    return DriveConstants(np.ones(n), zero, zero, np.ones(n), zero)


@dataclass(frozen=True, eq=False)
class DrivenDynamics:
    """The model of a robot's modelled joints as CasADi functions (evaluate with NumPy arrays or
    symbols): PWM input where the robot has a drive, joint torque (N m, N) where it has none."""

    joints: tuple[str, ...]        # the modelled joints, e.g. ("roll", "pitch", "insertion")
    q_fixed: np.ndarray            # the robot's actuated q; modelled entries are overwritten
    lower: np.ndarray              # (n,) joint limits of the modelled joints (rad or m)
    upper: np.ndarray
    drive: DriveConstants
    coulomb: bool                  # whether the smoothed Coulomb term is in ``forward``
    forward: ca.Function           # (x, u) -> xdot
    jacobians: ca.Function         # (x, u) -> (A, B) = (d xdot/dx, d xdot/du), by AD
    mass_matrix: ca.Function       # q -> M + diag(N^2 J_rotor)   (kg m^2, kg)
    bias: ca.Function              # (q, v) -> c(q, v) + g(q)     (N m, N)
    gravity: ca.Function           # q -> g(q), offsets included  (N m, N)
    units: tuple[str, ...] = ()    # per joint "rad" or "m"
    input_unit: str = PWM_UNIT     # "PWM [counts]" or "torque [N m / N]" (TORQUE_UNIT)
    model_label: str = ""          # which model: "calibration <file>" or "CAD (URDF inertias)"
    robot: str = ""                # the robot's name
    rest: ca.Function | None = None   # q -> (g, M, dg/dq): what the model is linearised from at rest

    @property
    def state(self) -> list[str]:
        """State names: ``q_<joint>`` then ``v_<joint>``."""
        return [f"q_{j}" for j in self.joints] + [f"v_{j}" for j in self.joints]

    @property
    def inputs(self) -> list[str]:
        """Input names: ``pwm_<joint>`` (a drive) or ``tau_<joint>`` (torque input)."""
        prefix = "pwm" if self.input_unit == PWM_UNIT else "tau"
        return [f"{prefix}_{j}" for j in self.joints]

    @property
    def pwm_input(self) -> bool:
        """Whether the input is PWM counts through a drive (else joint torque)."""
        return self.input_unit == PWM_UNIT

    def input_label(self, k: int) -> str:
        """The input of joint ``k`` for people: ``roll PWM [counts]``, ``j2 torque [N m]``, ``d3 torque [N]``."""
        if self.pwm_input:
            return f"{self.joints[k]} PWM [counts]"
        return f"{self.joints[k]} torque [{'N' if self.units[k] == 'm' else 'N m'}]"


def modelled_joints(robot: Robot, params: DriveParameters | None, joints=None) -> tuple[str, ...]:
    """The joints a model of ``robot`` covers: the drive's (``params.driven``), else ``joints``
    (default all actuated), each an actuated joint of the robot, no repeats."""
    if params is not None:
        if joints is not None and tuple(joints) != params.driven:
            raise RcmKinError(f"the drive of {robot.name} ({params.source or 'in memory'}) models "
                              f"{', '.join(params.driven)}: `joints` must be those, or left out", parameter="joints")
        return params.driven
    joints = robot.actuated if joints is None else tuple(joints)
    if not joints or len(set(joints)) != len(joints) or any(j not in robot.actuated for j in joints):
        raise RcmKinError(f"`joints` must be distinct actuated joints of {robot.name} ({', '.join(robot.actuated)}), "
                          f"got {', '.join(map(str, joints)) or 'none'}", parameter="joints")
    return joints


def driven_dynamics(robot: Robot, params: DriveParameters | None = None, q_fixed=None, coulomb: bool = True, *,
                    joints=None) -> DrivenDynamics:
    """Build the CasADi model of ``robot``'s modelled joints.

    ``params`` None: the robot's own drive (:func:`~rcm_kin.dynamics.drive.robot_drive`). With a
    drive (checked against the robot: another robot's is a one-line error) the model has PWM input
    and covers ``params.driven``; without one it has torque input (N m, N) on the URDF inertias
    and covers ``joints`` (keyword only; default all actuated). ``q_fixed``: actuated configuration
    (robot order) giving the joints held still (default all zero); the positional order
    ``(robot, params, q_fixed, coulomb)`` is the one of before ``joints``. ``coulomb=False`` leaves the smoothed
    Coulomb friction out, e.g. for controller design (its slope at rest, ``F_c / v_c``, is a
    property of the smoothing only).
    """
    robot = check_robot(robot)
    params = resolve_drive(robot, params)
    joints = modelled_joints(robot, params, joints)
    require_masses(robot, "its dynamics")
    n = len(joints)
    q_fixed = robot.check_q(np.zeros(robot.nq) if q_fixed is None else q_fixed)
    index = [robot.actuated.index(j) for j in joints]
    drive = torque_constants(n) if params is None else drive_constants(params)
    coulomb = bool(coulomb) and params is not None
    terms = tuple(ca.DM(getattr(drive, name)) for name in TERM_NAMES)
    moments = {j: ca.DM(h) for j, h in offset_moments(robot, {} if params is None else params.gravity_offsets).items()}
    return DrivenDynamics(
        joints=joints, q_fixed=q_fixed, lower=robot.lower[index], upper=robot.upper[index], drive=drive,
        coulomb=coulomb, **model_functions(robot, joints, q_fixed, terms, moments, coulomb),
        units=tuple("m" if robot.joint_kind(j) == "prismatic" else "rad" for j in joints),
        input_unit=PWM_UNIT if params is not None else TORQUE_UNIT, model_label=model_label(params),
        robot=robot.name)


TERM_NAMES = tuple(f.name for f in fields(DriveConstants))   # the drive's constants, in their order


def model_functions(robot: Robot, joints: tuple[str, ...], q_fixed: np.ndarray, terms: tuple, moments: dict,
                    coulomb: bool, parameters: ca.SX | None = None) -> dict[str, ca.Function]:
    """The CasADi functions of :class:`DrivenDynamics` (``forward``, ``jacobians``, ``mass_matrix``,
    ``bias``, ``gravity``, ``rest``) of ``joints``, built once for numbers and for symbols: ``terms``
    the drive's constants in :data:`TERM_NAMES` order (n,) and ``moments`` the first-moment offsets
    ({joint index: (3,) kg m}, :func:`~rcm_kin.model.gravity.offset_moments`), each a ``DM`` of numbers
    or an ``SX`` expression of the symbol ``parameters``, which every function then takes as its
    last input ``p`` (:mod:`rcm_kin.dynamics.parametric`)."""
    gain, damping, coulomb_force, coulomb_velocity, reflected = terms
    n = len(joints)
    tree = tree_joints(robot.tree)
    gravity = np.array(robot.tree.gravity.linear)
    q, v, a, u = (ca.SX.sym(s, n) for s in ("q", "v", "a", "u"))
    phi = _driven_closure(robot, q_fixed, q, joints)

    rigid = closed_chain_rnea(tree, gravity, phi, q, v, a)
    zero = ca.DM.zeros(n)
    g_rigid = ca.substitute(rigid, ca.vertcat(v, a), ca.vertcat(zero, zero))
    g_offsets = _moment_gravity(tree, gravity, moments, phi, q)
    M = ca.jacobian(rigid, a) + ca.diag(reflected)
    bias = ca.substitute(rigid, a, zero) + g_offsets

    tau = gain * u - damping * v
    if coulomb:
        tau -= coulomb_force * ca.tanh(v / coulomb_velocity)
    x = ca.vertcat(q, v)
    xdot = ca.vertcat(v, ca.solve(M, tau - bias))
    p, p_names = ([], []) if parameters is None else ([parameters], ["p"])

    def function(name, inputs, outputs, names_in, names_out):
        return ca.Function(name, [*inputs, *p], outputs, [*names_in, *p_names], names_out)

    return dict(
        forward=function("forward", [x, u], [xdot], ["x", "u"], ["xdot"]),
        jacobians=function("jacobians", [x, u], [ca.jacobian(xdot, x), ca.jacobian(xdot, u)], ["x", "u"], ["A", "B"]),
        mass_matrix=function("mass_matrix", [q], [M], ["q"], ["M"]),
        bias=function("bias", [q, v], [bias], ["q", "v"], ["h"]),
        gravity=function("gravity", [q], [g_rigid + g_offsets], ["q"], ["g"]),
        rest=function("rest", [q], [g_rigid + g_offsets, ca.substitute(M, v, zero),
                                    ca.jacobian(g_rigid + g_offsets, q)], ["q"], ["g", "M", "dg"]))


def _driven_closure(robot: Robot, q_fixed: np.ndarray, q, joints: tuple[str, ...]) -> ca.SX:
    """Open-tree configuration of the modelled coordinates ``q``: ``S (E q + q_rest) + offsets``,
    the other actuated joints held at ``q_fixed``."""
    index = [robot.actuated.index(j) for j in joints]
    rest = q_fixed.copy()
    rest[index] = 0.0
    return linear_closure(relation_jacobian(robot)[:, index], tree_configuration(robot, rest), q)


def driven_gravity_function(robot: Robot, offsets: dict, q_fixed=None, joints=None) -> ca.Function:
    """``q -> g(q)`` (N m, N) of the modelled joints ``joints`` with the first-moment ``offsets``
    ({link: (3,) kg m}, e.g. ``DriveParameters.gravity_offsets``): the ``gravity`` of
    :func:`driven_dynamics` without building the rest of the model. ``joints``: the modelled
    joints (e.g. ``params.driven``), default all actuated, as :func:`driven_dynamics` without a drive."""
    joints = modelled_joints(robot, None, joints)
    q_fixed = robot.check_q(np.zeros(robot.nq) if q_fixed is None else q_fixed)
    tree = tree_joints(robot.tree)
    gravity = np.array(robot.tree.gravity.linear)
    q, zero = ca.SX.sym("q", len(joints)), ca.DM.zeros(len(joints))
    phi = _driven_closure(robot, q_fixed, q, joints)
    g = (closed_chain_rnea(tree, gravity, phi, q, zero, zero)
         + _offset_gravity(robot, tree, gravity, offsets, phi, q))
    return ca.Function("driven_gravity", [q], [g], ["q"], ["g"])


def _offset_gravity(robot: Robot, joints, gravity, offsets: dict, phi, q) -> ca.SX:
    """Generalised gravity of the calibrated first moments (mass-free, kg m in link frames):
    :func:`_moment_gravity` of their moments in the joints' frames."""
    return _moment_gravity(joints, gravity, {j: ca.DM(h) for j, h in offset_moments(robot, offsets).items()}, phi, q)


def _moment_gravity(joints, gravity, moments: dict, phi, q) -> ca.SX:
    """Generalised gravity of first moments ``moments`` ({joint index: (3,) kg m in its frame}, numbers
    or symbols): the gradient of their potential ``-g . (R_j h_j)``."""
    if not moments:
        return ca.SX.zeros(q.shape[0])
    placements = world_placements(joints, phi)
    potential = sum(-ca.dot(ca.DM(gravity), placements[j][0] @ h) for j, h in moments.items())
    return ca.gradient(potential, q)


def holding_pwm(model: DrivenDynamics, q, *, allow_outside_limits: bool = False) -> np.ndarray:
    """Input (n,) that holds the modelled joints still at ``q`` (rad, m): ``g(q) / k_u``; PWM
    counts through a drive, the torque itself (N m, N) for a torque-input model.
    ``allow_outside_limits``: evaluate a pose outside the joint limits (refused by default)."""
    q = check_pose(model, q, allow_outside_limits=allow_outside_limits)
    return np.array(model.gravity(q)).ravel() / model.drive.input_gain


def check_model(model, parameter: str = "model") -> DrivenDynamics:
    """``model`` itself when it is a :class:`DrivenDynamics`, else an RcmKinError naming ``parameter``."""
    if not isinstance(model, DrivenDynamics):
        raise RcmKinError(f"`{parameter}` must be a driven-joint model (rk.driven_dynamics(robot)), got "
                          f"{type(model).__name__}", parameter=parameter)
    return model


def check_pose(model: DrivenDynamics, q, *, allow_outside_limits: bool = False, parameter: str = "q") -> np.ndarray:
    """``q`` as the modelled joints' pose (n,) (rad, m): numbers, finite, of the model's size and
    within its joints' limits unless ``allow_outside_limits``; else an RcmKinError naming
    ``parameter`` (a :class:`~rcm_kin.errors.JointLimitError` for the limits), as
    :meth:`Robot.check_pose` for a robot's pose."""
    n = len(check_model(model).joints)
    try:
        q = np.asarray(q, dtype=float).ravel()
    except (TypeError, ValueError):
        raise RcmKinError(f"a pose is {n} numbers ({', '.join(model.joints)}), got {str(q)[:60]!r}",
                          parameter=parameter) from None
    if q.shape != (n,) or not np.all(np.isfinite(q)):
        raise RcmKinError(f"a pose is {n} finite numbers ({', '.join(model.joints)}), got {q.tolist()[:8]}",
                          parameter=parameter)
    if allow_outside_limits:
        return q
    return check_within_limits(q, model.joints, model.lower, model.upper, lambda i: model.units[i] == "rad",
                               parameter=parameter)


def check_state(x, u, model: DrivenDynamics | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``x`` (2n,) and ``u`` (n,) as float arrays, or a clear error (PWM within the driver's
    range). ``model`` None: the PSM's three driven joints with PWM input."""
    joints = model.joints if model is not None else DRIVEN
    pwm = model is None or model.pwm_input
    n = len(joints)
    x, u = np.asarray(x, dtype=float).ravel(), np.asarray(u, dtype=float).ravel()
    if x.size != 2 * n or u.size != n:
        what = "PWM" if pwm else "torque"
        raise RcmKinError(f"the driven-joint state has {2 * n} values (q, v of {', '.join(joints)}) and the input "
                          f"{n} {what} values, got {x.size} and {u.size}")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(u))):
        raise RcmKinError(f"state and {'PWM' if pwm else 'torque'} must be finite numbers")
    if pwm and np.any(np.abs(u) > DRIVER_PWM_RANGE):
        raise RcmKinError(f"PWM beyond the 8-bit driver's range (|u| <= {DRIVER_PWM_RANGE:.0f} counts): {u.tolist()}")
    return x, u

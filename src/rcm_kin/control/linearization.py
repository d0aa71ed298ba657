"""Linear models of a robot's modelled joints at equilibria: ``dx = A dx + B du`` about ``(x0, u0)``.

``x0 = [q; 0]`` is a pose held still and ``u0`` the input that holds it (gravity over the drive
gain: PWM counts where the robot has a drive, the joint torques where it has none), so
``forward(x0, u0) = 0``. ``A = d xdot / dx`` and ``B = d xdot / du`` come from CasADi's
automatic differentiation of :mod:`rcm_kin.dynamics.state_space`; :func:`linearize_pinocchio`
gets the same matrices from Pinocchio's analytic ABA derivatives of the open tree projected
through the loop closure, and :func:`linearize_finite_differences` by central differences, as
independent checks. State ``[q; v]`` in SI (rad, m, rad/s, m/s), input PWM counts or N m / N,
output ``q``.
:meth:`Linearization.to_ss` hands a model to python-control; :func:`zero_order_hold` samples
one with the input held.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np
import pinocchio as pin

from rcm_kin.dynamics.state_space import PWM_UNIT, DrivenDynamics, check_pose, holding_pwm
from rcm_kin.errors import RcmKinError
from rcm_kin.model.gravity import offset_moments
from rcm_kin.model.reduced import relation_jacobian, tree_configuration
from rcm_kin.symbolic.compiled import compiled, map_points, map_points_into
from rcm_kin.symbolic.linalg import spd_inverse
from rcm_kin.symbolic.points import CompiledPoints, compiled_points

if TYPE_CHECKING:
    import control

    from rcm_kin.model import Robot


@dataclass(frozen=True)
class Linearization:
    """A linear model about an equilibrium (SI state; PWM or torque input) of n modelled joints."""

    x0: np.ndarray     # (2n,) [q; v], v = 0
    u0: np.ndarray     # (n,) holding input (PWM counts, or N m / N)
    A: np.ndarray      # (2n, 2n)
    B: np.ndarray      # (2n, n)
    C: np.ndarray      # (n, 2n): the joint positions
    D: np.ndarray      # (n, n)
    state: list[str]
    inputs: list[str]
    joints: tuple[str, ...] = ("roll", "pitch", "insertion")
    units: tuple[str, ...] = ("rad", "rad", "m")          # per joint position
    input_labels: tuple[str, ...] = ("roll PWM [counts]", "pitch PWM [counts]", "insertion PWM [counts]")
    input_unit: str = PWM_UNIT
    model: str = ""                                        # which model: calibration <file> or CAD

    def as_dict(self) -> dict:
        """The model as JSON-ready lists (keys x0, u0, A, B, C, D, state, input)."""
        return {"x0": self.x0.tolist(), "u0": self.u0.tolist(), "A": self.A.tolist(), "B": self.B.tolist(),
                "C": self.C.tolist(), "D": self.D.tolist(), "state": self.state, "input": self.inputs}

    def to_ss(self) -> control.StateSpace:
        """The model as a python-control ``StateSpace`` in the deviations from ``(x0, u0)``, with
        labelled signals: states ``roll [rad]`` .. ``insertion rate [m/s]``, inputs
        ``roll PWM [counts]`` .. (a drive) or ``j2 torque [N m]`` .. (torque input), outputs the
        joint positions ``roll [rad]`` .. ``insertion [m]``."""
        import control  # python-control costs ~120 MB and a second to import: only when asked for

        positions = [f"{j} [{u}]" for j, u in zip(self.joints, self.units)]
        rates = [f"{j} rate [{u}/s]" for j, u in zip(self.joints, self.units)]
        return control.ss(self.A, self.B, self.C, self.D, states=positions + rates,
                          inputs=list(self.input_labels), outputs=positions)


def zero_order_hold(A: np.ndarray, B: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """``(Ad, Bd)`` of ``x[k+1] = Ad x[k] + Bd u[k]``: the exact sampling of ``xdot = A x + B u``
    with ``u`` held over each ``period`` (s), ``expm([[A, B], [0, 0]] period)`` (what scipy's
    ``cont2discrete(..., method="zoh")`` and python-control's ``c2d`` compute, without their
    per-call set-up: this runs in the identification's and the stability survey's inner loops)."""
    n, m = B.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = A, B
    from scipy.linalg import (
        expm,  # SciPy is imported by the designs that discretise, not by the CLI
    )

    E = expm(block * period)
    return E[:n, :n], E[:n, n:]


def equilibrium(model: DrivenDynamics, q) -> tuple[np.ndarray, np.ndarray]:
    """``(x0, u0)``: the pose ``q`` (rad, m; the model's joints) at rest and its holding input."""
    q = check_pose(model, q)
    return np.r_[q, np.zeros(len(model.joints))], holding_pwm(model, q)


def check_in_range(model: DrivenDynamics, Q: np.ndarray, tol: float = 1e-9) -> None:
    """Refuse poses (N, n) or (n,) outside the modelled joints' limits (the model means nothing
    there): the first such pose, as :func:`~rcm_kin.dynamics.state_space.check_pose` refuses it."""
    Q = np.atleast_2d(Q)
    outside = np.flatnonzero(np.any((Q < model.lower - tol) | (Q > model.upper + tol), axis=1))
    if outside.size:
        check_pose(model, Q[outside[0]], parameter="Q")


def linearize(model: DrivenDynamics, q) -> Linearization:
    """The linear model at pose ``q`` (rad, m; the model's joints), by CasADi AD."""
    x0, u0 = equilibrium(model, q)
    A, B = (np.array(m) for m in model.jacobians(x0, u0))
    n = len(model.joints)
    C = np.hstack([np.eye(n), np.zeros((n, n))])
    return Linearization(x0, u0, A, B, C, np.zeros((n, n)), model.state, model.inputs, tuple(model.joints),
                         tuple(model.units), tuple(model.input_label(k) for k in range(n)), model.input_unit,
                         model.model_label)


@dataclass(frozen=True)
class LinearizationGrid:
    """Linear models over N poses of n modelled joints."""

    q: np.ndarray    # (N, n) poses (rad, m)
    u0: np.ndarray   # (N, n) holding input (PWM counts, or N m / N)
    A: np.ndarray    # (N, 2n, 2n)
    B: np.ndarray    # (N, 2n, n)


def linearize_grid(model: DrivenDynamics, Q, chunk: int = 4096, compile: bool = True,
                   method: str | None = None) -> LinearizationGrid:
    """Linear models at (N, n) poses: the compiled gravity and Jacobians
    (:mod:`rcm_kin.symbolic.compiled`) mapped over chunks of ``chunk`` poses. ``compile=False``
    maps the interpreted functions (the same values to rounding, about 45 us a pose against 5):
    for a model used once on a few poses, whose compilation would cost seconds.

    ``method``: ``"ad"``, CasADi's Jacobians of ``forward`` at ``(x0, u0)``; ``"rest"``, the
    closed form at an equilibrium, ``A = [[0, I], [-M^-1 dg/dq, -M^-1 D]]``, ``B = [0; M^-1 K]``
    (``D`` the drive's damping and Coulomb slope at rest, ``K`` its gains; exact at rest, where
    the applied input cancels gravity and the Coriolis terms are quadratic in ``v``):
    :func:`rest_linearization`, ``M^-1`` by its Cholesky factor, compiled and run over the poses in
    one C loop into the result arrays (about 1 us a pose for 7 joints; ``chunk`` matters only
    interpreted): cheaper for many joints. Default: ``"ad"`` for a model with a drive (the PSM's
    tables, bit for bit as before), ``"rest"`` for a torque-input model."""
    n = len(model.joints)
    try:
        Q = np.ascontiguousarray(np.atleast_2d(np.asarray(Q, dtype=float)))
    except (TypeError, ValueError):
        raise RcmKinError(f"`Q` must be rows of {n} numbers ({', '.join(model.joints)})", parameter="Q") from None
    if Q.ndim != 2 or Q.shape[1] != n or Q.shape[0] == 0 or not np.all(np.isfinite(Q)):
        raise RcmKinError(f"poses must be at least one finite row of {n} values ({', '.join(model.joints)}), "
                          f"got shape {Q.shape}",
                          parameter="Q")
    if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise RcmKinError(f"`chunk` is a whole number of poses, at least 1, got {chunk!r}", parameter="chunk")
    method = method or ("ad" if model.pwm_input else "rest")
    if method not in ("ad", "rest"):
        raise RcmKinError(f"`method` is 'ad' or 'rest', got {method!r}", parameter="method")
    check_in_range(model, Q)
    if method == "rest":
        return _rest_grid(model, Q, chunk, compile)
    gravity, jacobians = _compiled(model) if compile else (model.gravity, model.jacobians)
    (g,) = map_points(gravity, Q, chunk=chunk)
    u0 = g / model.drive.input_gain
    A, B = map_points(jacobians, np.hstack([Q, np.zeros_like(Q)]), u0, chunk=chunk)
    return LinearizationGrid(Q, u0, A, B)


def _rest_grid(model: DrivenDynamics, Q: np.ndarray, chunk: int, compile: bool) -> LinearizationGrid:
    """:func:`linearize_grid` by the closed form at rest: :func:`rest_linearization` at every pose,
    written into the result arrays (one C loop where compiled,
    :func:`~rcm_kin.symbolic.points.compiled_points`; CasADi maps of ``chunk`` poses where not)."""
    n, N = len(model.joints), len(Q)
    u0, A, B = np.empty((N, n)), np.empty((N, 2 * n, 2 * n)), np.empty((N, 2 * n, n))
    outs = [u0, A.reshape(N, -1), B.reshape(N, -1)]           # row-major A, B = column-major A^T, B^T
    if compile:
        _compiled_rest(model)([Q], outs)
    else:
        map_points_into(rest_linearization(model), [Q], outs, chunk=chunk)
    if not np.isfinite(B.sum()):                              # M^-1 in B: NaN or inf where M is not definite
        bad = int(np.argmin(np.isfinite(B).all(axis=(1, 2))))
        raise RcmKinError(f"the mass matrix is not positive definite at pose {bad} "
                          f"({', '.join(model.joints)} = {np.array2string(Q[bad], precision=4)})")
    return LinearizationGrid(Q, u0, A, B)


@functools.lru_cache(maxsize=8)
def rest_linearization(model: DrivenDynamics) -> ca.Function:
    """``q -> (u0, A^T, B^T)``: the holding input and the closed form at rest of
    :func:`linearize_grid` (``method="rest"``) as one CasADi function of the pose (dense outputs,
    transposed so that their column-major nonzeros are ``A`` and ``B`` row by row).
    ``A = [[0, I], [-M^-1 dg/dq, -M^-1 D]]``, ``B = [0; M^-1 K]`` from ``model.rest``, ``M^-1`` by
    its Cholesky factor (:func:`~rcm_kin.symbolic.linalg.spd_inverse`), ``D`` the drive's damping
    and Coulomb slope at rest, ``K`` its gains."""
    n, drive = len(model.joints), model.drive
    q = ca.SX.sym("q", n)
    g, M, dg = model.rest(q)
    Minv = spd_inverse(M)
    damping = drive.damping + (drive.coulomb / drive.coulomb_velocity if model.coulomb else 0.0)
    zero, eye = ca.SX(n, n), ca.SX.eye(n)
    A = ca.vertcat(ca.horzcat(zero, eye), ca.horzcat(-ca.mtimes(Minv, dg), -ca.mtimes(Minv, ca.diag(damping))))
    B = ca.vertcat(zero, ca.mtimes(Minv, ca.diag(drive.input_gain)))
    return ca.Function("rest_linearization", [q], [g / ca.DM(drive.input_gain), ca.densify(A.T), ca.densify(B.T)],
                       ["q"], ["u0", "At", "Bt"])


@functools.lru_cache(maxsize=8)
def _compiled(model: DrivenDynamics) -> tuple[ca.Function, ca.Function]:
    """Holding gravity and (A, B), compiled (built once, then loaded from the cache)."""
    return compiled(model.gravity), compiled(model.jacobians)


@functools.lru_cache(maxsize=8)
def _compiled_rest(model: DrivenDynamics) -> CompiledPoints:
    """:func:`rest_linearization` compiled (built once, then loaded from the cache), at many poses in one C loop."""
    return compiled_points(rest_linearization(model))


def linearize_finite_differences(model: DrivenDynamics, x, u, step: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` by central differences of ``forward`` (truncation error ~ step^2)."""
    x, u = np.asarray(x, float), np.asarray(u, float)

    def f(xx, uu):
        return np.array(model.forward(xx, uu)).ravel()

    A = np.column_stack([(f(x + step * e, u) - f(x - step * e, u)) / (2 * step) for e in np.eye(x.size)])
    B = np.column_stack([(f(x, u + e) - f(x, u - e)) / 2 for e in np.eye(u.size)])   # exactly linear in u
    return A, B


def linearize_pinocchio(robot: Robot, model: DrivenDynamics, offsets: dict, x, u) -> tuple[np.ndarray, np.ndarray]:
    """``(A, B)`` from Pinocchio's analytic derivatives, independent of the CasADi transcription.

    The rigid-body part is ``computeABADerivatives`` on the open tree (reflected rotor inertia as
    the tree's armature), turned into inverse-dynamics derivatives ``d tau / dq = -M d a / dq``
    and projected through the closure ``q_tree = S q + offsets`` (``S^T (.) S``). The
    calibrated first moments ``h`` add ``g_h(q) = g_1(h) - g_1(0)``, the gravity of a unit mass
    at ``h`` minus one at the link origin, differentiated by ``computeGeneralizedGravityDerivatives``.
    The drive terms are differentiated by hand.
    """
    x, u = np.asarray(x, float), np.asarray(u, float)
    n = len(model.joints)
    q, v = x[:n], x[n:]
    tree, S = _armatured_tree(robot, model), relation_jacobian(robot)
    index = [robot.actuated.index(j) for j in model.joints]
    data = tree.createData()
    q_act = model.q_fixed.copy()
    q_act[index] = q
    Sd = S[:, index]
    q_tree, v_tree = tree_configuration(robot, q_act), Sd @ v

    drive = model.drive
    coulomb_slope = np.zeros(n)
    tau_drive = drive.input_gain * u - drive.damping * v
    if model.coulomb:
        smooth = np.tanh(v / drive.coulomb_velocity)
        tau_drive -= drive.coulomb * smooth
        coulomb_slope = drive.coulomb / drive.coulomb_velocity * (1 - smooth**2)

    M = Sd.T @ _symmetric(pin.crba(tree, data, q_tree)) @ Sd
    g_offsets, dg_offsets = _offset_gravity(robot, offsets, q_tree)
    h = Sd.T @ pin.rnea(tree, data, q_tree, v_tree, np.zeros(tree.nv)) + Sd.T @ g_offsets
    a = np.linalg.solve(M, tau_drive - h)
    tau_tree = pin.rnea(tree, data, q_tree, v_tree, Sd @ a)
    da_dq, da_dv, _ = pin.computeABADerivatives(tree, data, q_tree, v_tree, tau_tree)
    M_tree = _symmetric(data.M)
    dtau_dq = Sd.T @ (-M_tree @ da_dq) @ Sd + Sd.T @ dg_offsets @ Sd
    dtau_dv = Sd.T @ (-M_tree @ da_dv) @ Sd
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-Minv @ dtau_dq, -Minv @ (dtau_dv + np.diag(drive.damping + coulomb_slope))]])
    B = np.vstack([np.zeros((n, n)), Minv @ np.diag(drive.input_gain)])
    return A, B


def _symmetric(M: np.ndarray) -> np.ndarray:
    return np.triu(M) + np.triu(M, 1).T


@functools.lru_cache(maxsize=8)
def _armatured_tree(robot: Robot, model: DrivenDynamics) -> pin.Model:
    tree = pin.Model(robot.tree)
    for joint, inertia in zip(model.joints, model.drive.reflected_inertia):
        tree.armature[tree.joints[tree.getJointId(joint)].idx_v] += inertia
    return tree


def _offset_gravity(robot: Robot, offsets: dict, q_tree: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Generalised gravity (tree nv) of mass-free first moments and its q-derivative."""
    g, dg = np.zeros(robot.tree.nv), np.zeros((robot.tree.nv, robot.tree.nv))
    for joint, h in offset_moments(robot, offsets).items():
        for lever, sign in ((h, 1.0), (np.zeros(3), -1.0)):
            unit = _unit_mass_tree(robot, joint, tuple(lever))
            data = unit.createData()
            g += sign * pin.computeGeneralizedGravity(unit, data, q_tree)
            dg += sign * pin.computeGeneralizedGravityDerivatives(unit, data, q_tree)
    return g, dg


@functools.lru_cache(maxsize=32)
def _unit_mass_tree(robot: Robot, joint: int, lever: tuple) -> pin.Model:
    """The open tree with every body massless except 1 kg at ``lever`` (joint frame) on ``joint``."""
    model = pin.Model(robot.tree)
    for j in range(1, model.njoints):
        model.inertias[j] = pin.Inertia.Zero()
    model.inertias[joint] = pin.Inertia(1.0, np.array(lever), np.zeros((3, 3)))
    return model

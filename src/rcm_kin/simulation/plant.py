"""The plant over one controller period, with the PWM held (zero-order hold).

Two plants: the smooth model (:func:`period_map`, :class:`SmoothPlant`), and the identified drive
trains with friction that sticks (:class:`DriveTrainPlant`, time-stepped as
:mod:`rcm_kin.dynamics.stick_slip`). Both are :class:`Plant` s, and so is their kernel form, the
:class:`~rcm_kin.simulation.compiled_plant.CompiledPlant` that ``kernel_plant()`` gives.

Smooth model: classical RK4 (:func:`rcm_kin.symbolic.integrators.rk4_map`) with ``substeps``
equal steps per period ``T`` and the PWM held. The stiffest term of the driven joints is the
smoothed Coulomb friction at rest; at 400 Hz and 4 substeps its ``|lambda| h`` stays inside RK4's
stability region, and ``tests/simulation/test_simulation.py`` holds one period to an adaptive
solver (DOP853) (the figures: docs/findings.md, "The smooth plant's integrator").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import casadi as ca
import numpy as np

from rcm_kin import dynamics
from rcm_kin.dynamics.axis_friction import MAX_ELEMENTS, STATE_SIZE, AxisFriction
from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, JointDrive, with_joint
from rcm_kin.dynamics.state_space import DrivenDynamics, driven_dynamics
from rcm_kin.errors import RcmKinError
from rcm_kin.simulation.compiled_plant import CompiledPlant, compiled_drive_train, compiled_smooth
from rcm_kin.symbolic.integrators import rk4_map

if TYPE_CHECKING:
    from rcm_kin.model import Robot


@runtime_checkable
class Plant(Protocol):
    """What the closed loop drives: ``initial(position) -> x``, the state at rest at ``position``
    (rad, rad, m), and ``step(x, u) -> x``, one controller period under the PWM ``u`` (3,) counts
    held; ``x[:3]`` is what the encoders see (SI).

    Optional: ``kernel_plant() -> CompiledPlant | None``, the plant as the compiled kernel takes it
    (:mod:`rcm_kin.simulation.compiled_plant`); None, or no such method: the loop runs in Python."""

    def initial(self, position) -> np.ndarray:
        ...

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        ...


def period_map(forward: ca.Function, period: float, substeps: int = 4) -> ca.Function:
    """``(x, u) -> x(T)``: ``forward(x, u) -> xdot`` (``x = [q; v]`` SI, ``u`` PWM counts)
    integrated over one period ``T`` (s) by ``substeps`` RK4 steps with ``u`` constant. Returns a
    CasADi Function (NumPy in, DM out)."""
    if not (period > 0 and substeps >= 1):
        raise RcmKinError(f"the period must be positive and substeps >= 1, got {period} s and {substeps}")
    return rk4_map(forward, period, substeps, "period_map")


@dataclass(frozen=True)
class DriveTrainPlant:
    """The driven joints with the identified stick-slip drive trains
    (:mod:`rcm_kin.dynamics.stick_slip`), one controller period per :meth:`step`.

    State ``x`` (3 STATE_SIZE,): rows ``[theta, w, q, v, z_1 .. z_MAX_ELEMENTS]`` of (roll, pitch,
    insertion) flattened (:data:`~rcm_kin.dynamics.stick_slip.STATE_SIZE` rows), so ``x[:3]`` is
    what the encoders see (the motor angle over the ratio, SI) and ``x[3:6]`` its rate; ``q, v``
    are the link's, ``z_i`` the presliding elements' anchors. Each period the rigid-body mass
    matrix and bias forces (gravity, Coriolis) are evaluated at the period's start and held; the
    axes are coupled through them, not through the off-diagonal inertia within a period (which
    the drive inertia and friction dominate over 2.5 ms).

    :meth:`step` advances the axes with the model's numba kernel
    (:func:`rcm_kin.dynamics.stick_slip.advance_axis`), loaded on the first step (the package's lazy
    ``dynamics.stick_slip``): the compiled loop, which runs this plant's kernel form
    (:meth:`kernel_plant`, the C twin of that kernel), never loads numba."""

    model: DrivenDynamics                 # rigid body + drive, without identified extras
    friction: np.ndarray                  # (3, n) AxisFriction vectors, DRIVEN order
    period: float                         # s

    def initial(self, position) -> np.ndarray:
        """At rest at ``position`` (rad, rad, m) with relaxed springs."""
        q = np.asarray(position, dtype=float)
        return np.concatenate([q, np.zeros(3), q, np.zeros(3)] + [q] * MAX_ELEMENTS)

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        state = np.array(x, dtype=float).reshape(STATE_SIZE, 3)
        q, v = state[2], state[3]
        M = np.array(self.model.mass_matrix(q))
        bias = np.array(self.model.bias(q, v)).ravel()
        d, advance_axis = self.model.drive, dynamics.stick_slip.advance_axis     # the numba model, loaded here
        for i in range(3):
            axis = np.ascontiguousarray(state[:, i])
            advance_axis(self.friction[i], d.input_gain[i], d.damping[i], d.reflected_inertia[i], bias[i],
                         M[i, i] - d.reflected_inertia[i], float(u[i]), axis, self.period)
            state[:, i] = axis
        return state.ravel()

    def kernel_plant(self) -> CompiledPlant | None:
        """This plant with its mass matrix and bias compiled to C; None without a C compiler."""
        return compiled_drive_train(self)


@dataclass(frozen=True)
class SmoothPlant:
    """The smooth model's period map as a :class:`Plant`: ``x = [q; v]`` (6,). ``period_map`` is
    the CasADi ``(x, u) -> x(T)`` of :func:`period_map` (with its ``period`` given, the plant has a
    kernel form), or any function of NumPy arrays (run in Python only)."""

    period_map: Callable[[np.ndarray, np.ndarray], np.ndarray]
    period: float | None = None         # s

    def initial(self, position) -> np.ndarray:
        return np.r_[np.asarray(position, dtype=float), np.zeros(3)]

    def step(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        return np.array(self.period_map(x, u)).ravel()

    def kernel_plant(self) -> CompiledPlant | None:
        """The CasADi period map compiled to C; None without a C compiler or for a Python function."""
        if self.period is None or not isinstance(self.period_map, ca.Function):
            return None
        return compiled_smooth(self.period_map, self.period)


def smooth_friction(drive: JointDrive) -> AxisFriction:
    """A joint without an identified drive train: its smooth-model constants (extra inertia,
    viscous, Coulomb friction) with the Coulomb law as a sticking one."""
    return AxisFriction(extra_inertia=drive.extra_inertia, viscous=drive.viscous, coulomb=drive.coulomb)


def drive_train_plant(robot: Robot, params: DriveParameters, period: float) -> DriveTrainPlant:
    """The PSM plant with ``params``' identified drive trains; a joint without one keeps its
    smooth-model constants (:func:`smooth_friction`)."""
    return DriveTrainPlant(driven_dynamics(robot, rigid_body_drive(params), coulomb=False),
                           drive_train_friction(params), period)


def rigid_body_drive(params: DriveParameters) -> DriveParameters:
    """``params`` as a drive-train plant's rigid-body model takes them: each driven joint's smooth
    friction and extra inertia zeroed (its drive train, :func:`drive_train_friction`, has them)."""
    for joint in DRIVEN:
        params = with_joint(params, joint, extra_inertia=0.0, viscous=0.0, coulomb=0.0)
    return params


def drive_train_friction(params: DriveParameters) -> np.ndarray:
    """(3, n): the AxisFriction vector of each driven joint (DRIVEN order): its identified drive
    train, else its smooth-model constants (:func:`smooth_friction`)."""
    return np.stack([params.drive_train.get(j, smooth_friction(params[j])).vector() for j in DRIVEN])

"""One model for many parameter sets: the drive's constants and the first-moment offsets as inputs.

:func:`driven_dynamics` bakes a parameter set's numbers into its CasADi functions, so compiled
code is generated per set. A :class:`ParametricDynamics` is the same model with those numbers as a
last input ``p`` of every function (``mass_matrix(q, p)``, ``bias(q, v, p)``, ``forward(x, u, p)``,
...): built and compiled once, it serves every set of the same structure (the same robot, modelled
joints, held joints and links with offsets), as a robustness run's drawn sets are. ``values(params)``
is a set's ``p``; ``bind(params)`` the :class:`DrivenDynamics` of one set, whose functions call the
parametric ones with its ``p`` (no code generated). Both models come from one builder
(:func:`~rcm_kin.dynamics.state_space.model_functions`), so ``bind(params)`` evaluates the expression
graph of ``driven_dynamics(robot, params)`` operation for operation (tests/dynamics/test_parametric.py).

``p`` holds, in order: the drive's constants (:data:`~rcm_kin.dynamics.state_space.TERM_NAMES`, n
each: input gain, damping, Coulomb force and velocity, reflected inertia), then the first moment
(3, kg m) of each joint with offsets, in the joint frame (:func:`~rcm_kin.model.gravity.offset_moments`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from rcm_kin.dynamics.drive import DriveParameters, model_label, resolve_drive
from rcm_kin.dynamics.state_space import (
    TERM_NAMES,
    DrivenDynamics,
    drive_constants,
    driven_dynamics,
    model_functions,
)
from rcm_kin.errors import RcmKinError
from rcm_kin.model.gravity import offset_moments
from rcm_kin.model.robot import check_robot
from rcm_kin.symbolic.compiled import compiled

if TYPE_CHECKING:
    from rcm_kin.model import Robot

FUNCTIONS = ("forward", "jacobians", "mass_matrix", "bias", "gravity", "rest")   # DrivenDynamics' functions


@dataclass(frozen=True, eq=False)
class ParametricDynamics:
    """:class:`DrivenDynamics`' functions of one structure with the parameter vector ``p`` as their
    last input; ``template`` the model of the set it was built from (joints, limits, units)."""

    template: DrivenDynamics
    moment_joints: tuple[int, ...]     # joint indices whose first moments are in p, in order
    forward: ca.Function               # (x, u, p) -> xdot
    jacobians: ca.Function             # (x, u, p) -> (A, B)
    mass_matrix: ca.Function           # (q, p) -> M
    bias: ca.Function                  # (q, v, p) -> h
    gravity: ca.Function               # (q, p) -> g
    rest: ca.Function                  # (q, p) -> (g, M, dg/dq)
    robot: Robot

    @property
    def size(self) -> int:
        """The length of ``p``."""
        return self.forward.size_in(2)[0]

    def values(self, params: DriveParameters) -> np.ndarray:
        """``p`` of ``params`` (a drive of the same joints, offsets on links of the joints in
        :attr:`moment_joints`); an RcmKinError naming ``params`` for one of another structure."""
        if not isinstance(params, DriveParameters) or params.driven != self.template.joints:
            raise RcmKinError(f"`params` must be drive parameters of {', '.join(self.template.joints)}, the joints "
                              "this parametric model was built for", parameter="params")
        drive = drive_constants(params)
        moments = offset_moments(self.robot, params.gravity_offsets)
        if stray := sorted(set(moments) - set(self.moment_joints)):
            names = ", ".join(self.robot.tree.names[j] for j in stray)
            raise RcmKinError(f"`params` has first-moment offsets on links of {names}, which the parametric model "
                              "was built without: build it from a set with offsets there", parameter="params")
        first = np.zeros((len(self.moment_joints), 3))
        for k, j in enumerate(self.moment_joints):
            first[k] = moments.get(j, 0.0)
        return np.concatenate([*(np.asarray(getattr(drive, name), dtype=float) for name in TERM_NAMES), first.ravel()])

    def bind(self, params: DriveParameters) -> DrivenDynamics:
        """The :class:`DrivenDynamics` of ``params``: each function the parametric one called with
        ``values(params)`` (CasADi MX functions of the model's own inputs)."""
        p = ca.DM(self.values(params))
        bound = {name: _fixed(getattr(self, name), p) for name in FUNCTIONS}
        return replace(self.template, drive=drive_constants(params), model_label=model_label(params), **bound)

    def compiled(self, *names: str) -> ParametricDynamics:
        """This model with the functions ``names`` (default all of :data:`FUNCTIONS`) compiled to C
        (:func:`~rcm_kin.symbolic.compiled.compiled`: built once, then loaded from the cache;
        interpreted without a C compiler)."""
        if unknown := [n for n in names if n not in FUNCTIONS]:
            raise RcmKinError(f"`names` are of {', '.join(FUNCTIONS)}, got {', '.join(map(str, unknown))}",
                              parameter="names")
        return replace(self, **{name: compiled(getattr(self, name)) for name in names or FUNCTIONS})


def parametric_dynamics(robot: Robot, params: DriveParameters | None = None, q_fixed=None,
                        coulomb: bool = True) -> ParametricDynamics:
    """The model of ``robot``'s driven joints as :func:`driven_dynamics` with ``params`` (default the
    robot's own drive; a drive is required), its drive constants and the first moments of the joints
    with offsets in ``params`` as the last input ``p`` of every function."""
    robot = check_robot(robot)
    params = resolve_drive(robot, params)
    if params is None:
        raise RcmKinError(f"a parametric model is of a robot's drive, and {robot.name} has none: give `params`",
                          parameter="params")
    template = driven_dynamics(robot, params, q_fixed, coulomb)
    n = len(template.joints)
    moment_joints = tuple(sorted(offset_moments(robot, params.gravity_offsets)))
    p = ca.SX.sym("p", len(TERM_NAMES) * n + 3 * len(moment_joints))
    terms = tuple(p[k * n:(k + 1) * n] for k in range(len(TERM_NAMES)))
    base = len(TERM_NAMES) * n
    moments = {j: p[base + 3 * k:base + 3 * k + 3] for k, j in enumerate(moment_joints)}
    functions = model_functions(robot, template.joints, template.q_fixed, terms, moments, template.coulomb, p)
    return ParametricDynamics(template, moment_joints, robot=robot, **functions)


def structure_key(robot: Robot, params: DriveParameters) -> tuple:
    """What a parametric model built from ``params`` is shaped by, as a key: the robot (the object
    loaded now), the driven joints and the links with first-moment offsets. Sets with the same key
    share one model (:meth:`ParametricDynamics.values` takes any of them)."""
    if not isinstance(params, DriveParameters):
        raise RcmKinError(f"`params` must be drive parameters (load_drive_parameters), got {type(params).__name__}",
                          parameter="params")
    return check_robot(robot), params.driven, tuple(sorted(params.gravity_offsets))


_SHARED: dict[tuple, ParametricDynamics] = {}     # (structure_key, coulomb, names compiled) -> model


def shared_model(robot: Robot, params: DriveParameters, coulomb: bool = True,
                 compile_names: tuple[str, ...] = ()) -> ParametricDynamics:
    """:func:`parametric_dynamics` of ``params``' structure (:func:`structure_key`) with the
    functions ``compile_names`` compiled, built once per process and structure: a robustness run's
    samples (their plant family and their margins' model), a tuning run's draws. A compiled
    variant is the model of ``compile_names=()`` with those functions compiled, never a second build."""
    base = (structure_key(robot, params), bool(coulomb))
    if base + ((),) not in _SHARED:
        _SHARED[base + ((),)] = parametric_dynamics(robot, params, coulomb=coulomb)
    key = base + (tuple(compile_names),)
    if key not in _SHARED:
        _SHARED[key] = _SHARED[base + ((),)].compiled(*compile_names)
    return _SHARED[key]


def _fixed(fn: ca.Function, p: ca.DM) -> ca.Function:
    """``fn`` with its last input fixed at ``p``: an MX function of its other inputs, same names."""
    inputs = [ca.MX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in() - 1)]
    return ca.Function(fn.name(), inputs, fn.call([*inputs, p]), fn.name_in()[:-1], fn.name_out())

"""The ``Robot`` type: a robot's Pinocchio models and index maps (data only; built by
:mod:`rcm_kin.model.loading`).

Coordinates: ``q`` of every public function is the vector of *actuated* joints in the sidecar's
``actuated`` order (rad for revolute, m for prismatic). ``q_tree`` is the open tree's full
configuration, passive joints of the loops included.

Model/Data split, as in Pinocchio: a ``Robot`` holds models, never one shared workspace.
:meth:`Robot.create_data` gives the caller a workspace of its own (:class:`RobotData`); functions
that take ``data=None`` use the calling thread's own workspace (:attr:`Robot.scratch`), so two
threads using one robot never share scratch data.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from operator import le

import numpy as np
import pinocchio as pin

from rcm_kin.errors import JointLimitError, RcmKinError
from rcm_kin.model.description import RobotDescription

LIMIT_TOLERANCE = 1e-9      # rad or m: how far outside its limits a joint value still counts as within

FLOAT64 = np.dtype(np.float64)   # NumPy's one float64 dtype: :meth:`Robot.check_pose`'s identity test

@dataclass(frozen=True)
class RobotData:
    """Pinocchio scratch workspaces of one robot: the open tree's, the reduced model's and one per
    loop constraint."""

    tree: pin.Data
    reduced: pin.Data
    constraints: tuple              # pin.PointAnchorConstraintData, one per loop, in the robot's order
    position_errors: tuple = field(init=False, repr=False, compare=False)
    # each constraint's ``constraint_position_error``, read in place: Pinocchio's views of the
    # constraint data held here, so that they update with each ``calc`` and live as long as it

    loop_terms: tuple | None = field(default=None, init=False, repr=False, compare=False)
    # ``(checks, terms)`` that :meth:`keep_loop_terms` made last

    def __post_init__(self) -> None:
        object.__setattr__(self, "position_errors", tuple(c.constraint_position_error for c in self.constraints))

    def keep_loop_terms(self, checks: tuple) -> tuple:
        """``(checks, terms)``, kept as :attr:`loop_terms`: each of ``checks`` (a robot's
        :func:`~rcm_kin.model.constrained.loop_checks`, one ``(calc, rows)`` per constraint) with this
        workspace's data and position error of its constraint, ``(calc, rows, c_data, position_error)``,
        for the closure error's loops to read while ``checks`` stays the same object (held here, so
        its identity cannot pass to another)."""
        terms = tuple((calc, rows, c_data, error)
                      for (calc, rows), c_data, error in zip(checks, self.constraints, self.position_errors))
        object.__setattr__(self, "loop_terms", (checks, terms))
        return checks, terms


@dataclass(frozen=True)
class JointRow:
    """One open-tree joint: limits in rad or m, unit axis in the base frame at q = 0."""

    name: str
    kind: str           # 'revolute' or 'prismatic'
    role: str           # 'actuated' or 'passive'
    lower: float
    upper: float
    axis: np.ndarray


@dataclass(eq=False)
class Robot:
    """A robot's models and index maps (no scratch data: see :meth:`create_data`)."""

    name: str
    description: RobotDescription
    with_counterweights: bool
    tree: pin.Model                 # open tree, all joints independent
    reduced: pin.Model              # actuated coordinates; loop joints are mimic joints
    constraints: list               # Pinocchio constraint models, one per loop
    tree_q_actuated: np.ndarray     # index in q_tree of each actuated joint (actuated order)
    tree_q_passive: np.ndarray      # index in q_tree of each passive joint (description order)
    reduced_q_actuated: np.ndarray  # index in the reduced q of each actuated joint
    lower: np.ndarray               # actuated joint limits (rad or m)
    upper: np.ndarray
    massless_links: tuple[str, ...] = ()   # moving links whose rigid body has no <inertial> in the URDF
    _threads: threading.local = field(default_factory=threading.local, init=False, repr=False)  # per thread: RobotData
    _bounds: tuple | None = field(default=None, init=False, repr=False)  # _pose_bounds, made when read

    def __setattr__(self, name: str, value) -> None:
        if name in ("lower", "upper"):      # own read-only copies, whenever set: limit_bounds reads them once
            value = np.array(value, dtype=float)
            value.setflags(write=False)
        object.__setattr__(self, name, value)
        if name in ("lower", "upper", "description"):   # what _pose_bounds reads: made again from the new value
            object.__setattr__(self, "_bounds", None)

    def create_data(self) -> RobotData:
        """New scratch workspaces for the caller alone (Pinocchio's ``model.createData()``)."""
        return RobotData(self.tree.createData(), self.reduced.createData(),
                         tuple(c.model.createData() for c in self.constraints))

    @property
    def scratch(self) -> RobotData:
        """The calling thread's own workspaces (created on first use in each thread)."""
        data = getattr(self._threads, "data", None)
        if data is None:
            data = self._threads.data = self.create_data()
        return data

    def workspace(self, data: RobotData | None = None) -> RobotData:
        """``data`` if it is a workspace of this robot (else an error), or this thread's own."""
        own = getattr(self._threads, "data", None)
        if data is None or data is own:           # this thread's own: checked
            return self.scratch if own is None else own
        if not isinstance(data, RobotData):
            raise RcmKinError(f"data must be this robot's RobotData (robot.create_data()), got {type(data).__name__}",
                              parameter="data")
        if (len(data.tree.oMi) != self.tree.njoints or len(data.reduced.oMi) != self.reduced.njoints
                or len(data.constraints) != len(self.constraints)):
            raise RcmKinError(f"data is not a workspace of {self.name}: make it with robot.create_data()",
                              parameter="data")
        return data

    @property
    def tree_data(self) -> pin.Data:
        """The calling thread's workspace of the open tree."""
        return self.scratch.tree

    @property
    def reduced_data(self) -> pin.Data:
        """The calling thread's workspace of the reduced model."""
        return self.scratch.reduced

    @property
    def gravity(self) -> np.ndarray:
        """Gravity in the base frame (m/s^2): -z 9.81 unless the sidecar's ``[base]`` tilts it."""
        return np.array(self.tree.gravity.linear)

    @property
    def actuated(self) -> tuple[str, ...]:
        """Names of the actuated joints, in the order of ``q``."""
        return self.description.actuated

    @property
    def nq(self) -> int:
        """Number of actuated joints."""
        return len(self.description.actuated)

    def joint_kind(self, name: str) -> str:
        """'revolute' or 'prismatic'."""
        shortname = self.tree.joints[self.tree.getJointId(name)].shortname()
        # Pinocchio: JointModelPX/PY/PZ (axis-aligned) or JointModelPrismaticUnaligned
        prismatic = "Prismatic" in shortname or shortname in ("JointModelPX", "JointModelPY", "JointModelPZ")
        return "prismatic" if prismatic else "revolute"

    def frame_id(self, name: str) -> int:
        """The reduced model's id of frame ``name``, or an error listing the frames of interest."""
        if not self.reduced.existFrame(name):
            raise RcmKinError(f"{self.name} has no frame '{name}'; frames of interest: "
                              f"{', '.join(self.description.frames)}")
        return self.reduced.getFrameId(name)

    def to_reduced(self, q: np.ndarray) -> np.ndarray:
        """Actuated-order vector -> the reduced model's configuration vector."""
        q_red = np.zeros(self.reduced.nq)
        q_red[self.reduced_q_actuated] = q
        return q_red

    def from_reduced(self, q_red: np.ndarray) -> np.ndarray:
        """The reduced model's configuration vector -> actuated order."""
        return np.asarray(q_red)[self.reduced_q_actuated]

    def check_q(self, q, *, allow_short: bool = False, parameter: str = "q") -> np.ndarray:
        """``q`` as a float array of the actuated size, or a clear error (an RcmKinError naming
        ``parameter``). Short vectors are padded with zeros when ``allow_short``."""
        if (type(q) is np.ndarray and q.dtype == np.float64 and q.shape == (self.nq,)
                and all(map(math.isfinite, q.tolist()))):
            return q.copy()               # the common case, without the checks' array operations
        try:
            q = np.atleast_1d(np.asarray(q, dtype=float))
        except (TypeError, ValueError):
            raise RcmKinError(f"joint values must be numbers ({', '.join(self.actuated)}), "
                              f"got {str(q)[:60]!r}", parameter=parameter) from None
        if q.ndim != 1 or q.size > self.nq or (q.size < self.nq and not allow_short):
            raise RcmKinError(f"{self.name} takes {self.nq} joint values ({', '.join(self.actuated)}), got {q.size}",
                              parameter=parameter)
        if not np.all(np.isfinite(q)):
            raise RcmKinError(f"joint values must be finite numbers, got {q.tolist()}", parameter=parameter)
        return np.concatenate([q, np.zeros(self.nq - q.size)])

    def check_limits(self, q, tol: float = LIMIT_TOLERANCE, parameter: str = "q") -> np.ndarray:
        """``q`` (actuated, rad or m) unchanged, or a clear error naming every joint outside its limits
        (a :class:`~rcm_kin.errors.JointLimitError` carrying their names, values and limits).
        The one joint-limit policy of rcm_kin: poses outside the limits are refused, not computed."""
        return check_within_limits(q, self.actuated, self.lower, self.upper,
                                   lambda i: self.joint_kind(self.actuated[i]) == "revolute", tol, parameter)

    def check_pose(self, q, *, allow_outside_limits: bool = False, parameter: str = "q") -> np.ndarray:
        """The public functions' check of a pose argument (the API's policy): ``q`` as the actuated
        vector (rad, m), finite and of the right size, and within the joint limits unless
        ``allow_outside_limits`` (an explicit request to evaluate the model outside them);
        else an RcmKinError (:class:`~rcm_kin.errors.JointLimitError` for the limits) naming ``parameter``."""
        if not allow_outside_limits and type(q) is np.ndarray and q.dtype is FLOAT64:
            shape, low, high = self._bounds or self._pose_bounds()
            if q.shape == shape:
                values = q.tolist()       # finite and within the limits (NaN fails every comparison): one pass
                if all(map(le, low, values)) and all(map(le, values, high)):
                    return q.copy()
        q = self.check_q(q, parameter=parameter)
        return q if allow_outside_limits else self.check_limits(q, parameter=parameter)

    @property
    def limit_bounds(self) -> tuple[list[float], list[float]]:
        """The joint limits widened by :data:`LIMIT_TOLERANCE` as Python floats, as
        :func:`check_within_limits` compares them: the one-pass check of :meth:`check_pose` (made
        again when ``lower``, ``upper`` or ``description`` is set)."""
        _, low, high = self._bounds or self._pose_bounds()
        return low, high

    def _pose_bounds(self) -> tuple[tuple[int], list[float], list[float]]:
        """The shape of a pose and :attr:`limit_bounds`, kept until ``lower``, ``upper`` or
        ``description`` is set."""
        self._bounds = ((self.nq,), (self.lower - LIMIT_TOLERANCE).tolist(), (self.upper + LIMIT_TOLERANCE).tolist())
        return self._bounds


def check_robot(robot, parameter: str = "robot") -> Robot:
    """``robot`` itself when it is a :class:`Robot`; else an RcmKinError naming ``parameter`` and
    saying how to get one (the public functions take the loaded robot, not its name)."""
    if isinstance(robot, Robot):
        return robot
    hint = f"rk.load_robot({robot!r})" if isinstance(robot, str) else "rk.load_robot(name or path)"
    raise RcmKinError(f"`{parameter}` must be a loaded robot ({hint}), got {type(robot).__name__}", parameter=parameter)


def check_within_limits(q, joints, lower, upper, revolute: Callable[[int], bool], tol: float = LIMIT_TOLERANCE,
                        parameter: str = "q") -> np.ndarray:
    """``q`` (rad or m, one value per joint of ``joints``) unchanged, or the one joint-limit error of
    rcm_kin: a :class:`~rcm_kin.errors.JointLimitError` naming ``parameter`` and every joint outside
    ``[lower, upper]`` (degrees where ``revolute(i)``, metres for the others), carrying their
    names, values and limits. A robot's pose (:meth:`Robot.check_limits`) and a driven-joint
    model's (:func:`rcm_kin.dynamics.state_space.check_pose`) are both checked here."""
    q = np.asarray(q, dtype=float)
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    if q.ndim == 1 and all(lo - tol <= x <= hi + tol for x, lo, hi in zip(q.tolist(), lower.tolist(), upper.tolist())):
        return q                            # the common case in plain floats (NumPy's calls cost more on 7 values)
    outside = (q < lower - tol) | (q > upper + tol)
    if np.any(outside):
        shown = lambda i, x: f"{np.degrees(x):.6g} deg" if revolute(i) else f"{x:.6g} m"  # noqa: E731
        bad = np.flatnonzero(outside)
        raise JointLimitError("outside the joint limits: " + "; ".join(
            f"{joints[i]} {shown(i, q[i])} not in [{shown(i, lower[i])}, {shown(i, upper[i])}]" for i in bad),
            joints=tuple(joints[i] for i in bad), values=q[bad].copy(), lower=lower[bad].copy(),
            upper=upper[bad].copy(), parameter=parameter)
    return q

"""Load a bundled robot (URDF + sidecar) into its open-tree and reduced Pinocchio models.

Coordinates: ``q`` of every public function is the vector of *actuated* joints in the sidecar's
``actuated`` order (rad for revolute, m for prismatic). ``q_tree`` is the open tree's full
configuration, passive joints of the loops included.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from rcm_kin.closure.constrained import build_constraint_models, closure_residual
from rcm_kin.closure.description import RobotDescription, read_description
from rcm_kin.closure.reduced import build_reduced_model, tree_configuration
from rcm_kin.errors import JointLimitError, RcmKinError

GRAVITY = np.array([0.0, 0.0, -9.81])  # m/s^2, base frame (z up) of every bundled robot


def urdf_dir() -> Path:
    """The folder of bundled URDFs: inside the installed package, else the source checkout's ``urdf/``."""
    here = Path(__file__).resolve().parent
    for candidate in (here / "urdf", here.parents[1] / "urdf"):
        if (candidate / "psm.toml").is_file():
            return candidate
    raise RcmKinError("the bundled robot models are missing: reinstall rcm-kin (pip install .)")


def robot_names() -> list[str]:
    return sorted(p.stem for p in urdf_dir().glob("*.toml"))


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
    """A robot's models and index maps. ``*_data`` are Pinocchio scratch workspaces."""

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
    tree_data: pin.Data = field(repr=False, default=None)
    reduced_data: pin.Data = field(repr=False, default=None)

    @property
    def actuated(self) -> tuple[str, ...]:
        return self.description.actuated

    @property
    def nq(self) -> int:
        return len(self.description.actuated)

    def joint_kind(self, name: str) -> str:
        """'revolute' or 'prismatic'."""
        shortname = self.tree.joints[self.tree.getJointId(name)].shortname()
        # Pinocchio: JointModelPX/PY/PZ (axis-aligned) or JointModelPrismaticUnaligned
        prismatic = "Prismatic" in shortname or shortname in ("JointModelPX", "JointModelPY", "JointModelPZ")
        return "prismatic" if prismatic else "revolute"

    def frame_id(self, name: str) -> int:
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
        return np.asarray(q_red)[self.reduced_q_actuated]

    def check_q(self, q, *, allow_short: bool = False) -> np.ndarray:
        """``q`` as a float array of the actuated size, or a clear error. Short vectors are
        padded with zeros when ``allow_short``."""
        try:
            q = np.atleast_1d(np.asarray(q, dtype=float))
        except (TypeError, ValueError):
            raise RcmKinError(f"joint values must be numbers ({', '.join(self.actuated)}), got {str(q)[:60]!r}") from None
        if q.ndim != 1 or q.size > self.nq or (q.size < self.nq and not allow_short):
            raise RcmKinError(f"{self.name} takes {self.nq} joint values ({', '.join(self.actuated)}), got {q.size}")
        if not np.all(np.isfinite(q)):
            raise RcmKinError(f"joint values must be finite numbers, got {q.tolist()}")
        return np.concatenate([q, np.zeros(self.nq - q.size)])

    def check_limits(self, q, tol: float = 1e-9) -> np.ndarray:
        """``q`` (actuated, rad or m) unchanged, or a clear error naming every joint outside its limits.
        The one joint-limit policy of rcm_kin: poses outside the limits are refused, not computed."""
        q = np.asarray(q, dtype=float)
        outside = (q < self.lower - tol) | (q > self.upper + tol)
        if np.any(outside):
            shown = lambda i, x: (f"{np.degrees(x):.6g} deg" if self.joint_kind(self.actuated[i]) == "revolute"  # noqa: E731
                                  else f"{x:.6g} m")
            raise JointLimitError("outside the joint limits: " + "; ".join(
                f"{self.actuated[i]} {shown(i, q[i])} not in [{shown(i, self.lower[i])}, {shown(i, self.upper[i])}]"
                for i in np.flatnonzero(outside)))
        return q

    def joint_table(self) -> list[JointRow]:
        """Every joint of the open tree, in tree order, passive loop joints included."""
        from rcm_kin.kinematics.fk import joint_axes_world  # kinematics builds on this module

        axes = joint_axes_world(self, np.zeros(self.nq))
        rows = []
        for jid in range(1, self.tree.njoints):
            name, i = self.tree.names[jid], self.tree.joints[jid].idx_q
            rows.append(JointRow(name, self.joint_kind(name), "actuated" if name in self.actuated else "passive",
                                 float(self.tree.lowerPositionLimit[i]), float(self.tree.upperPositionLimit[i]),
                                 axes[name]))
        return rows


def _joint_q_index(model: pin.Model, name: str, where: str) -> int:
    if not model.existJointName(name):
        raise RcmKinError(f"{where}: joint '{name}' is not in the URDF")
    joint = model.joints[model.getJointId(name)]
    if joint.nq != 1:
        raise RcmKinError(f"{where}: joint '{name}' must be a 1-DOF revolute or prismatic joint")
    return joint.idx_q


def _urdf_without(description: RobotDescription, links: tuple[str, ...]) -> str:
    """The URDF text with the mass of ``links`` removed (their geometry stays)."""
    root = ET.parse(description.urdf).getroot()
    found = set()
    for link in root.iter("link"):
        if link.get("name") in links:
            found.add(link.get("name"))
            for inertial in link.findall("inertial"):
                link.remove(inertial)
    if missing := set(links) - found:
        raise RcmKinError(f"{description.urdf}: counterweight links {sorted(missing)} are not in the URDF")
    return ET.tostring(root, encoding="unicode")


def build_robot(description: RobotDescription, counterweights: bool = True) -> Robot:
    """Build and check the open-tree, constrained and reduced models of one description.

    ``counterweights=False`` drops the mass of the sidecar's counterweight links."""
    where = str(description.urdf)
    if counterweights:
        tree = pin.buildModelFromUrdf(str(description.urdf))
    else:
        tree = pin.buildModelFromXML(_urdf_without(description, description.counterweights))
    tree.gravity.linear = GRAVITY
    tree_data = tree.createData()
    assert tree.check(tree_data), f"{where}: pinocchio model check failed"

    actuated = [_joint_q_index(tree, n, where) for n in description.actuated]
    passive = [_joint_q_index(tree, p.joint, where) for p in description.passive]
    for p in description.passive:
        if p.follows not in description.actuated:
            raise RcmKinError(f"{where}: passive joint '{p.joint}' follows '{p.follows}', which is not actuated")
    unassigned = set(tree.names[1:]) - set(description.actuated) - {p.joint for p in description.passive}
    if unassigned:
        raise RcmKinError(f"{where}: joints {sorted(unassigned)} are neither actuated nor passive")
    for frame in description.frames:
        if not tree.existFrame(frame):
            raise RcmKinError(f"{where}: frame of interest '{frame}' is not a link of the URDF")

    reduced = build_reduced_model(tree, description.passive)
    reduced_data = reduced.createData()
    assert reduced.check(reduced_data), f"{where}: pinocchio check of the reduced model failed"
    reduced_actuated = [reduced.joints[reduced.getJointId(n)].idx_q for n in description.actuated]

    tree_q = np.array(actuated, dtype=int)
    robot = Robot(
        name=description.robot, description=description, with_counterweights=counterweights,
        tree=tree, reduced=reduced,
        constraints=build_constraint_models(tree, description.loops),
        tree_q_actuated=tree_q, tree_q_passive=np.array(passive, dtype=int),
        reduced_q_actuated=np.array(reduced_actuated, dtype=int),
        lower=tree.lowerPositionLimit[tree_q].copy(), upper=tree.upperPositionLimit[tree_q].copy(),
        tree_data=tree_data, reduced_data=reduced_data)
    _check_passive_relations(robot)
    return robot


def _check_passive_relations(robot: Robot, tol: float = 1e-9) -> None:
    """The sidecar's linear passive relations must close every loop (checked at the limits)."""
    if not robot.constraints:
        return
    for q in (np.zeros(robot.nq), robot.lower, robot.upper, 0.5 * (robot.lower + robot.upper)):
        residual = closure_residual(robot, tree_configuration(robot, q))
        if np.max(np.abs(residual)) > tol:
            raise RcmKinError(f"{robot.description.urdf}: the [[passive]] relations do not close the loops "
                              f"(residual {np.max(np.abs(residual)):.2e} m at q = {np.round(q, 4).tolist()})")


@functools.lru_cache(maxsize=None)
def load_robot(name: str, counterweights: bool = True) -> Robot:
    """A bundled robot by name (``psm``, ``mtm``) or any sidecar ``.toml`` by path; with
    ``counterweights=False`` the counterweight links carry no mass."""
    if not isinstance(name, str):
        raise RcmKinError(f"a robot is named by a string ({', '.join(robot_names())}) or a .toml path, "
                          f"got {type(name).__name__}")
    if name.endswith(".toml"):
        path = Path(name)
    elif name in robot_names():
        path = urdf_dir() / f"{name}.toml"
    else:
        raise RcmKinError(f"unknown robot '{name}'; choose one of: {', '.join(robot_names())}")
    return build_robot(read_description(path), counterweights)

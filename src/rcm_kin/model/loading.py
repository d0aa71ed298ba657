"""Load a robot description (URDF + sidecar, or a URDF alone) into its open-tree, constrained and
reduced models.

:func:`load_robot` caches by the *content* of the description's files (sidecar and URDF): a file
edited on disk is reloaded at the next call, an unchanged one is built once. The URDF's
``<mimic>`` tags become passive relations and its ``continuous`` joints revolute ones limited to
[-pi, pi] (:mod:`rcm_kin.model.urdf_text`).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import threading
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError, read_bounded
from rcm_kin.model.constrained import build_constraint_models, closure_residual
from rcm_kin.model.description import GRAVITY, RobotDescription, read_description, urdf_alone
from rcm_kin.model.inertials import check_bodies
from rcm_kin.model.reduced import build_reduced_model, tree_configuration
from rcm_kin.model.robot import Robot
from rcm_kin.model.urdf_text import UrdfFacts, build_tree, massless_links, merge_passive, read_urdf

__all__ = ["GRAVITY", "build_robot", "load_robot", "robot_names", "urdf_dir"]


@functools.cache
def urdf_dir() -> Path:
    """The folder of bundled URDFs: inside the installed package, else the source checkout's ``urdf/``."""
    package = Path(__file__).resolve().parents[1]
    for candidate in (package / "urdf", package.parents[1] / "urdf"):
        if candidate.is_dir() and any(candidate.glob("*.toml")):
            return candidate
    raise RcmKinError("the bundled robot models are missing: reinstall rcm-kin (pip install .)")


def robot_names() -> list[str]:
    """Names of the bundled robots (their sidecars in :func:`urdf_dir`)."""
    return list(_bundled_names())


@functools.cache
def _bundled_names() -> tuple[str, ...]:
    return tuple(sorted(p.stem for p in urdf_dir().glob("*.toml") if p.with_suffix(".urdf").is_file()))


def _joint_q_index(model: pin.Model, name: str, where: str) -> int:
    if not model.existJointName(name):
        raise RcmKinError(f"{where}: joint '{name}' is not in the URDF")
    joint = model.joints[model.getJointId(name)]
    if joint.nq != 1:
        raise RcmKinError(f"{where}: joint '{name}' must be a 1-DOF revolute or prismatic joint")
    return joint.idx_q


def _urdf_without(description: RobotDescription, links: tuple[str, ...], text: str) -> str:
    """The URDF ``text`` with the mass of ``links`` removed (their geometry stays)."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RcmKinError(f"{description.urdf}: not valid XML ({exc})") from None
    found = set()
    for link in root.iter("link"):
        if link.get("name") in links:
            found.add(link.get("name"))
            for inertial in link.findall("inertial"):
                link.remove(inertial)
    if missing := set(links) - found:
        raise RcmKinError(f"{description.urdf}: counterweight links {sorted(missing)} are not in the URDF")
    return ET.tostring(root, encoding="unicode")


def _read_bytes(path: Path, what: str) -> bytes:
    """The bytes of ``path`` (a ``what``), bounded (:func:`~rcm_kin.errors.read_bounded`)."""
    try:
        return read_bounded(path, what)
    except OSError as exc:
        raise RcmKinError(f"cannot read the {what} {path}: {exc.strerror}") from None


def _text(data: bytes, path: Path) -> str:
    try:
        return data.decode()
    except UnicodeDecodeError as exc:
        raise RcmKinError(f"{path}: not UTF-8 text ({exc})") from None


def completed(description: RobotDescription, facts: UrdfFacts, tree: pin.Model) -> RobotDescription:
    """``description`` with the URDF's defaults filled in (robot name, actuated joints in
    Pinocchio's depth-first order, leaf links as frames) and its ``<mimic>`` tags merged into the
    passive relations."""
    where = str(description.urdf)
    mimic = {r.joint for r in facts.mimic}
    actuated = description.actuated or tuple(
        n for n in tree.names[1:] if n not in mimic and n not in {p.joint for p in description.passive})
    passive = merge_passive(facts.mimic, description.passive, actuated, where)
    if not actuated:
        raise RcmKinError(f"{where}: the URDF has no joint to actuate (every joint is fixed or a mimic)")
    robot = description.robot or facts.name
    if not robot:
        raise RcmKinError(f"{where}: the URDF's <robot> has no name; give one in a sidecar (robot = ...)")
    if description.rcm is not None and not all(j in actuated for j in description.rcm.joints):
        raise RcmKinError(f"{where}: [rcm] 'joints' must name two actuated joints, got {list(description.rcm.joints)}")
    return dataclasses.replace(
        description, robot=robot, actuated=actuated, frames=description.frames or facts.leaf_links,
        passive=passive)


def build_robot(description: RobotDescription, counterweights: bool = True, urdf_text: str | None = None) -> Robot:
    """Build and check the open-tree, constrained and reduced models of one description (the URDF
    from ``urdf_text`` when given, else read from ``description.urdf``).

    ``counterweights=False`` drops the mass of the sidecar's counterweight links."""
    where = str(description.urdf)
    if urdf_text is None:
        urdf_text = _text(_read_bytes(description.urdf, "URDF"), description.urdf)
    facts = read_urdf(urdf_text, where)
    text = facts.text if counterweights else _urdf_without(description, description.counterweights, facts.text)
    tree = build_tree(facts, where, text)
    dropped = () if counterweights else description.counterweights    # their inertials removed from the text
    check_bodies(tree, {link: m for link, m in facts.masses.items() if link not in dropped}, where)
    tree.gravity.linear = np.asarray(description.gravity, dtype=float)
    if not tree.check(tree.createData()):
        raise RcmKinError(f"{where}: Pinocchio's model check failed")
    description = completed(description, facts, tree)

    actuated = [_joint_q_index(tree, n, where) for n in description.actuated]
    passive = [_joint_q_index(tree, p.joint, where) for p in description.passive]
    unassigned = set(tree.names[1:]) - set(description.actuated) - {p.joint for p in description.passive}
    if unassigned:
        raise RcmKinError(f"{where}: joints {sorted(unassigned)} are neither actuated nor passive")
    for frame in description.frames:
        if not tree.existFrame(frame):
            raise RcmKinError(f"{where}: frame of interest '{frame}' is not a link of the URDF")

    reduced = build_reduced_model(tree, description.passive)
    if not reduced.check(reduced.createData()):
        raise RcmKinError(f"{where}: Pinocchio's check of the reduced model failed")
    reduced_actuated = [reduced.joints[reduced.getJointId(n)].idx_q for n in description.actuated]

    tree_q = np.array(actuated, dtype=int)
    robot = Robot(
        name=description.robot, description=description, with_counterweights=counterweights,
        tree=tree, reduced=reduced,
        constraints=build_constraint_models(tree, description.loops),
        tree_q_actuated=tree_q, tree_q_passive=np.array(passive, dtype=int),
        reduced_q_actuated=np.array(reduced_actuated, dtype=int),
        lower=tree.lowerPositionLimit[tree_q].copy(), upper=tree.upperPositionLimit[tree_q].copy(),
        massless_links=massless_links(tree, facts.inertial_links))
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


_CACHE: dict[tuple, Robot] = {}   # (counterweights, sidecar digest, URDF path, URDF digest) -> robot
_DESCRIPTIONS: dict[tuple[str, str], RobotDescription] = {}   # (sidecar path, its digest) -> description
_CACHE_LOCK = threading.Lock()
_CACHE_SIZE = 32


def _sidecar_path(name: str) -> Path:
    if not isinstance(name, (str, Path)):
        raise RcmKinError(f"a robot is named by a string ({', '.join(robot_names())}), a .toml or a .urdf path, "
                          f"got {type(name).__name__}")
    name = str(name)
    if name.endswith((".toml", ".urdf")):
        return Path(name)
    if name in _bundled_names():
        return urdf_dir() / f"{name}.toml"
    raise RcmKinError(f"unknown robot '{name}'; choose one of: {', '.join(robot_names())}, "
                      f"or give the path of a sidecar .toml or a .urdf")


def _bounded_put(cache: dict, key, value):
    """``cache[key]`` unless another thread put one first; the oldest entry goes past
    :data:`_CACHE_SIZE`."""
    with _CACHE_LOCK:
        if key not in cache and len(cache) >= _CACHE_SIZE:
            cache.pop(next(iter(cache)))
        return cache.setdefault(key, value)


def _description(path: Path) -> tuple[RobotDescription, str]:
    """The sidecar at ``path`` (the one parsed before from the same bytes, or these bytes parsed),
    and the digest of its bytes: one read of the file gives both."""
    if not path.is_file():
        raise RcmKinError(f"no robot description at {path}")
    data = _read_bytes(path, "robot description")
    digest = hashlib.sha256(data).hexdigest()
    key = (os.path.abspath(path), digest)
    description = _DESCRIPTIONS.get(key)
    if description is None or not description.urdf.exists():
        description = _bounded_put(_DESCRIPTIONS, key, read_description(path, _text(data, path)))
    return description, digest


def load_robot(name: str | Path, counterweights: bool = True) -> Robot:
    """A bundled robot by name (see :func:`robot_names`), any sidecar ``.toml`` by path, or a
    ``.urdf`` alone (every default: see :class:`~rcm_kin.model.description.RobotDescription`); with
    ``counterweights=False`` the counterweight links carry no mass.

    The result is cached by the content of the sidecar and its URDF, so a call after either file
    changed builds the new model; the cached robot holds no shared scratch data
    (:meth:`Robot.create_data`)."""
    path = _sidecar_path(name)
    if path.suffix == ".urdf":
        if not path.is_file():
            raise RcmKinError(f"no URDF at {path}")
        description, sidecar = urdf_alone(path), "urdf alone"
    else:
        description, sidecar = _description(path)
    urdf = _read_bytes(description.urdf, "URDF")           # read once: its digest and its model
    key = (bool(counterweights), sidecar, str(description.urdf), hashlib.sha256(urdf).hexdigest())
    robot = _CACHE.get(key)
    if robot is None:
        robot = _bounded_put(_CACHE, key, build_robot(description, counterweights, _text(urdf, description.urdf)))
    return robot

"""What rcm_kin reads from a URDF's text before Pinocchio sees it, and the open tree built from it.

- :func:`read_urdf`: the robot's name, its joints' types, ``<mimic>`` tags (as passive relations),
  the links with ``<inertial>`` data (checked: :mod:`rcm_kin.model.inertials`) and the leaf links;
  joint types rcm_kin does not model (floating, planar, anything else) are refused with the joint's name.
- ``continuous`` joints: Pinocchio builds them as 2-variable (cos, sin) joints; rcm_kin rewrites
  them in the text as ``revolute`` with limits [-pi, pi] so that every joint stays 1-DOF (a
  ``<limit>``'s effort and velocity are kept; without one they stay infinite, as Pinocchio has them).
- :func:`build_tree`: Pinocchio's model of the text, every parse problem one error line naming the file.
- :func:`merge_passive`: the URDF's mimic relations and the sidecar's ``[[passive]]`` entries,
  mimic chains resolved to the actuated joint they follow.
"""

from __future__ import annotations

import os
import tempfile
import threading
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.model.description import PassiveRelation
from rcm_kin.model.inertials import body_links, check_inertials

MODELLED = ("revolute", "continuous", "prismatic", "fixed")
CONTINUOUS_LIMIT = np.pi   # rad: the limits [-pi, pi] a continuous joint is given


@dataclass(frozen=True)
class UrdfFacts:
    """What the loader needs of a URDF besides Pinocchio's model of it."""

    name: str                                # the <robot name=...> attribute
    text: str                                # the text for Pinocchio (continuous joints as revolute)
    joint_types: dict[str, str]              # joint name -> URDF type, in document order
    mimic: tuple[PassiveRelation, ...]       # <mimic> tags: joint = multiplier * mimicked + offset
    continuous: tuple[str, ...]              # joints rewritten from continuous to revolute
    unlimited: tuple[str, ...]               # of those, the ones without <limit>: effort, velocity infinite
    inertial_links: frozenset[str]           # links with an <inertial> element
    leaf_links: tuple[str, ...]              # links no joint has as parent, document order
    masses: dict[str, float] = field(default_factory=dict)   # link -> its <inertial> mass (kg), checked


def _number(element: ET.Element, key: str, default: float, where: str) -> float:
    value = element.get(key)
    if value is None:
        return default
    try:
        return float(value)
    except ValueError:
        raise RcmKinError(f"{where}: '{key}' must be a number, got {value!r}") from None


def _as_revolute(joint: ET.Element) -> bool:
    """Turn a continuous ``joint`` element into a revolute one limited to [-pi, pi]; True if it
    had no ``<limit>`` (effort and velocity placeholders to be set infinite after the build)."""
    joint.set("type", "revolute")
    limit = joint.find("limit")
    unlimited = limit is None
    if unlimited:
        limit = ET.SubElement(joint, "limit", effort="0", velocity="0")
    limit.set("lower", repr(-CONTINUOUS_LIMIT))
    limit.set("upper", repr(CONTINUOUS_LIMIT))
    return unlimited


def read_urdf(text: str, where: str) -> UrdfFacts:
    """The facts of the URDF ``text`` (``where``: its file, for the errors)."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RcmKinError(f"{where}: not valid XML ({exc})") from None
    if root.tag != "robot":
        raise RcmKinError(f"{where}: not a URDF (the root element is <{root.tag}>, not <robot>)")
    joints = root.findall("joint")
    types, mimic, continuous, unlimited, parents = {}, [], [], [], set()
    for joint in joints:
        name, kind = joint.get("name", ""), joint.get("type", "")
        if kind not in MODELLED:
            raise RcmKinError(f"{where}: joint '{name}' is {kind or 'of no type'}: rcm-kin models fixed-base "
                              f"robots with revolute, continuous, prismatic and fixed joints")
        types[name] = kind
        if (parent := joint.find("parent")) is not None:
            parents.add(parent.get("link"))
        if (tag := joint.find("mimic")) is not None and kind != "fixed":
            at = f"{where}: <mimic> of joint '{name}'"
            mimic.append(PassiveRelation(name, tag.get("joint", ""), _number(tag, "multiplier", 1.0, at),
                                         _number(tag, "offset", 0.0, at)))
    for joint in joints:
        if joint.get("type") == "continuous":
            continuous.append(joint.get("name"))
            if _as_revolute(joint):
                unlimited.append(joint.get("name"))
    for relation in mimic:
        if relation.follows not in types:
            raise RcmKinError(f"{where}: joint '{relation.joint}' mimics '{relation.follows}', "
                              f"which is not in the URDF")
    masses = check_inertials(root, where)
    links = [link.get("name", "") for link in root.findall("link")]
    inertial = frozenset(link.get("name") for link in root.findall("link") if link.find("inertial") is not None)
    return UrdfFacts(
        name=root.get("name", ""), text=ET.tostring(root, encoding="unicode") if continuous else text,
        joint_types=types, mimic=tuple(mimic), continuous=tuple(continuous), unlimited=tuple(unlimited),
        inertial_links=inertial, masses=masses,
        leaf_links=tuple(name for name in links if name not in parents))


_STDERR_LOCK = threading.Lock()   # file descriptor 2 is the process's: one capture at a time


class _CapturedStderr:
    """Collects what C++ code writes on file descriptor 2 (urdfdom's parse messages) meanwhile."""

    def __enter__(self):
        _STDERR_LOCK.acquire()
        try:
            self.file = tempfile.TemporaryFile(mode="w+b")
            self.saved = os.dup(2)
            os.dup2(self.file.fileno(), 2)
        except OSError:
            _STDERR_LOCK.release()
            raise
        return self

    def __exit__(self, *exc):
        os.dup2(self.saved, 2)
        os.close(self.saved)
        self.file.seek(0)
        self.text = self.file.read().decode(errors="replace")
        self.file.close()
        _STDERR_LOCK.release()
        return False


def _first_error(captured: str) -> str:
    """urdfdom's first ``Error:`` message, without its source-line trailer."""
    for line in captured.splitlines():
        if line.strip().startswith("Error:"):
            return line.strip()[len("Error:"):].strip()
    return ""


def build_tree(facts: UrdfFacts, where: str, text: str | None = None) -> pin.Model:
    """Pinocchio's open tree of ``text`` (default ``facts.text``), all joints independent (mimic
    tags not applied); a parse failure, or an error urdfdom reports while it builds (and drops what
    it could not read), is one error line naming the file."""
    with _CapturedStderr() as stderr:
        try:
            tree = pin.buildModelFromXML(facts.text if text is None else text)
        except (RuntimeError, ValueError, IndexError, TypeError) as exc:
            tree, failure = None, (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    if tree is None:
        reason = _first_error(stderr.text) or failure
        raise RcmKinError(f"{where}: Pinocchio cannot read the URDF ({reason[:200]})")
    if reason := _first_error(stderr.text):
        raise RcmKinError(f"{where}: the URDF parser reported an error and dropped what it could not read "
                          f"({reason[:200]})")
    for name in facts.unlimited:
        j = tree.joints[tree.getJointId(name)]
        tree.effortLimit[j.idx_v] = tree.velocityLimit[j.idx_v] = np.inf
    return tree


def _resolve(joint: str, relations: dict[str, PassiveRelation], where: str) -> PassiveRelation:
    """``joint``'s relation followed down a mimic chain to the joint that mimics no other."""
    follows, multiplier, offset, seen = joint, 1.0, 0.0, [joint]
    while follows in relations:
        r = relations[follows]
        follows, multiplier, offset = r.follows, multiplier * r.multiplier, multiplier * r.offset + offset
        if follows in seen:
            raise RcmKinError(f"{where}: mimic joints form a cycle: {' -> '.join([*seen, follows])}")
        seen.append(follows)
    return PassiveRelation(joint, follows, multiplier, offset)


def merge_passive(mimic: tuple[PassiveRelation, ...], passive: tuple[PassiveRelation, ...],
                  actuated: tuple[str, ...], where: str, tol: float = 1e-12) -> tuple[PassiveRelation, ...]:
    """The sidecar's ``passive`` relations, then the URDF's ``mimic`` ones not restated there, each
    resolved to an actuated joint. A sidecar entry for a mimic joint must agree with the tag."""
    relations = {r.joint: r for r in mimic}
    relations.update({r.joint: r for r in passive if r.joint not in relations})
    for name in actuated:
        if name in {r.joint for r in mimic}:
            raise RcmKinError(f"{where}: joint '{name}' is a <mimic> of '{relations[name].follows}' in the URDF, "
                              f"so it cannot be actuated")
    order = [r.joint for r in passive] + [r.joint for r in mimic if r.joint not in {p.joint for p in passive}]
    resolved = [_resolve(joint, relations, where) for joint in order]
    for r in resolved:
        if r.follows not in actuated:
            raise RcmKinError(f"{where}: passive joint '{r.joint}' follows '{r.follows}', which is not actuated")
    by_joint = {r.joint: r for r in resolved}
    for p in passive:
        tag = next((m for m in mimic if m.joint == p.joint), None)
        r = by_joint[p.joint]
        if tag is not None and (p.follows != r.follows or abs(p.multiplier - r.multiplier) > tol
                                or abs(p.offset - r.offset) > tol):
            raise RcmKinError(f"{where}: [[passive]] '{p.joint}' = {p.multiplier:g} * {p.follows} + {p.offset:g} "
                              f"disagrees with the URDF's <mimic> ({r.multiplier:g} * {r.follows} + {r.offset:g})")
    return tuple(resolved)


def massless_links(tree: pin.Model, inertial_links: frozenset[str]) -> tuple[str, ...]:
    """Links moved by a non-fixed joint (directly or through fixed joints) whose rigid body (the
    links fixed to each other) has no ``<inertial>`` at all, in tree order."""
    bodies = body_links(tree)
    return tuple(link for j in sorted(bodies) if not inertial_links & set(bodies[j]) for link in bodies[j])

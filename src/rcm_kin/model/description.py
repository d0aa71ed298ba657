"""The robot description sidecar: what a URDF cannot say (loops, actuated joints, frames).

A sidecar ``<robot>.toml`` sits beside ``<robot>.urdf``; the bundled sidecars (``urdf/*.toml``)
and docs/models.md document the format. Lengths are in metres and angles in radians, in the frame of the link named.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.errors import RcmKinError, read_toml


@dataclass(frozen=True)
class LoopClosure:
    """Point ``point_a`` fixed in ``link_a`` coincides with ``point_b`` fixed in ``link_b``.

    ``plane_normal`` (in ``link_a``'s frame), when given, marks a planar loop: the constraint
    component along it holds by construction, so only the two in-plane components count.
    """

    name: str
    link_a: str
    point_a: np.ndarray
    link_b: str
    point_b: np.ndarray
    plane_normal: np.ndarray | None


@dataclass(frozen=True)
class PassiveRelation:
    """Reduced model of a loop: ``q[joint] = multiplier * q[follows] + offset`` (rad or m)."""

    joint: str
    follows: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class RcmDescription:
    """Where a robot's remote centre of motion is to be checked: the instrument shaft is the z
    axis of ``shaft_frame``; ``joints`` are the two joints that pivot it about the RCM; lines are
    compared in ``base_frame`` (None: the robot's base)."""

    shaft_frame: str
    joints: tuple[str, str]
    base_frame: str | None = None


@dataclass(frozen=True)
class RobotDescription:
    robot: str
    urdf: Path
    actuated: tuple[str, ...]
    frames: tuple[str, ...]
    loops: tuple[LoopClosure, ...]
    passive: tuple[PassiveRelation, ...]
    counterweights: tuple[str, ...] = ()   # links whose mass is a counterweight (removable)
    rcm: RcmDescription | None = None
    drive: Path | None = None   # the robot's drive parameter file (its calibration); None: CAD, torque only


def _vector3(entry: dict, key: str, where: str) -> np.ndarray:
    try:
        v = np.asarray(entry[key], dtype=float)
    except KeyError:
        raise RcmKinError(f"{where}: missing '{key}'") from None
    except (TypeError, ValueError):
        raise RcmKinError(f"{where}: '{key}' must be a list of 3 numbers") from None
    if v.shape != (3,):
        raise RcmKinError(f"{where}: '{key}' must be a list of 3 numbers, got {entry[key]!r}")
    return v


def _text(entry: dict, key: str, where: str) -> str:
    value = entry.get(key)
    if not isinstance(value, str) or not value:
        raise RcmKinError(f"{where}: missing or empty '{key}'")
    return value


def read_description(path: str | Path, text: str | None = None) -> RobotDescription:
    """Read and check a sidecar file (``text``: its content, already read); errors name the file
    and the entry at fault."""
    path = Path(path)
    raw = read_toml(path, "robot description", text)

    where = str(path)
    urdf = path.parent / _text(raw, "urdf", where)
    if not urdf.exists():
        raise RcmKinError(f"{where}: URDF file {urdf} does not exist")
    actuated = raw.get("actuated")
    if not actuated or not all(isinstance(n, str) for n in actuated):
        raise RcmKinError(f"{where}: 'actuated' must be a non-empty list of joint names")
    loops = []
    for i, entry in enumerate(raw.get("loop", [])):
        at = f"{where}: loop {i + 1}"
        normal = _vector3(entry, "plane_normal", at) if "plane_normal" in entry else None
        if normal is not None:
            norm = np.linalg.norm(normal)
            if norm == 0:
                raise RcmKinError(f"{at}: 'plane_normal' must not be zero")
            normal = normal / norm
        loops.append(LoopClosure(
            name=entry.get("name", f"loop{i + 1}"),
            link_a=_text(entry, "link_a", at), point_a=_vector3(entry, "point_a", at),
            link_b=_text(entry, "link_b", at), point_b=_vector3(entry, "point_b", at),
            plane_normal=normal))
    passive = []
    for i, entry in enumerate(raw.get("passive", [])):
        at = f"{where}: passive {i + 1}"
        try:
            multiplier, offset = float(entry.get("multiplier", 1.0)), float(entry.get("offset", 0.0))
        except (TypeError, ValueError):
            raise RcmKinError(f"{at}: 'multiplier' and 'offset' must be numbers") from None
        passive.append(PassiveRelation(_text(entry, "joint", at), _text(entry, "follows", at), multiplier, offset))
    if loops and not passive:
        raise RcmKinError(f"{where}: loops need [[passive]] relations for the reduced model")
    rcm = None
    if "rcm" in raw:
        entry, at = raw["rcm"], f"{where}: [rcm]"
        joints = entry.get("joints") if isinstance(entry, dict) else None
        if not (isinstance(joints, list) and len(joints) == 2 and all(j in actuated for j in joints)):
            raise RcmKinError(f"{at}: 'joints' must name two actuated joints")
        rcm = RcmDescription(_text(entry, "shaft_frame", at), tuple(joints), entry.get("base_frame"))
    drive = None
    if "drive" in raw:
        drive = path.parent / _text(raw, "drive", where)
        if not drive.is_file():
            raise RcmKinError(f"{where}: drive parameter file {drive} does not exist")
    return RobotDescription(
        robot=_text(raw, "robot", where), urdf=urdf, drive=drive, actuated=tuple(actuated),
        frames=tuple(raw.get("frames", ())), loops=tuple(loops), passive=tuple(passive),
        counterweights=tuple(raw.get("counterweights", ())), rcm=rcm)

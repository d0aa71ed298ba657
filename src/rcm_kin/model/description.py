"""The robot description sidecar: what a URDF cannot say (loops, actuated joints, frames).

A sidecar ``<robot>.toml`` sits beside ``<robot>.urdf``; the bundled sidecars (``urdf/*.toml``)
and docs/models.md document the format. Lengths are in metres and angles in radians, in the frame of the link named.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rcm_kin.errors import RcmKinError, read_toml

GRAVITY = np.array([0.0, 0.0, -9.81])  # m/s^2: gravity in the world (z up), and in an untilted base frame


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
    """A robot as its sidecar (or, for a URDF alone, the defaults) describes it. Empty ``robot``,
    ``actuated`` or ``frames`` mean the URDF's defaults, filled in by the loader: its robot name,
    every non-fixed, non-mimic joint in depth-first order, its leaf links."""

    robot: str
    urdf: Path
    actuated: tuple[str, ...]
    frames: tuple[str, ...]
    loops: tuple[LoopClosure, ...]
    passive: tuple[PassiveRelation, ...]
    counterweights: tuple[str, ...] = ()   # links whose mass is a counterweight (removable)
    rcm: RcmDescription | None = None
    drive: Path | None = None   # the robot's drive parameter file (its calibration); None: CAD, torque only
    base_rpy: np.ndarray | None = None     # [base] rpy: the base's orientation in the world (rad, URDF rpy)
    gravity: np.ndarray = field(default_factory=GRAVITY.copy)   # m/s^2 in the base frame


def _base_gravity(raw: dict, where: str) -> tuple[np.ndarray | None, np.ndarray]:
    """``[base]``: ``rpy`` (the base's orientation in the world, where gravity is -z 9.81 m/s^2)
    or ``gravity`` (m/s^2 in the base frame), not both; -> (rpy or None, gravity in the base frame)."""
    entry = raw.get("base", {})
    at = f"{where}: [base]"
    if not isinstance(entry, dict):
        raise RcmKinError(f"{at} must be a table (rpy = [r, p, y] or gravity = [gx, gy, gz])")
    if unknown := set(entry) - {"rpy", "gravity"}:
        raise RcmKinError(f"{at}: unknown keys {sorted(unknown)} (rpy or gravity)")
    if "rpy" in entry and "gravity" in entry:
        raise RcmKinError(f"{at}: give 'rpy' or 'gravity', not both")
    if "gravity" in entry:
        g = _vector3(entry, "gravity", at)
        if not np.all(np.isfinite(g)):
            raise RcmKinError(f"{at}: 'gravity' must be finite")
        return None, g
    if "rpy" in entry:
        rpy = _vector3(entry, "rpy", at)
        if not np.all(np.isfinite(rpy)):
            raise RcmKinError(f"{at}: 'rpy' must be finite")
        return rpy, _rpy_matrix(rpy).T @ GRAVITY
    return None, GRAVITY.copy()


def _rpy_matrix(rpy: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    (cr, cp, cy), (sr, sp, sy) = np.cos(rpy), np.sin(rpy)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


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
        raise RcmKinError(f"{where}: missing or empty '{key}'" if key not in entry or value == "" else
                          f"{where}: '{key}' must be a text (a name), got {value!r}"[:200])
    return value


SIDECAR_KEYS = {"robot", "urdf", "actuated", "frames", "counterweights", "drive", "loop", "passive", "rcm", "base"}
ENTRY_KEYS = {"loop": {"name", "link_a", "point_a", "link_b", "point_b", "plane_normal"},
              "passive": {"joint", "follows", "multiplier", "offset"},
              "rcm": {"shaft_frame", "joints", "base_frame"}}


def _check_keys(raw: dict, where: str) -> None:
    """Every key of the sidecar is one it knows: a misspelt key (``drvie``, ``[bsae]``) would
    otherwise drop a calibration or a tilt without a word."""
    if unknown := sorted(set(raw) - SIDECAR_KEYS):
        raise RcmKinError(f"{where}: unknown keys {unknown} (known: {', '.join(sorted(SIDECAR_KEYS))})")
    for table, known in ENTRY_KEYS.items():
        entries = raw.get(table, [])
        entries = [entries] if isinstance(entries, dict) else entries
        if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
            form = "a table [rcm]" if table == "rcm" else f"[[{table}]] tables"
            raise RcmKinError(f"{where}: '{table}' must be {form}")
        for i, entry in enumerate(entries):
            if unknown := sorted(set(entry) - known):
                at = f"[{table}]" if table == "rcm" else f"{table} {i + 1}"
                raise RcmKinError(f"{where}: {at}: unknown keys {unknown} (known: {', '.join(sorted(known))})")


def read_description(path: str | Path, text: str | None = None) -> RobotDescription:
    """Read and check a sidecar file (``text``: its content, already read); errors name the file
    and the entry at fault."""
    path = Path(path)
    raw = read_toml(path, "robot description", text)

    where = str(path)
    _check_keys(raw, where)
    urdf = path.parent / _text(raw, "urdf", where)
    if not urdf.exists():
        raise RcmKinError(f"{where}: URDF file {urdf} does not exist")
    actuated = raw.get("actuated", ())
    if not isinstance(actuated, (list, tuple)) or not all(isinstance(n, str) and n for n in actuated):
        raise RcmKinError(f"{where}: 'actuated' must be a list of joint names (leave it out for every joint)")
    if "actuated" in raw and not actuated:
        raise RcmKinError(f"{where}: 'actuated' must not be empty (leave it out for every joint)")
    frames = raw.get("frames", ())
    if not isinstance(frames, (list, tuple)) or not all(isinstance(n, str) and n for n in frames):
        raise RcmKinError(f"{where}: 'frames' must be a list of link names")
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
        if not (isinstance(joints, list) and len(joints) == 2 and all(isinstance(j, str) for j in joints)
                and (not actuated or all(j in actuated for j in joints))):
            raise RcmKinError(f"{at}: 'joints' must name two actuated joints")
        rcm = RcmDescription(_text(entry, "shaft_frame", at), tuple(joints), entry.get("base_frame"))
    drive = None
    if "drive" in raw:
        drive = path.parent / _text(raw, "drive", where)
        if not drive.is_file():
            raise RcmKinError(f"{where}: drive parameter file {drive} does not exist")
    robot = _text(raw, "robot", where) if "robot" in raw else ""
    base_rpy, gravity = _base_gravity(raw, where)
    return RobotDescription(
        robot=robot, urdf=urdf, drive=drive, actuated=tuple(actuated),
        frames=tuple(frames), loops=tuple(loops), passive=tuple(passive),
        counterweights=tuple(raw.get("counterweights", ())), rcm=rcm, base_rpy=base_rpy, gravity=gravity)


def urdf_alone(urdf: str | Path) -> RobotDescription:
    """The description of a URDF without a sidecar: every default (see :class:`RobotDescription`),
    no loops, no RCM, no drive, an untilted base."""
    return RobotDescription(robot="", urdf=Path(urdf), actuated=(), frames=(), loops=(), passive=())

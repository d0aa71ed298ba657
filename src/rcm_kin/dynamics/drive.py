"""The drive: joint torque -> motor torque -> current -> voltage -> PWM counts, and back.

Per driven joint (PSM roll, pitch, insertion): a brushed DC motor behind a transmission of
ratio ``gear_ratio`` (motor rad per joint rad, or per metre for the insertion), driven by an
8-bit sign-magnitude PWM driver. With the joint at velocity ``v``:

    tau_motor = tau / gear_ratio                      (N m)
    current   = tau_motor / torque_constant           (A)
    voltage   = resistance * current + torque_constant * gear_ratio * v   (V)
    pwm       = pwm_sign * voltage / volts_per_pwm    (counts; hardware sign)

A drive file describes one robot (its ``robot`` key) and the actuated joints it has tables for:
every top-level table other than ``[gravity_offsets]``, ``[drive_train.<joint>]`` and ``[uncertainty]``
(:mod:`rcm_kin.dynamics.drive_uncertainty`) is a joint
table. The order of the tables in the file means nothing: :attr:`DriveParameters.driven`, the order
of every per-joint array, is the robot's actuated order. A file of the bundled PSM has exactly its
three driven joints, :data:`DRIVEN` (roll, pitch, insertion: its actuated order) as soon as it is
read; any other robot's joints are put in its actuated order by :func:`check_drive`, which every
use of a drive on a robot goes through. The bundled PSM's lives in ``urdf/psm_drive.toml`` beside
its sidecar (documented there); the shipped set is the calibrated one
(:mod:`rcm_kin.identification.calibration`). For the bundled PSM the PWM saturation is not a drive
constant: it comes from the firmware,
:data:`rcm_kin.hardware.PWM_LIMIT` (older files that still carry a ``pwm_limit`` key load when it
agrees); a drive file of any other robot gives ``pwm_limit`` (counts) in each joint table.
"""

from __future__ import annotations

import os
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Final

import numpy as np

from rcm_kin.atomic import write_text
from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.dynamics.drive_schema import (
    DRIVE_TRAIN,
    DRIVE_TRAIN_DEFAULT,
    JOINT_DRIVE,
    TABLES,
    check_offset,
    check_table,
    joint_tables,
)
from rcm_kin.dynamics.drive_uncertainty import DriveUncertainty, parse_uncertainty, uncertainty_lines
from rcm_kin.errors import ParameterFileError, RcmKinError, RcmKinWarning, read_text, read_toml, warn
from rcm_kin.hardware import PWM_LIMIT
from rcm_kin.model.loading import urdf_dir

DEFAULT_PARAMETERS = urdf_dir() / "psm_drive.toml"   # the bundled PSM's calibration (its sidecar names it)
SHIPPED_ROBOT = "psm"       # the robot a drive file that names none is taken to describe (older files)
DRIVEN = ("roll", "pitch", "insertion")   # the bundled PSM's (its PSM-specific code); generic code: params.driven
FIRMWARE_FIELDS = ("pwm_limit",)   # JointDrive fields set from rcm_kin.hardware, not read from the file


@dataclass(frozen=True)
class JointDrive:
    """Drive constants of one joint (SI; PWM in counts)."""

    gear_ratio: float
    torque_constant: float
    resistance: float
    volts_per_pwm: float
    pwm_sign: float
    pwm_limit: float                 # counts: the firmware saturation (the PSM's: rcm_kin.hardware.PWM_LIMIT)
    rotor_inertia: float
    viscous: float
    coulomb: float
    coulomb_velocity: float = 0.02   # rad/s (m/s): width of the smoothed Coulomb law tanh(v / width)
    extra_inertia: float = 0.0       # kg m^2 (kg) at the joint the CAD lacks (drums, cables): grey-box

    @property
    def pwm_per_torque(self) -> float:
        """Static gain: PWM counts per joint N m (N), hardware sign included."""
        return self.pwm_sign * self.resistance / (self.torque_constant * self.gear_ratio * self.volts_per_pwm)

    @property
    def reflected_inertia(self) -> float:
        """Drive-side inertia at the joint: the rotor's reflected through the transmission plus the
        identified extra inertia (kg m^2, or kg for the insertion)."""
        return self.rotor_inertia * self.gear_ratio**2 + self.extra_inertia


@dataclass(frozen=True)
class DriveParameters:
    """The drives of the driven joints and the calibrated gravity offsets."""

    joints: dict[str, JointDrive]
    gravity_offsets: dict[str, np.ndarray]   # link -> first moment (kg m) in the link's frame
    source: str = ""
    drive_train: dict[str, AxisFriction] = field(default_factory=dict)   # identified stick-slip model per joint
    robot: str = SHIPPED_ROBOT   # the robot the file describes (its ``robot`` key)
    uncertainty: DriveUncertainty = field(default_factory=DriveUncertainty)   # its [uncertainty] tables

    def __getitem__(self, joint: str) -> JointDrive:
        return self.joints[joint]

    @property
    def driven(self) -> tuple[str, ...]:
        """The joints this file describes in the robot's actuated order (the order of every per-joint
        array), whatever the order of their tables in the file: :data:`DRIVEN` for the bundled PSM,
        set on reading; any other robot's once :func:`check_drive` has checked them against it."""
        return tuple(self.joints)

    @property
    def model(self) -> str:
        """Which model an output used, for people: ``calibration <file>``."""
        return f"calibration {Path(self.source).name}" if self.source else "calibration (in memory)"


@dataclass(frozen=True)
class DriveEffort:
    """What the drives must do, per driven joint (arrays of shape (..., n) in ``params.driven`` order)."""

    tau: np.ndarray            # joint torque/force (N m, N)
    motor_torque: np.ndarray   # N m
    current: np.ndarray        # A
    voltage: np.ndarray        # V (positive = increases the joint)
    pwm: np.ndarray            # counts, hardware sign, before saturation
    saturated: np.ndarray      # bool: |pwm| above the firmware limit


def load_drive_parameters(path: str | Path | None = None) -> DriveParameters:
    """Read a drive parameter file (default: the shipped, calibrated one of the bundled PSM). Its
    joint tables (every top-level table but ``[gravity_offsets]`` and ``[drive_train]``) are the
    driven joints: the bundled PSM's are exactly :data:`DRIVEN`, in that order whatever the file's
    (another table is an error naming it); any other robot's are in file order until
    :func:`check_drive` puts them in the robot's actuated order. The PSM's ``pwm_limit`` is the firmware's
    (:data:`rcm_kin.hardware.PWM_LIMIT`), any other robot's is read from each joint table. Every
    value is checked against its unit and range (:mod:`rcm_kin.dynamics.drive_schema`)."""
    if path is not None and not isinstance(path, (str, Path)):
        raise RcmKinError(f"`path` is a drive parameter file's path, got {type(path).__name__}", parameter="path")
    path = Path(path) if path is not None else DEFAULT_PARAMETERS
    try:
        text = read_text(path, "drive parameter file")
    except (OSError, UnicodeDecodeError):
        text = None                          # read_toml says what is wrong with the file
    key = (os.path.abspath(path), text)
    if text is not None and key in _PARSED:  # the same bytes parsed and checked before (a hot path: every
        return _PARSED[key]                  # holding effort, map and model of a robot reads its drive)
    params = _parsed(path, read_toml(path, "drive parameter file", text))
    if text is not None:
        if len(_PARSED) >= 32:
            _PARSED.pop(next(iter(_PARSED)))
        _PARSED[key] = params
    return params


_PARSED: dict[tuple[str, str], DriveParameters] = {}   # (file, its text) -> its parameters, checked


def _parsed(path: Path, raw: dict) -> DriveParameters:
    """The checked parameters of the drive file ``path`` parsed as ``raw``."""
    robot = raw.get("robot", None)
    if robot is None:
        warn(f"{path}: names no robot (a `robot = \"...\"` line); taken as the {SHIPPED_ROBOT}'s", RcmKinWarning)
        robot = SHIPPED_ROBOT
    elif not isinstance(robot, str) or not robot:
        raise ParameterFileError(f"{path}: robot must be the name of the robot the file describes, got {robot!r}"[:300],
                                 path=path, table=None, key="robot")
    tables = joint_tables(raw, path)
    if not tables:
        raise ParameterFileError(f"{path}: describes no joint (one table [<joint>] per driven joint)", path=path,
                                 table=None, key=None)
    firmware = dict(zip(DRIVEN, PWM_LIMIT)) if robot == SHIPPED_ROBOT else {}
    if firmware:                             # the PSM's code takes its three driven joints, in DRIVEN order
        if extra := [joint for joint in tables if joint not in DRIVEN]:
            raise ParameterFileError(f"{path}: [{extra[0]}] is not a driven joint of the bundled {SHIPPED_ROBOT}: its "
                                     f"drive file has the joint tables {', '.join(DRIVEN)} only (the joints its "
                                     f"firmware drives) and the tables {', '.join(TABLES)}", path=path,
                                     table=extra[0], key=None)
        tables = {joint: tables.get(joint) for joint in DRIVEN}
    joints = {joint: _joint_drive(path, joint, entry, firmware.get(joint)) for joint, entry in tables.items()}
    offsets = {}
    if not isinstance(raw.get("gravity_offsets", {}), dict):
        raise ParameterFileError(f"{path}: gravity_offsets must be a table [gravity_offsets] of 3-number lists (kg m)",
                                 path=path, table="gravity_offsets")
    for link, value in raw.get("gravity_offsets", {}).items():
        offsets[link] = np.array(check_offset(value, path, link))
    return DriveParameters(joints, offsets, str(path), _drive_train(path, raw.get("drive_train", {}), tuple(joints)),
                           robot, parse_uncertainty(path, raw.get("uncertainty"), tuple(joints)))


def _joint_drive(path: Path, joint: str, entry, limit: float | None) -> JointDrive:
    """One joint table: its constants checked; ``pwm_limit`` the firmware's ``limit`` when given
    (a key in the file must then agree), else required in the table."""
    names = [f.name for f in fields(JointDrive) if f.name not in FIRMWARE_FIELDS]
    required = [f.name for f in fields(JointDrive) if f.default is MISSING and f.name in names]
    required += [] if limit is not None else list(FIRMWARE_FIELDS)
    if not isinstance(entry, dict) or set(required) - set(entry):
        absent = [k for k in required if k not in entry] if isinstance(entry, dict) else list(required)
        raise ParameterFileError(f"{path}: [{joint}] needs {', '.join(absent)}"
                                 + (" (pwm_limit: the firmware's saturation, counts)"
                                    if "pwm_limit" in absent else ""),
                                 path=path, table=joint, key=absent[0])
    unknown = sorted(set(entry) - set(names) - set(FIRMWARE_FIELDS))
    if unknown:
        raise ParameterFileError(f"{path}: [{joint}] has unknown keys {', '.join(unknown)} "
                                 f"(known: {', '.join(names + list(FIRMWARE_FIELDS))})", path=path, table=joint,
                                 key=unknown[0])
    values = check_table(entry, JOINT_DRIVE, path, joint)
    if limit is None:
        return JointDrive(**{n: values[n] for n in names if n in values}, pwm_limit=values["pwm_limit"])
    legacy = values.get("pwm_limit", float(limit))
    if legacy != limit:
        raise ParameterFileError(f"{path}: [{joint}] pwm_limit = {legacy:g} differs from the firmware's {limit:g} "
                                 "counts (rcm_kin/hardware.py PWM_LIMIT); drive files no longer set it: remove the "
                                 "key (a simulation takes other limits through FirmwareSettings, `pwm_limit`)",
                                 path=path, table=joint, key="pwm_limit", parameter="pwm_limit")
    return JointDrive(**{n: values[n] for n in names if n in values}, pwm_limit=float(limit))


def check_drive(robot, params: DriveParameters) -> DriveParameters:
    """``params`` if they describe ``robot`` (same name, joints and links that exist), with their
    joints in the robot's actuated order (:attr:`DriveParameters.driven`), else a one-line
    :class:`~rcm_kin.errors.ParameterFileError`: a calibration is never applied to another robot."""
    where = params.source or "the drive parameters"
    if params.robot != robot.name:
        raise ParameterFileError(f"{where} describes robot '{params.robot}', not '{robot.name}': give the drive "
                                 f"parameters of {robot.name} (or none: its URDF inertias, torque only)",
                                 path=params.source, table=None, key="robot", parameter="drive")
    if missing := [j for j in params.driven if j not in robot.actuated]:
        raise ParameterFileError(f"{where}: joints {', '.join(missing)} are not actuated joints of {robot.name} "
                                 f"({', '.join(robot.actuated)})", path=params.source, table=missing[0], key=None,
                                 parameter="drive")
    if links := [link for link in params.gravity_offsets if not robot.tree.existBodyName(link)]:
        raise ParameterFileError(f"{where}: [gravity_offsets] links {', '.join(links)} are not links of {robot.name}",
                                 path=params.source, table="gravity_offsets", key=links[0], parameter="drive")
    order = tuple(j for j in robot.actuated if j in params.joints)
    return params if order == params.driven else replace(params, joints={j: params.joints[j] for j in order})


def robot_drive(robot) -> DriveParameters | None:
    """The drive parameters the robot's sidecar names (its ``drive`` key), checked against the robot;
    None when it names none: the robot then runs on its URDF inertias, torque only."""
    path = robot.description.drive
    return None if path is None else check_drive(robot, load_drive_parameters(path))


CAD: Final = "cad"   # a `drive` argument asking for no drive: the URDF inertias, torque only


def resolve_drive(robot, drive=None) -> DriveParameters | None:
    """The one rule for which drive a result of ``robot`` uses: ``None`` the robot's own
    (:func:`robot_drive`; None when its sidecar names none), :data:`CAD` none (the URDF inertias),
    else ``drive`` (DriveParameters, or the path of a drive file) checked against the robot
    (:func:`check_drive`: a file of another robot is a one-line error)."""
    if drive is None:
        return robot_drive(robot)
    if isinstance(drive, str) and drive == CAD:
        return None
    if isinstance(drive, (str, Path)):
        drive = load_drive_parameters(drive)
    if not isinstance(drive, DriveParameters):
        raise RcmKinError(f"`drive` is DriveParameters, the path of a drive file, None (the robot's own) or {CAD!r} "
                          f"(none), got {type(drive).__name__}", parameter="drive")
    return check_drive(robot, drive)


def model_label(params: DriveParameters | None) -> str:
    """Which model an output used: ``CAD (URDF inertias)`` or ``calibration <file>``."""
    return "CAD (URDF inertias)" if params is None else params.model


def _drive_train(path: Path, raw, driven: tuple[str, ...]) -> dict[str, AxisFriction]:
    """The ``[drive_train.<joint>]`` tables: the identified stick-slip model of each joint. Values
    are numbers (not booleans) in the ranges of :data:`rcm_kin.dynamics.drive_schema.DRIVE_TRAIN`:
    finite, >= 0 but for the presliding slope (|s| <= 20 /rad), a Stribeck velocity > 0, and the
    presliding elements a whole number 1..4 (absent: 1)."""
    known = [f.name for f in fields(AxisFriction)]
    if not isinstance(raw, dict):
        raise ParameterFileError(f"{path}: drive_train must be tables [drive_train.<joint>] ({', '.join(driven)})",
                                 path=path, table="drive_train")
    out = {}
    for joint, entry in raw.items():
        if joint not in driven:
            raise ParameterFileError(f"{path}: [drive_train.{joint}] is not a joint of the file ({', '.join(driven)})",
                                     path=path, table=f"drive_train.{joint}")
        if not isinstance(entry, dict):
            raise ParameterFileError(f"{path}: drive_train.{joint} must be a table [drive_train.{joint}] of parameters",
                                     path=path, table=f"drive_train.{joint}")
        unknown = sorted(set(entry) - set(known))
        if unknown:
            raise ParameterFileError(f"{path}: [drive_train.{joint}] has unknown keys {', '.join(unknown)} "
                                     f"(known: {', '.join(known)})", path=path, table=f"drive_train.{joint}",
                                     key=unknown[0])
        out[joint] = AxisFriction(**check_table(entry, DRIVE_TRAIN, path, f"drive_train.{joint}", DRIVE_TRAIN_DEFAULT))
    return out


def write_parameters(params: DriveParameters, path: str | Path, header: str = "") -> Path:
    """Write a drive parameter file in the format :func:`load_drive_parameters` reads."""
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    lines += ["", f"robot = {params.robot!r}".replace("'", '"')]
    for joint, drive in params.joints.items():
        firmware = FIRMWARE_FIELDS if params.robot == SHIPPED_ROBOT and joint in DRIVEN else ()
        values = {k: v for k, v in vars(drive).items() if k not in firmware}
        lines += ["", f"[{joint}]"] + [f"{k} = {float(v)!r}" for k, v in values.items()]
    lines += ["", "[gravity_offsets]"]
    lines += [f"{link} = [{', '.join(repr(float(x)) for x in h)}]" for link, h in params.gravity_offsets.items()]
    for joint, friction in params.drive_train.items():
        lines += ["", f"[drive_train.{joint}]"] + [f"{k} = {float(v)!r}" for k, v in friction.as_dict().items()]
    lines += uncertainty_lines(params.uncertainty)
    path = Path(path)
    try:
        write_text(path, "\n".join(lines) + "\n")
    except OSError as exc:
        raise RcmKinError(f"cannot write the parameter file {path}: {exc.strerror}") from None
    return path


def with_joint(params: DriveParameters, joint: str, **changes) -> DriveParameters:
    """A copy of ``params`` with some constants of one joint changed."""
    joints = dict(params.joints)
    joints[joint] = replace(joints[joint], **changes)
    return replace(params, joints=joints)


def _constants(params: DriveParameters, *names: str) -> tuple[np.ndarray, ...]:
    """Per driven joint (``params.driven`` order), one array per constant named."""
    return tuple(np.array([getattr(params[j], a) for j in params.driven]) for a in names)


def drive_effort(params: DriveParameters, tau, v=None) -> DriveEffort:
    """Motor torque, current, voltage and PWM for joint torques ``tau`` (..., n) of the driven
    joints (``params.driven``, n of them) at joint velocities ``v`` (default 0: holding)."""
    tau = np.asarray(tau, dtype=float)
    n = len(params.driven)
    if tau.shape[-1:] != (n,):
        where = params.source or "the drive parameters"
        raise RcmKinError(f"{where} describe {n} joints ({', '.join(params.driven)}), given torques of "
                          f"{tau.shape[-1] if tau.ndim else 1}", parameter="drive")
    v = np.zeros_like(tau) if v is None else np.broadcast_to(np.asarray(v, dtype=float), tau.shape)
    gear, kt, res, vpp, sign, limit = _constants(params, "gear_ratio", "torque_constant", "resistance",
                                                 "volts_per_pwm", "pwm_sign", "pwm_limit")
    motor_torque = tau / gear
    current = motor_torque / kt
    voltage = res * current + kt * gear * v
    pwm = sign * voltage / vpp
    return DriveEffort(tau, motor_torque, current, voltage, pwm, np.abs(pwm) > limit)


def pwm_to_torque(params: DriveParameters, pwm) -> np.ndarray:
    """Static joint torque (..., n) produced by PWM counts (..., n) at zero velocity (``params.driven`` order)."""
    pwm = np.asarray(pwm, dtype=float)
    return pwm / np.array([params[j].pwm_per_torque for j in params.driven])

"""Read a PSM gain schedule back from its ``gains.json`` (what ``rcm-kin schedule psm`` writes, and
the shipped tuned design :data:`SHIPPED_TUNED`), with the law's options it was written for.

The file's tables (``k_roll``, ``k_pitch``, ``ff_pitch``, ``u_hold`` when the gravity feedforward
was exported, ``friction_feedforward`` when the friction compensation was) and its ``points``' linear
models give a :class:`~rcm_kin.control.gain_schedule.GainSchedule`; its ``"controller"`` entry
(``scheduled``, ``gravity``, ``track_velocity``, ``friction``) the law's options, which default, for
a file written before the entry existed, to what the file can run: scheduled, velocity error, and
the feedforwards it carries. Every table is checked against the grid's shape and for finite values:
a file that does not fit is a one-line error naming the key.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.control.friction import FrictionCompensation
from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.control.weights import Weights
from rcm_kin.errors import RcmKinError
from rcm_kin.model.loading import urdf_dir

SHIPPED_TUNED = urdf_dir() / "psm_tuned" / "gains.json"   # `rcm-kin schedule psm --tune` on the shipped drive file
MAX_BYTES = 16 * 2**20                                    # a 41 x 41 schedule's file is about 4 MB
FLAGS = ("scheduled", "gravity", "track_velocity", "friction")


@dataclass(frozen=True)
class ScheduleFile:
    """A gain schedule read from its file, the law's options (:data:`FLAGS`) and the file's path."""

    schedule: GainSchedule
    flags: dict[str, bool]
    path: Path


def _fail(path: Path, message: str, key: str | None = None) -> RcmKinError:
    where = f" (key {key!r})" if key else ""
    return RcmKinError(f"{path}: {message}{where}; give the gains.json that rcm-kin schedule psm [--tune] wrote",
                       parameter="gains")


def _table(raw: dict, key: str, shape: tuple[int, ...], path: Path) -> np.ndarray:
    try:
        value = np.asarray(raw[key], dtype=float)
    except KeyError:
        raise _fail(path, "missing table", key) from None
    except (TypeError, ValueError):
        raise _fail(path, "a table of numbers is expected", key) from None
    if value.shape != shape or not np.all(np.isfinite(value)):
        raise _fail(path, f"expected finite numbers of shape {shape}, got shape {value.shape}", key)
    return value


def _read(path: Path) -> dict:
    try:
        if path.stat().st_size > MAX_BYTES:
            raise _fail(path, f"larger than {MAX_BYTES // 2**20} MiB: not a gain schedule")
        raw = json.loads(path.read_text())
    except OSError as exc:
        raise RcmKinError(f"cannot read the gain schedule {path}: {exc.strerror}", parameter="gains") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise _fail(path, f"not JSON ({exc})") from None
    if not isinstance(raw, dict):
        raise _fail(path, "a JSON object (gains.json of rcm-kin schedule) is expected")
    return raw


def read_schedule_file(path: str | Path | None = None) -> ScheduleFile:
    """The schedule in ``path`` (default :data:`SHIPPED_TUNED`) and its law's options (see the module's notes)."""
    path = Path(path) if path is not None else SHIPPED_TUNED
    raw = _read(path)
    for key in ("roll_deg", "pitch_deg", "points"):
        if not isinstance(raw.get(key), list):
            raise _fail(path, "a list is expected", key)
    roll = _table(raw, "roll_deg", (len(raw["roll_deg"]),), path)
    pitch = _table(raw, "pitch_deg", (len(raw["pitch_deg"]),), path)
    if roll.size < 2 or pitch.size < 2 or np.any(np.diff(roll) <= 0) or np.any(np.diff(pitch) <= 0):
        raise _fail(path, "the grids need at least 2 strictly increasing values", "roll_deg/pitch_deg")
    grid = (pitch.size, roll.size)
    points = raw.get("points")
    if not isinstance(points, list) or len(points) != roll.size * pitch.size:
        raise _fail(path, f"one entry per grid point ({roll.size * pitch.size}) expected", "points")
    models = {k: np.array([_table(p, k, shape, path) for p in points]).reshape(*grid, *shape)
              for k, shape in (("A", (6, 6)), ("B", (6, 3)), ("A_cl", (7, 7)))}
    has = {"gravity": "u_hold" in raw, "friction": "friction_feedforward" in raw}
    u_hold = _table(raw, "u_hold", (*grid, 2), path) if has["gravity"] else np.zeros((*grid, 2))
    friction = None
    if has["friction"]:
        fc = raw["friction_feedforward"]
        try:
            friction = FrictionCompensation(tuple(fc["pwm"]), float(fc["ramp_deg_s"]))
        except (KeyError, TypeError, ValueError):
            raise _fail(path, "pwm (2 counts) and ramp_deg_s expected", "friction_feedforward") from None
    try:
        weights = Weights(**raw.get("weights", {}))
    except TypeError:
        raise _fail(path, "unknown weight names", "weights") from None
    insertion = raw.get("insertion_m")
    if isinstance(insertion, bool) or not isinstance(insertion, (int, float)) or not np.isfinite(insertion):
        raise _fail(path, "the insertion of the models, a number of metres, is expected", "insertion_m")
    k_pitch = _table(raw, "k_pitch", (*grid, 3), path)
    if np.any(k_pitch[..., 2] <= 0):
        raise _fail(path, "the pitch Ki must be > 0 PWM/(deg s) at every grid point (the law's integral holds the "
                    "pose with it)", "k_pitch")
    schedule = GainSchedule(roll, pitch, float(insertion),
                            _table(raw, "k_roll", (*grid, 2), path), k_pitch, u_hold,
                            _table(raw, "ff_pitch", (*grid, 2), path), models["A"], models["B"], models["A_cl"],
                            weights, friction)
    flags = {"scheduled": True, "gravity": has["gravity"], "track_velocity": True, "friction": has["friction"]}
    stated = raw.get("controller", {})
    if not isinstance(stated, dict):
        raise _fail(path, "an object of the law's options expected", "controller")
    for name in FLAGS:
        if name in stated:
            if not isinstance(stated[name], bool):
                raise _fail(path, f"{name} is true or false", "controller")
            flags[name] = stated[name]
    for name in ("gravity", "friction"):
        if flags[name] and not has[name]:
            raise _fail(path, f"the law adds the {name} feedforward but the file has no table of it", "controller")
    return ScheduleFile(schedule, flags, path)

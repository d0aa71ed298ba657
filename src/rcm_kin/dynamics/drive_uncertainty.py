"""What a drive parameter file knows about its own uncertainty: the ``[uncertainty]`` tables.

Written by the identification and the calibration, read with the rest of the file
(:func:`rcm_kin.dynamics.drive.load_drive_parameters`), used by the prediction and holding bands:

    [uncertainty.hull]                  per joint [lo, hi] rad: the poses the calibration saw
    roll = [-0.26, 0.35]
    [uncertainty.holding_residuals]     per joint: leave-one-hold-out residuals, PWM counts
    roll = [1.2, -0.4, ...]             (measured minus predicted, each hold left out of its fit)
    [uncertainty.ranges.roll]           parameters the logs do not determine: the range over which
    presliding_force = [0.9, 5.0]       the fit on every log stays as good (SI)
    [uncertainty.preloads]              per joint: the presliding spring's force at the first rest of
    roll = [-0.3, 0.1, 0.2]             each step log inside the calibrated poses that shows it (its
                                        best preload), as a fraction of its slip force
    [uncertainty.discrepancy]           per joint: each such log's widening score under its left-out
    roll = [0.4, 1.2, 0.1]              band (how far it had to widen, in the median's travel)
    [[uncertainty.folds.roll]]          one table per leave-one-log-out fold: the log it left out
    left_out = "roll_step_...csv"       and its drive-train parameters (AxisFriction's keys)
    extra_inertia = 0.7
    ...

Every part is optional: a file without ``[uncertainty]`` has none (the bands then say so).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field, fields

import numpy as np

from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.dynamics.drive_schema import DRIVE_TRAIN, DRIVE_TRAIN_DEFAULT, Range, check_table
from rcm_kin.errors import ParameterFileError

ANGLE = Range("rad", -np.pi, np.pi)
RESIDUAL = Range("PWM counts", -255.0, 255.0)
PRELOAD = Range("fraction of the slip force", -1.0, 1.0)
SCORE = Range("median travels", 0.0, 1e9)
PARTS = ("hull", "holding_residuals", "ranges", "folds", "preloads", "discrepancy")


@dataclass(frozen=True)
class FoldSet:
    """The drive-train parameters fitted on every log but ``left_out``."""

    left_out: str
    friction: AxisFriction


@dataclass(frozen=True)
class DriveUncertainty:
    """Per joint: the leave-one-log-out parameter sets, the ranges of the parameters the logs do not
    determine (SI), the leave-one-hold-out holding residuals (PWM counts, measured minus predicted),
    the range of poses the calibration saw (rad) and the presliding preloads the logs'
    first rests show (fractions of the slip force)."""

    folds: dict[str, tuple[FoldSet, ...]] = field(default_factory=dict)
    ranges: dict[str, dict[str, tuple[float, float]]] = field(default_factory=dict)
    holding_residuals: dict[str, np.ndarray] = field(default_factory=dict)
    hull: dict[str, tuple[float, float]] = field(default_factory=dict)
    preloads: dict[str, tuple[float, ...]] = field(default_factory=dict)
    discrepancy: dict[str, tuple[float, ...]] = field(default_factory=dict)

    def __bool__(self) -> bool:
        return any((self.folds, self.ranges, self.holding_residuals, self.hull, self.preloads, self.discrepancy))


def _error(path, key: str, text: str) -> ParameterFileError:
    return ParameterFileError(f"{path}: [uncertainty.{key}] {text}"[:300], path=path, table=f"uncertainty.{key}",
                              key=key)


def _pair(value, rule: Range, path, key: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise _error(path, key, f"must be [lo, hi] ({rule.unit})")
    lo, hi = (rule.check(v, path, f"uncertainty.{key}", str(i)) for i, v in enumerate(value))
    if lo > hi:
        raise _error(path, key, f"has lo {lo:.6g} above hi {hi:.6g}")
    return lo, hi


def _numbers(value, rule: Range, path, part: str, joint: str) -> tuple[float, ...]:
    if not isinstance(value, list) or not value:
        raise _error(path, f"{part}.{joint}", f"must be a list of numbers ({rule.unit})")
    return tuple(rule.check(x, path, f"uncertainty.{part}", joint) for x in value)


def _joint_tables(raw, path, part: str, driven) -> dict:
    if not isinstance(raw, dict):
        raise _error(path, part, "must be a table keyed by joint")
    if unknown := [j for j in raw if j not in driven]:
        raise _error(path, part, f"names {unknown[0]}, not a joint of the file ({', '.join(driven)})")
    return raw


def parse_uncertainty(path, raw, driven) -> DriveUncertainty:
    """The ``[uncertainty]`` tables of the drive file ``path`` (``raw``: its parsed TOML value), checked:
    joints of the file, numbers in range, each error naming the file and the table."""
    if raw is None:
        return DriveUncertainty()
    if not isinstance(raw, dict) or (unknown := sorted(set(raw) - set(PARTS))):
        raise ParameterFileError(f"{path}: [uncertainty] holds the tables {', '.join(PARTS)} only"
                                 + (f" (not {unknown[0]})" if isinstance(raw, dict) else ""), path=path,
                                 table="uncertainty", key=None)
    hull = {j: _pair(v, ANGLE, path, f"hull.{j}")
            for j, v in _joint_tables(raw.get("hull", {}), path, "hull", driven).items()}
    preloads, discrepancy = ({j: _numbers(v, rule, path, part, j)
                              for j, v in _joint_tables(raw.get(part, {}), path, part, driven).items()}
                             for part, rule in (("preloads", PRELOAD), ("discrepancy", SCORE)))
    residuals = {}
    for j, v in _joint_tables(raw.get("holding_residuals", {}), path, "holding_residuals", driven).items():
        if not isinstance(v, list) or not v:
            raise _error(path, f"holding_residuals.{j}", "must be a list of numbers (PWM counts)")
        residuals[j] = np.array([RESIDUAL.check(x, path, "uncertainty.holding_residuals", j) for x in v])
    known = [f.name for f in fields(AxisFriction)]
    ranges = {}
    for j, table in _joint_tables(raw.get("ranges", {}), path, "ranges", driven).items():
        if not isinstance(table, dict) or any(n not in known for n in table):
            raise _error(path, f"ranges.{j}", f"must name drive-train parameters ({', '.join(known)})")
        ranges[j] = {n: _pair(v, DRIVE_TRAIN.get(n, DRIVE_TRAIN_DEFAULT), path, f"ranges.{j}.{n}")
                     for n, v in table.items()}
    folds = {}
    for j, sets in _joint_tables(raw.get("folds", {}), path, "folds", driven).items():
        if not isinstance(sets, list) or not all(isinstance(s, dict) for s in sets):
            raise _error(path, f"folds.{j}", "must be tables [[uncertainty.folds.<joint>]]")
        out = []
        for s in sets:
            entry = dict(s)
            left_out = entry.pop("left_out", None)
            if not isinstance(left_out, str):
                raise _error(path, f"folds.{j}", "each fold names the log it left out (left_out = \"...\")")
            if unknown := sorted(set(entry) - set(known)):
                raise _error(path, f"folds.{j}", f"has unknown key {unknown[0]} (known: left_out, {', '.join(known)})")
            values = check_table(entry, DRIVE_TRAIN, path, f"uncertainty.folds.{j}", DRIVE_TRAIN_DEFAULT)
            out.append(FoldSet(left_out, AxisFriction(**values)))
        folds[j] = tuple(out)
    return DriveUncertainty(folds, ranges, residuals, hull, preloads, discrepancy)


def uncertainty_lines(u: DriveUncertainty) -> list[str]:
    """``u`` as the TOML lines :func:`parse_uncertainty` reads (none when it is empty)."""
    def numbers(values) -> str:
        return "[" + ", ".join(repr(float(x)) for x in values) + "]"

    lines = []
    if u.hull:
        lines += ["", "[uncertainty.hull]"] + [f"{j} = {numbers(v)}" for j, v in u.hull.items()]
    if u.holding_residuals:
        lines += ["", "[uncertainty.holding_residuals]"]
        lines += [f"{j} = {numbers(v)}" for j, v in u.holding_residuals.items()]
    if u.preloads:
        lines += ["", "[uncertainty.preloads]"] + [f"{j} = {numbers(v)}" for j, v in u.preloads.items()]
    if u.discrepancy:
        lines += ["", "[uncertainty.discrepancy]"] + [f"{j} = {numbers(v)}" for j, v in u.discrepancy.items()]
    for j, table in u.ranges.items():
        lines += ["", f"[uncertainty.ranges.{j}]"] + [f"{n} = {numbers(v)}" for n, v in table.items()]
    for j, sets in u.folds.items():
        for s in sets:
            lines += ["", f"[[uncertainty.folds.{j}]]", f"left_out = {json.dumps(s.left_out)}"]
            lines += [f"{k} = {float(v)!r}" for k, v in s.friction.as_dict().items()]
    return lines

"""What a drive parameter file may hold: per key its unit and valid range, checked once where the
file is read (:func:`rcm_kin.dynamics.drive.load_drive_parameters`), with the file and key named.

The ranges are physical plausibility bounds for a small brushed-DC cable-driven robot, wide enough
for any calibration or identification of this hardware and narrow enough that a value outside them
is a typing or unit error (a zero gear ratio, a negative resistance, NaN). One line per key: a key
added to :class:`~rcm_kin.dynamics.stick_slip.AxisFriction` without a line here is checked as a
finite number >= 0 (:data:`DRIVE_TRAIN_DEFAULT`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from rcm_kin.dynamics.axis_friction import MAX_ELEMENTS
from rcm_kin.errors import ParameterFileError


@dataclass(frozen=True)
class Range:
    """A finite number in ``[lo, hi]`` (``lo`` excluded when ``open_lo``; a whole number when
    ``whole``) of ``unit``."""

    unit: str
    lo: float
    hi: float
    open_lo: bool = False
    whole: bool = False

    def check(self, value, path: Path | str, table: str, key: str) -> float:
        """``value`` as a float, or an error naming the file, the table and the key."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterFileError(f"{path}: [{table}] {key} must be a number ({self.unit}), got {value!r}"[:300],
                                     path=path, table=table, key=key)
        value = float(value)
        if not math.isfinite(value) or value < self.lo or value > self.hi or (self.open_lo and value == self.lo):
            raise ParameterFileError(f"{path}: [{table}] {key} = {value:.6g} is outside {self.text()}",
                                     path=path, table=table, key=key)
        if self.whole and not value.is_integer():
            raise ParameterFileError(f"{path}: [{table}] {key} must be a whole number in {self.text()}, "
                                     f"got {value:.6g}",
                                     path=path, table=table, key=key)
        return value

    def text(self) -> str:
        return f"{'(' if self.open_lo else '['}{self.lo:g}, {self.hi:g}] {self.unit}".rstrip()


# [roll], [pitch], [insertion]: rcm_kin.dynamics.drive.JointDrive (insertion: per metre where it says rad)
JOINT_DRIVE = {
    "gear_ratio": Range("motor rad per joint rad (per m)", 0.0, 1e4, open_lo=True),
    "torque_constant": Range("N m/A", 0.0, 10.0, open_lo=True),
    "resistance": Range("ohm", 0.0, 1e3, open_lo=True),
    "volts_per_pwm": Range("V per count", 0.0, 10.0, open_lo=True),
    "pwm_sign": Range("(-1 or 1)", -1.0, 1.0),
    "rotor_inertia": Range("kg m^2", 0.0, 1.0),
    "viscous": Range("N m s/rad (N s/m)", 0.0, 1e4),
    "coulomb": Range("N m (N)", 0.0, 1e4),
    "coulomb_velocity": Range("rad/s (m/s)", 0.0, 10.0, open_lo=True),
    "extra_inertia": Range("kg m^2 (kg)", 0.0, 1e3),
    "pwm_limit": Range("counts", 0.0, 255.0, open_lo=True),
}

# [drive_train.<joint>]: rcm_kin.dynamics.stick_slip.AxisFriction
DRIVE_TRAIN_DEFAULT = Range("(SI)", 0.0, 1e6)
DRIVE_TRAIN = {
    "extra_inertia": Range("kg m^2", 0.0, 1e3),
    "stribeck_velocity": Range("rad/s", 0.0, 10.0, open_lo=True),
    "presliding_slope": Range("1/rad", -20.0, 20.0),
    "presliding_elements": Range("elements", 1.0, float(MAX_ELEMENTS), whole=True),
}

GRAVITY_OFFSET = Range("kg m", -10.0, 10.0)     # [gravity_offsets] each of the 3 components


def check_table(entry: dict, schema: dict[str, Range], path, table: str, default: Range | None = None) -> dict:
    """The table's values as floats, each checked by its key's range (``default`` for keys not in
    ``schema``); keys are assumed already known to the caller."""
    out = {}
    for key, value in entry.items():
        rule = schema.get(key, default)
        if rule is None:
            raise ParameterFileError(f"{path}: [{table}] has no rule for {key}", path=path, table=table, key=key)
        out[key] = rule.check(value, path, table, key)
    if "pwm_sign" in out and abs(out["pwm_sign"]) != 1.0:
        raise ParameterFileError(f"{path}: [{table}] pwm_sign must be -1 or 1, got {out['pwm_sign']:g}", path=path,
                                 table=table, key="pwm_sign")
    return out


def check_offset(value, path, link: str) -> list[float]:
    """A ``[gravity_offsets]`` entry: 3 numbers in kg m."""
    if not isinstance(value, list) or len(value) != 3:
        raise ParameterFileError(f"{path}: gravity_offsets.{link} must be 3 numbers (kg m)", path=path,
                                 table="gravity_offsets", key=link)
    return [GRAVITY_OFFSET.check(v, path, "gravity_offsets", f"{link}[{i}]") for i, v in enumerate(value)]

"""What a drive parameter file may hold: per key its unit and valid range, checked once where the
file is read (:func:`rcm_kin.dynamics.drive.load_drive_parameters`), with the file and key named.

The ranges are physical plausibility bounds for a small brushed-DC cable-driven robot, wide enough
for any calibration or identification of this hardware and narrow enough that a value outside them
is a typing or unit error (a zero gear ratio, a negative resistance, NaN, ``1e-300``). The drive
constants have bands of about a factor 10-100 either way of the PSM's (``urdf/psm_drive.toml``
gives each shipped value's source), each with its reason, which the error states: a drive of
another small electric robot fits, a value that would make the holding PWM or a linearisation
entry absurd (``gear_ratio = 1e-300``: -3.8e302 counts) does not. One line per key: a key
added to :class:`~rcm_kin.dynamics.stick_slip.AxisFriction` without a line here is checked as a
finite number >= 0 (:data:`DRIVE_TRAIN_DEFAULT`).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from pathlib import Path

from rcm_kin.dynamics.axis_friction import MAX_ELEMENTS
from rcm_kin.errors import ParameterFileError


@dataclass(frozen=True)
class Range:
    """A finite number in ``[lo, hi]`` (``lo`` excluded when ``open_lo``; a whole number when
    ``whole``) of ``unit``; ``why``: what is plausible and why, said when a value is outside."""

    unit: str
    lo: float
    hi: float
    open_lo: bool = False
    whole: bool = False
    why: str = ""

    def check(self, value, path: Path | str, table: str, key: str) -> float:
        """``value`` as a float, or an error naming the file, the table and the key."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParameterFileError(f"{path}: [{table}] {key} must be a number ({self.unit}), got {value!r}"[:300],
                                     path=path, table=table, key=key)
        value = float(value)
        if not math.isfinite(value) or value < self.lo or value > self.hi or (self.open_lo and value == self.lo):
            raise ParameterFileError(f"{path}: [{table}] {key} = {value:.6g} is outside {self.text()}"
                                     + (f" ({self.why})" if self.why else ""), path=path, table=table, key=key)
        if self.whole and not value.is_integer():
            raise ParameterFileError(f"{path}: [{table}] {key} must be a whole number in {self.text()}, "
                                     f"got {value:.6g}",
                                     path=path, table=table, key=key)
        return value

    def text(self) -> str:
        return f"{'(' if self.open_lo else '['}{self.lo:g}, {self.hi:g}] {self.unit}".rstrip()


# [roll], [pitch], [insertion]: rcm_kin.dynamics.drive.JointDrive (insertion: per metre where it says rad)
JOINT_DRIVE = {
    "gear_ratio": Range("motor rad per joint rad (per m)", 0.1, 1e4,
                        why="plausible: a capstan or gear reduction, the PSM's 13.3 pitch, 20 roll, 105/m insertion"),
    "torque_constant": Range("N m/A", 1e-3, 1.0, why="plausible: a small brushed DC motor, the PSM's 0.0302"),
    "resistance": Range("ohm", 0.01, 100.0, why="plausible: a small DC motor's terminal resistance, the PSM's 0.582"),
    "volts_per_pwm": Range("V per count", 1e-3, 1.0,
                           why="plausible: the supply voltage / 255 counts of a 0.26-255 V supply, the PSM's 0.0588 "
                               "nominal (15 V) and 0.117 calibrated"),
    "pwm_sign": Range("(-1 or 1)", -1.0, 1.0),
    "rotor_inertia": Range("kg m^2", 0.0, 1.0),
    "viscous": Range("N m s/rad (N s/m)", 0.0, 1e4),
    "coulomb": Range("N m (N)", 0.0, 1e4),
    "coulomb_velocity": Range("rad/s (m/s)", 1e-4, 1.0,
                              why="plausible: the width of tanh(v / width), about the slowest speed the encoders "
                                  "resolve (roll 0.06 rad/s), the PSM's 0.02 rad/s and 0.002 m/s; narrower makes "
                                  "the Coulomb law a step and its linearisation coulomb / width"),
    "extra_inertia": Range("kg m^2 (kg)", 0.0, 1e3),
    "pwm_limit": Range("counts", 0.0, 255.0, open_lo=True),
}

# [drive_train.<joint>]: rcm_kin.dynamics.stick_slip.AxisFriction
DRIVE_TRAIN_DEFAULT = Range("(SI)", 0.0, 1e6)
DRIVE_TRAIN = {
    "extra_inertia": Range("kg m^2", 0.0, 1e3),
    "stribeck_velocity": Range("rad/s", 1e-4, 10.0,
                               why="plausible: the identification searches 1e-3 to 1 rad/s, the PSM's 0.01"),
    "presliding_slope": Range("1/rad", -20.0, 20.0),
    "presliding_elements": Range("elements", 1.0, float(MAX_ELEMENTS), whole=True),
}

GRAVITY_OFFSET = Range("kg m", -10.0, 10.0)     # [gravity_offsets] each of the 3 components


# The top-level entries of a drive file besides its joint tables [<joint>] (numbers only, one per driven joint)
TABLES = ("gravity_offsets", "drive_train", "uncertainty")
KEYS = ("robot",)


def joint_tables(raw: dict, path) -> dict:
    """The joint tables of a parsed drive file: every top-level table but :data:`TABLES`. An entry that
    cannot be a joint table is an error naming it and the known ones: a key that is not a table, a table
    of tables (``[drive-train.roll]``) or one named like a known table (a misspelling)."""
    known = f"robot = \"...\", the tables [{'], ['.join(TABLES)}] and one [<joint>] of numbers per driven joint"
    tables = {}
    for name, entry in raw.items():
        if name in TABLES or name in KEYS:
            continue
        if not isinstance(entry, dict):
            raise ParameterFileError(f"{path}: unknown key {name} (a drive file holds {known})", path=path,
                                     table=None, key=name)
        close = difflib.get_close_matches(name, TABLES, n=1, cutoff=0.75)
        if close or any(isinstance(v, dict) for v in entry.values()):
            nested = next((f"{name}.{k}" for k, v in entry.items() if isinstance(v, dict)), name)
            hint = f"; did you mean [{close[0]}]?" if close else ""
            raise ParameterFileError(f"{path}: unknown table [{nested}] (a drive file holds {known}{hint})",
                                     path=path, table=name, key=None)
        tables[name] = entry
    return tables


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

"""Holding torque, voltage and PWM of the PSM's driven joints over pose grids, as CSV and figures.

Grids are roll x pitch at one insertion, or a sweep of insertion; every pose is evaluated by
the driven model's gravity compiled to C (:func:`driven_gravity`; the same numbers as the
vectorised :func:`rcm_kin.model.gravity.gravity_batch`) with the calibrated gravity offsets,
then through the drive model. Angles in the tables are degrees (for people);
torques N m (insertion N), voltage V, PWM counts with the hardware sign.
"""

from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

import casadi as ca
import numpy as np

from rcm_kin.atomic import atomic_open
from rcm_kin.csv_table import write_csv_blocks
from rcm_kin.dynamics.drive import (
    DRIVEN,
    DriveEffort,
    DriveParameters,
    drive_effort,
    model_label,
    resolve_drive,
)
from rcm_kin.dynamics.state_space import driven_gravity_function
from rcm_kin.errors import RcmKinError, WorkLimitError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.model.gravity import gravity_batch
from rcm_kin.model.masses import require_masses
from rcm_kin.model.robot import check_robot
from rcm_kin.plotting import draw_apart, effort_heatmaps, insertion_curves, thesis_trend_curves
from rcm_kin.progress import over_blocks
from rcm_kin.statics.holding_band import band_columns
from rcm_kin.symbolic.compiled import compiled, map_points

if TYPE_CHECKING:
    from rcm_kin.model import Robot


DEFAULT_GRID_DEG = np.linspace(-30.0, 30.0, 61)   # roll and pitch, deg (the CLI's default grid)
MAX_POSES = 1001 * 1001   # poses of one map (the largest benchmarked: bench_gravity.py)
BYTES_PER_POSE = 140      # peak memory per pose, measured: 1001 x 1001 poses took 135 MB more than 5 x 5
DRIVE_BLOCK = 1 << 12     # poses through the drive model at a time: its temporaries stay in the cache


def check_map_size(poses: int) -> None:
    """Refuse a map of more than :data:`MAX_POSES` poses before anything is allocated, saying what it
    would need."""
    if poses > MAX_POSES:
        raise WorkLimitError(f"a map of {poses:,} poses is beyond the {MAX_POSES:,} (1001 x 1001) this command is "
                             f"measured for (about {MAX_POSES * BYTES_PER_POSE / 1e6:.0f} MB at the limit): use fewer "
                             "points per axis", requested=poses, limit=MAX_POSES)


@dataclass(frozen=True)
class GravityMap:
    """Holding effort of the driven joints over a roll x pitch x insertion grid: a labelled result.

    Every array of :attr:`effort` (``tau`` N m or N, ``motor_torque`` N m, ``current`` A, ``voltage`` V,
    ``pwm`` counts with the hardware sign, ``saturated``) has the axes :attr:`dims` =
    ``(pitch, roll, insertion, joint)``:
    pitch rows, roll columns. Read one pose by name with :meth:`sel` rather than by position;
    :meth:`write` writes the table (CSV or .npz)."""

    roll_deg: np.ndarray        # (R,) grid values, deg
    pitch_deg: np.ndarray       # (P,) grid values, deg
    insertion: np.ndarray       # (I,) grid values, m
    effort: DriveEffort         # arrays of shape (P, R, I, 3)
    extra: dict[str, np.ndarray] = field(default_factory=dict)   # more table columns, (P, R, I) each: a band's

    dims: ClassVar[tuple[str, ...]] = ("pitch", "roll", "insertion", "joint")
    units: ClassVar[dict[str, str]] = {"roll": "deg", "pitch": "deg", "insertion": "m", "tau": "N m (insertion: N)",
                                       "voltage": "V", "pwm": "counts (hardware sign)"}

    @property
    def coords(self) -> dict[str, np.ndarray | tuple[str, ...]]:
        """The grid values along each axis of :attr:`dims`."""
        return {"pitch": self.pitch_deg, "roll": self.roll_deg, "insertion": self.insertion, "joint": DRIVEN}

    def index(self, roll: float, pitch: float, insertion: float | None = None) -> tuple[int, int, int]:
        """Array index ``(pitch, roll, insertion)`` of a grid pose (deg, deg, m); ``insertion`` may be
        left out when the map has one. A value that is not on the grid is an error naming the nearest."""
        if insertion is None:
            if self.insertion.size != 1:
                raise RcmKinError(f"the map has {self.insertion.size} insertions: give insertion (m)")
            insertion = float(self.insertion[0])
        return tuple(_on_grid(values, x, name, self.units[name])
                     for name, values, x in (("pitch", self.pitch_deg, pitch), ("roll", self.roll_deg, roll),
                                             ("insertion", self.insertion, insertion)))

    def sel(self, roll: float, pitch: float, insertion: float | None = None,
            joint: str | None = None) -> DriveEffort:
        """The holding effort at one grid pose, by name (deg, deg, m): arrays over the joints of
        ``coords["joint"]``, or scalars of one ``joint`` (``"roll"``, ``"pitch"``, ``"insertion"``)."""
        at = self.index(roll, pitch, insertion)
        if joint is not None:
            if joint not in DRIVEN:
                raise RcmKinError(f"joint '{joint}' is not an axis of the map: one of {', '.join(DRIVEN)}",
                                  parameter="joint")
            at = at + (DRIVEN.index(joint),)
        return DriveEffort(**{f.name: getattr(self.effort, f.name)[at] for f in fields(DriveEffort)})

    def write(self, path: str | Path) -> Path:
        """The map's table, one row per pose, as CSV (``.csv``) or NumPy (``.npz``) by the suffix."""
        suffix = Path(path).suffix.lstrip(".")
        if suffix not in TABLE_WRITERS:
            raise RcmKinError(f"a map's table is written as {' or '.join('.' + k for k in TABLE_WRITERS)}, "
                              f"not {Path(path).name}")
        return TABLE_WRITERS[suffix](self, path)


def _on_grid(values: np.ndarray, x: float, name: str, unit: str) -> int:
    k = int(np.argmin(np.abs(values - x)))
    if not abs(values[k] - x) <= 1e-9 * max(1.0, abs(x)):
        raise RcmKinError(f"{name} {x:g} {unit} is not on the map's grid (nearest {values[k]:g} {unit})")
    return k


@dataclass(frozen=True)
class HoldingEffort:
    """Gravity load at one pose: every actuated joint, and the drive's joints where one is described."""

    tau: np.ndarray                 # N m (N for prismatic), actuated order
    drive: DriveEffort | None       # the drive's joints (``driven`` order): voltage, PWM, saturation
    model: str = "CAD (URDF inertias)"   # which model: rcm_kin.dynamics.drive.model_label
    driven: tuple[str, ...] = ()         # the joints of ``drive`` (empty without a drive)


def holding_effort(robot: Robot, q, drive=None, *, params=None, allow_outside_limits: bool = False) -> HoldingEffort:
    """Holding effort of ``robot`` at actuated ``q`` (rad, m): the closed chain's gravity on every
    actuated joint and, with a drive (``drive`` given: DriveParameters or a drive file, checked
    against the robot; else the robot's sidecar drive), its calibrated gravity offsets and the
    motor effort of ``params.driven``. Without one: the URDF inertias, torque only. ``params`` is
    the keyword's former name, still accepted (give one of the two). ``allow_outside_limits``:
    evaluate a pose outside the joint limits (refused by default, :meth:`Robot.check_pose`)."""
    robot = check_robot(robot)
    if params is not None:
        if drive is not None:
            raise RcmKinError("holding_effort takes the drive once: give `drive` (`params` is its former name), "
                              "not both", parameter="drive")
        drive = params
    q = robot.check_pose(q, allow_outside_limits=allow_outside_limits)
    require_masses(robot, "the holding torque")
    drive = resolve_drive(robot, drive)
    if drive is None:
        return HoldingEffort(gravity_batch(robot, q[None])[0], None)
    tau = gravity_batch(robot, q[None], drive.gravity_offsets)[0]
    driven = tau[[robot.actuated.index(j) for j in drive.driven]]
    return HoldingEffort(tau, drive_effort(drive, driven), model_label(drive), drive.driven)


def parse_range(text: str, what: str, unit: str = "deg") -> tuple[float, float, int]:
    """``LO:HI:N`` -> (LO, HI, N), with a clear error naming ``unit`` (of LO and HI: "deg" for a
    revolute joint, "m" for a prismatic one); N = 1 is the single value LO (= HI)."""
    try:
        lo, hi, n = text.split(":")
        lo, hi, n = float(lo), float(hi), int(n)
    except ValueError:
        raise RcmKinError(f"{what} must be LO:HI:N ({unit}, {unit}, count), got '{text}'") from None
    if n < 1 or not (np.isfinite(lo) and np.isfinite(hi)) or (n > 1 and hi <= lo) or (n == 1 and hi != lo):
        raise RcmKinError(f"{what} {text}: need finite LO < HI and N >= 2, or LO = HI and N = 1")
    check_map_size(n)
    return lo, hi, n


def gravity_map(robot: Robot, drive=None, roll_deg=DEFAULT_GRID_DEG, pitch_deg=DEFAULT_GRID_DEG,
                insertion=HOME_INSERTION, progress: bool = False) -> GravityMap:
    """Holding effort over the grid roll x pitch x insertion (degrees, degrees, metres), a
    :class:`GravityMap` with named axes. ``drive``: the drive parameters (DriveParameters or the
    path of a drive file), checked against the robot (:func:`check_drive`); default: the robot's
    sidecar drive, as :func:`holding_effort` (:func:`resolve_drive`). The map is in voltage and PWM,
    so a robot without a drive is an error (its torques: :func:`rcm_kin.statics.torque_map`)."""
    robot = check_robot(robot)
    missing = [j for j in DRIVEN if j not in robot.actuated]
    if missing:
        raise RcmKinError(f"a holding-effort map is over the driven joints {', '.join(DRIVEN)}; {robot.name} has no "
                          f"{', '.join(missing)}", parameter="robot")
    drive = map_drive(robot, drive)
    roll_deg, pitch_deg, insertion = (_grid(x, name) for x, name in
                                      ((roll_deg, "roll_deg"), (pitch_deg, "pitch_deg"), (insertion, "insertion")))
    for name, values, unit, parameter in (("roll", np.radians(roll_deg), "deg", "roll_deg"),
                                          ("pitch", np.radians(pitch_deg), "deg", "pitch_deg"),
                                          ("insertion", insertion, "m", "insertion")):
        i = robot.actuated.index(name)
        lo, hi = robot.lower[i], robot.upper[i]
        if values.min() < lo - 1e-12 or values.max() > hi + 1e-12:
            shown = (np.degrees([lo, hi]) if unit == "deg" else [lo, hi])
            raise RcmKinError(f"{name} range outside the joint limits [{shown[0]:g}, {shown[1]:g}] {unit}",
                              parameter=parameter)
    check_map_size(roll_deg.size * pitch_deg.size * insertion.size)
    P, R, I = np.meshgrid(np.radians(pitch_deg), np.radians(roll_deg), insertion, indexing="ij")
    Q = np.column_stack([R.ravel(), P.ravel(), I.ravel()])
    shape = P.shape + (3,)
    del P, R, I                                      # large grids: keep the peak memory down
    tau = driven_gravity(robot, drive, Q, progress).reshape(shape)
    del Q
    return GravityMap(roll_deg, pitch_deg, insertion, drive_effort_blocks(drive, tau))


def map_drive(robot: Robot, drive=None) -> DriveParameters:
    """The drive of a :func:`gravity_map` of ``robot``: :func:`resolve_drive` (checked; default the
    sidecar's), required, over the map's joints :data:`DRIVEN` in that order (a file's other joints
    are not on the map)."""
    params = resolve_drive(robot, drive)
    if params is None:
        raise RcmKinError(f"a gravity map is in motor voltage and PWM and {robot.name} has no drive (its sidecar "
                          "names no `drive` file): give `drive`, or use torque_map for its holding torques",
                          parameter="drive")
    if missing := [j for j in DRIVEN if j not in params.driven]:
        raise RcmKinError(f"{params.source or 'the drive parameters'} describe no {', '.join(missing)}: a gravity map "
                          f"needs the drives of {', '.join(DRIVEN)}", parameter="drive")
    if params.driven != DRIVEN:
        params = replace(params, joints={j: params.joints[j] for j in DRIVEN},
                         drive_train={j: f for j, f in params.drive_train.items() if j in DRIVEN})
    return params


def _grid(values, name: str) -> np.ndarray:
    """One axis of a map's grid: a non-empty vector of finite numbers, or an error naming it."""
    try:
        grid = np.atleast_1d(np.asarray(values, dtype=float))
    except (TypeError, ValueError):
        raise RcmKinError(f"`{name}` must be numbers, got {str(values)[:60]!r}", parameter=name) from None
    if grid.ndim != 1 or grid.size == 0 or not np.all(np.isfinite(grid)):
        raise RcmKinError(f"`{name}` must be a non-empty list of finite numbers, got {grid.tolist()[:8]}",
                          parameter=name)
    return grid


def drive_effort_blocks(params: DriveParameters, tau: np.ndarray, block: int = DRIVE_BLOCK) -> DriveEffort:
    """:func:`drive_effort` at holding (v = 0) for torques (..., len(params.driven)), evaluated in
    blocks of ``block`` poses into the result arrays, so that its temporaries stay the size of a
    block (in the cache)."""
    n = tau.shape[-1]
    flat = tau.reshape(-1, n)
    out = {f.name: np.empty(flat.shape, dtype=bool if f.name == "saturated" else float)
           for f in fields(DriveEffort) if f.name != "tau"}
    for i in range(0, len(flat), block):
        part = drive_effort(params, flat[i:i + block])
        for name, values in out.items():
            values[i:i + block] = getattr(part, name)
    return DriveEffort(tau, **{name: values.reshape(tau.shape) for name, values in out.items()})


def driven_gravity(robot: Robot, drive: DriveParameters, Q: np.ndarray, progress: bool = False,
                   block: int = 1 << 16) -> np.ndarray:
    """Holding torques (N, 3) of the driven joints at (N, 3) poses (rad, rad, m; the instrument
    joints at zero), calibrated offsets included: the driven model's gravity
    (:func:`rcm_kin.dynamics.state_space.driven_gravity_function`, the numbers of
    :func:`gravity_batch`) compiled to C and
    mapped over the poses; ``progress`` shows a bar over blocks of ``block`` poses."""
    offsets = tuple((link, tuple(float(x) for x in h)) for link, h in sorted(drive.gravity_offsets.items()))
    gravity = _compiled_gravity(robot, offsets)
    tau = np.empty((len(Q), 3))
    for i in over_blocks(range(0, len(Q), block), progress, "gravity", "block"):
        tau[i:i + block] = map_points(gravity, Q[i:i + block])[0]
    return tau


@functools.lru_cache(maxsize=8)
def _compiled_gravity(robot: Robot, offsets: tuple) -> ca.Function:
    """The driven gravity with first moments ``offsets`` ((link, (hx, hy, hz)), ...), compiled:
    built once per robot and offsets in a process (and on disk by :mod:`rcm_kin.symbolic.compiled`)."""
    return compiled(driven_gravity_function(robot, {link: np.array(h) for link, h in offsets}, joints=DRIVEN))


def table_header(gmap: GravityMap | None = None) -> list[str]:
    """Column names of a map's table (CSV header, .npz array names), in order; those of ``gmap.extra``
    (a band's) last."""
    return (["roll_deg", "pitch_deg", "insertion_m"] + [f"{q}_{j}" for q in ("tau", "voltage", "pwm") for j in DRIVEN]
            + list(gmap.extra if gmap is not None else ()))


def with_band(gmap: GravityMap, drive: DriveParameters, level: float) -> GravityMap:
    """``gmap`` with its level-``level`` holding band as more columns
    (:func:`rcm_kin.statics.holding_band.band_columns`: lower/upper PWM, extrapolated)."""
    poses = {"roll": np.radians(gmap.roll_deg)[None, :, None], "pitch": np.radians(gmap.pitch_deg)[:, None, None],
             "insertion": gmap.insertion[None, None, :]}
    return replace(gmap, extra=band_columns(drive, DRIVEN, gmap.effort.pwm, poses, level))


def table_rows(gmap: GravityMap, start: int, stop: int) -> np.ndarray:
    """Rows ``start:stop`` of the map's table (:func:`table_header` columns; one row per pose,
    pitch slowest, insertion fastest)."""
    e = gmap.effort
    p, r, i = np.unravel_index(np.arange(start, min(stop, e.tau[..., 0].size)), e.tau.shape[:3])
    return np.column_stack([gmap.roll_deg[r], gmap.pitch_deg[p], gmap.insertion[i]]
                           + [x.reshape(-1, 3)[start:stop] for x in (e.tau, e.voltage, e.pwm)]
                           + [x.reshape(-1)[start:stop] for x in gmap.extra.values()])


def write_csv(gmap: GravityMap, path: str | Path, block: int = 1 << 14) -> Path:
    """The map's table as CSV (9 decimals, :mod:`rcm_kin.csv_table`), written in blocks of
    ``block`` rows."""
    poses = gmap.effort.tau[..., 0].size
    return write_csv_blocks(path, table_header(gmap), (table_rows(gmap, i, i + block) for i in range(0, poses, block)))


def write_npz(gmap: GravityMap, path: str | Path) -> Path:
    """The map's table as an uncompressed NumPy ``.npz``: one float64 array (poses,) per column
    of :func:`table_header`, rows in the CSV's order, at full precision (the CSV rounds to 9
    decimals). ``dict(np.load(path))`` is the table (e.g. for ``pandas.DataFrame``). The effort
    columns are written from views of the map, the pose columns made one at a time."""
    path = Path(path)
    e = gmap.effort
    shape = e.tau.shape[:3]
    axes = {"roll_deg": (gmap.roll_deg, 1), "pitch_deg": (gmap.pitch_deg, 0), "insertion_m": (gmap.insertion, 2)}
    columns = {name: np.broadcast_to(values.reshape([-1 if k == axis else 1 for k in range(3)]), shape).ravel()
               for name, (values, axis) in axes.items()}
    columns.update({f"{q}_{j}": getattr(e, q).reshape(-1, 3)[:, k]
                    for q in ("tau", "voltage", "pwm") for k, j in enumerate(DRIVEN)})
    columns.update({name: x.reshape(-1) for name, x in gmap.extra.items()})
    try:
        with atomic_open(path, "wb") as fh:              # np.savez would append ".npz" to another suffix
            np.savez(fh, **{name: columns[name] for name in table_header(gmap)})
    except OSError as exc:
        raise RcmKinError(f"cannot write {path}: {exc.strerror}") from None
    return path


TABLE_WRITERS = {"csv": write_csv, "npz": write_npz}     # table format -> writer (file suffix = the key)


def write_gravity_maps(robot: Robot, drive: DriveParameters, roll_deg, pitch_deg, insertion: float, out: Path,
                       progress: bool = False, sweep_roll_deg=(0.0, 20.0),
                       sweep_pitch_deg=(-20.0, 0.0, 20.0), table: str = "csv",
                       figures: bool = True, band: float | None = None) -> tuple[GravityMap, list[Path]]:
    """The roll x pitch map at one insertion (m) and an insertion sweep over the whole insertion
    range at the poses ``sweep_roll_deg`` x ``sweep_pitch_deg`` (at roll = pitch = 0 the shaft
    hangs through both axes and nothing depends on the insertion), in folder ``out``: their
    tables torque_map.csv and insertion_map.csv (``table`` "npz": .npz, see :func:`write_npz`)
    and, with ``figures``, torque_map.png, trend_curves.png, insertion_map.png (on two cores the first two drawn
    in two forked processes: :func:`rcm_kin.plotting.draw_apart`). ``band``: a level in
    (0, 1), the tables gain the holding band's columns (:func:`with_band`)."""
    if table not in TABLE_WRITERS:
        raise RcmKinError(f"table format '{table}': use one of {', '.join(TABLE_WRITERS)}")
    write_table = TABLE_WRITERS[table]
    gmap = gravity_map(robot, drive, roll_deg, pitch_deg, [insertion], progress=progress)
    i = robot.actuated.index("insertion")
    sweep = gravity_map(robot, drive, sweep_roll_deg, sweep_pitch_deg, np.linspace(robot.lower[i], robot.upper[i], 81))
    if band is not None:
        params = map_drive(robot, drive)
        gmap, sweep = with_band(gmap, params, band), with_band(sweep, params, band)

    def write_tables() -> list[Path]:
        return [write_table(gmap, out / f"torque_map.{table}"), write_table(sweep, out / f"insertion_map.{table}")]

    if not figures:
        return gmap, write_tables()

    def heat() -> Path:
        return effort_heatmaps(gmap, drive, out / "torque_map.png")

    def trends() -> Path:
        return thesis_trend_curves(gmap, out / "trend_curves.png")

    def tables_and_insertion() -> tuple[list[Path], Path]:
        # the tables are formatted in compiled code and written by the OS, both without the GIL, so on
        # a second thread they take (almost) no time from the figure, which is drawn in Python
        with ThreadPoolExecutor(1) as pool:
            tables = pool.submit(write_tables)
            drawn = insertion_curves(sweep, out / "insertion_map.png")
            return tables.result(), drawn

    # on two cores the heat maps and the trend curves (about 0.2 s of CPU each) are drawn in two forked processes
    # while this one draws the insertion curves: three processes share the two cores more evenly than two
    heat_png, (trends_png, (written, insertion)) = draw_apart(heat, lambda: draw_apart(trends, tables_and_insertion))
    return gmap, [written[0], heat_png, trends_png, written[1], insertion]

"""Holding effort of any robot: one pose (:func:`holding_effort`) or a map over two actuated joints.

For ANY robot description: the joint torques (N m, N) of every actuated joint that hold a pose,
through the loop closures (the closed chain's generalised gravity), and, where a drive is
described (the robot's sidecar ``drive`` file, or one given and checked with
:func:`~rcm_kin.dynamics.drive.check_drive`), the motor torque, current, voltage and PWM of the
drive's joints (``params.driven``) with its calibrated gravity offsets. Without a drive the robot
runs on its URDF inertias, torque only; every result names the model it used (``model``).

:func:`torque_map` evaluates a grid over two actuated joints (the others held at ``q``) by the
closed chain's gravity compiled to C (:func:`gravity_function`, the numbers of
:func:`rcm_kin.model.gravity.gravity_batch`). Values are SI inside (rad, m); the tables write
revolute joints in degrees (for people), prismatic in metres.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from rcm_kin.atomic import atomic_open
from rcm_kin.csv_table import write_csv_blocks
from rcm_kin.dynamics.drive import DriveEffort, DriveParameters, model_label, resolve_drive
from rcm_kin.dynamics.state_space import driven_gravity_function
from rcm_kin.errors import RcmKinError
from rcm_kin.model.loading import build_robot
from rcm_kin.model.masses import require_masses
from rcm_kin.model.robot import check_robot
from rcm_kin.plotting import torque_heatmaps
from rcm_kin.progress import over_blocks
from rcm_kin.statics.holding_band import band_columns, check_level
from rcm_kin.statics.maps import HoldingEffort, check_map_size, drive_effort_blocks
from rcm_kin.symbolic.compiled import map_points
from rcm_kin.symbolic.points import CompiledPoints, compiled_points

if TYPE_CHECKING:
    from rcm_kin.model import Robot

BLOCK = 1 << 13     # poses evaluated at a time: poses and torques stay in the cache (bounds the temporaries)


def unit_of(robot: Robot, joint: str) -> str:
    """SI unit of a joint's position: ``rad`` or ``m``."""
    return "m" if robot.joint_kind(joint) == "prismatic" else "rad"


@dataclass(frozen=True, eq=False)
class TorqueMap:
    """Holding effort over a grid of two actuated joints of any robot, a labelled result.

    :attr:`tau` has the axes :attr:`dims` = ``(joint_a, joint_b, "joint")``: the grid values of
    ``joint_a`` (rows), of ``joint_b`` (columns), every actuated joint; the arrays of :attr:`effort`
    (None without a drive) the axes ``(joint_a, joint_b, "driven")``. Grid values are SI (rad, m).
    Read one pose by name with :meth:`sel`; :meth:`write` writes the table (CSV or .npz)."""

    robot: str
    joints: tuple[str, str]             # the grid's joints (joint_a, joint_b)
    values: tuple[np.ndarray, np.ndarray]   # their grid values, rad or m
    units: tuple[str, str]              # "rad" or "m" each
    q: np.ndarray                       # (nq,) the pose of the other joints (grid joints: their first value)
    actuated: tuple[str, ...]
    tau: np.ndarray                     # (A, B, nq) N m (N)
    effort: DriveEffort | None          # arrays (A, B, len(driven))
    model: str                          # which model: "CAD (URDF inertias)" or "calibration <file>"
    driven: tuple[str, ...] = ()
    tau_units: tuple[str, ...] = ()     # per actuated joint: "N m" (revolute) or "N" (prismatic)
    params: DriveParameters | None = None   # the drive used (None: CAD, torque only)
    extra: dict[str, np.ndarray] = field(default_factory=dict)   # more table columns, (A, B) each: a band's

    @property
    def dims(self) -> tuple[str, str, str]:
        """The axes of :attr:`tau`."""
        return (*self.joints, "joint")

    @property
    def coords(self) -> dict[str, np.ndarray | tuple[str, ...]]:
        """The values along each axis of :attr:`dims` (and ``driven``: the last axis of :attr:`effort`)."""
        return {self.joints[0]: self.values[0], self.joints[1]: self.values[1], "joint": self.actuated,
                "driven": self.driven}

    @property
    def poses(self) -> int:
        """Number of grid poses."""
        return self.values[0].size * self.values[1].size

    def index(self, **at: float) -> tuple[int, int]:
        """Array index ``(a, b)`` of the grid pose ``{joint_a: value, joint_b: value}`` (rad, m); a
        value off the grid is an error naming the nearest."""
        if set(at) != set(self.joints):
            raise RcmKinError(f"select a pose of the map by its joints {' and '.join(self.joints)} "
                              f"(rad or m), got {', '.join(at) or 'none'}", parameter="joint")
        out = []
        for name, values, unit in zip(self.joints, self.values, self.units):
            x = float(at[name])
            k = int(np.argmin(np.abs(values - x)))
            if not abs(values[k] - x) <= 1e-9 * max(1.0, abs(x)):
                raise RcmKinError(f"{name} {x:g} {unit} is not on the map's grid (nearest {values[k]:g} {unit})")
            out.append(k)
        return tuple(out)

    def sel(self, **at: float) -> HoldingEffort:
        """The holding effort at one grid pose, by name: ``tmap.sel(j2=0.1, j3=-0.2)`` (rad, m)."""
        a, b = self.index(**at)
        drive = None if self.effort is None else DriveEffort(
            **{f.name: getattr(self.effort, f.name)[a, b] for f in fields(DriveEffort)})
        return HoldingEffort(self.tau[a, b], drive, self.model, self.driven)

    def header(self) -> list[str]:
        """Column names of the table: the grid joints (``_deg`` or ``_m``), ``tau_<joint>`` of every
        actuated joint, then ``voltage_<joint>``, ``pwm_<joint>`` of the drive's joints, then those of
        :attr:`extra` (a band's: ``lower_pwm_<joint>``, ``upper_pwm_<joint>``, ``extrapolated``)."""
        grid = [f"{j}_{'deg' if u == 'rad' else 'm'}" for j, u in zip(self.joints, self.units)]
        return (grid + [f"tau_{j}" for j in self.actuated]
                + [f"{x}_{j}" for x in ("voltage", "pwm") for j in (self.driven if self.effort is not None else ())]
                + list(self.extra))

    def rows(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start:stop`` of the table (:meth:`header`; ``joint_a`` slowest)."""
        a, b = np.unravel_index(np.arange(start, min(stop, self.poses)), self.tau.shape[:2])
        grid = [np.degrees(v) if u == "rad" else v for v, u in zip(self.values, self.units)]
        columns = [grid[0][a], grid[1][b], self.tau.reshape(-1, len(self.actuated))[start:stop]]
        if self.effort is not None:
            n = len(self.driven)
            columns += [self.effort.voltage.reshape(-1, n)[start:stop], self.effort.pwm.reshape(-1, n)[start:stop]]
        columns += [x.reshape(-1)[start:stop] for x in self.extra.values()]
        return np.column_stack(columns)

    def write(self, path: str | Path, block: int = 1 << 14) -> Path:
        """The map's table, one row per pose, as CSV (``.csv``, 9 decimals) or NumPy (``.npz``, one
        array per column, full precision) by the suffix."""
        path = Path(path)
        suffix = path.suffix.lstrip(".")
        if suffix == "csv":
            return write_csv_blocks(path, self.header(), (self.rows(i, i + block) for i in range(0, self.poses, block)))
        if suffix != "npz":
            raise RcmKinError(f"a map's table is written as .csv or .npz, not {path.name}")
        table = self.rows(0, self.poses)
        try:
            with atomic_open(path, "wb") as fh:         # np.savez would append ".npz" to another suffix
                np.savez(fh, **{name: table[:, k] for k, name in enumerate(self.header())})
        except OSError as exc:
            raise RcmKinError(f"cannot write {path}: {exc.strerror}") from None
        return path


def grid_axes(robot: Robot, grid: dict) -> tuple[tuple[str, str], tuple[np.ndarray, np.ndarray]]:
    """The two joints of ``grid`` ({joint: values, rad or m}) and their values, checked: actuated
    joints of the robot (a passive or unknown one is named), two different ones, non-empty finite
    values inside the joint limits."""
    if not isinstance(grid, dict) or len(grid) != 2:
        raise RcmKinError("`grid` must name two actuated joints and their values, e.g. {'j2': [...], 'j3': [...]} "
                          f"(rad, m), got {str(grid)[:60]}", parameter="grid")
    names, axes = tuple(grid), []
    for name in names:
        check_actuated(robot, name)
        try:
            values = np.atleast_1d(np.asarray(grid[name], dtype=float))
        except (TypeError, ValueError):
            raise RcmKinError(f"the grid of {name} must be numbers, got {str(grid[name])[:60]!r}",
                              parameter="grid") from None
        if values.ndim != 1 or values.size == 0 or not np.all(np.isfinite(values)):
            raise RcmKinError(f"the grid of {name} must be a non-empty list of finite numbers, got "
                              f"{values.ravel().tolist()[:8]}", parameter="grid")
        i = robot.actuated.index(name)
        if values.min() < robot.lower[i] - 1e-12 or values.max() > robot.upper[i] + 1e-12:
            lo, hi = robot.lower[i], robot.upper[i]
            shown = f"[{np.degrees(lo):g}, {np.degrees(hi):g}] deg" if unit_of(robot, name) == "rad" else \
                f"[{lo:g}, {hi:g}] m"
            raise RcmKinError(f"the grid of {name} is outside its joint limits {shown}", parameter="grid")
        axes.append(values)
    return names, tuple(axes)


def check_actuated(robot: Robot, name: str) -> None:
    """An error unless ``name`` is an actuated joint: a passive joint of the loops and an unknown
    name are told apart."""
    if name in robot.actuated:
        return
    if robot.tree.existJointName(str(name)):
        raise RcmKinError(f"{name} is a passive joint of {robot.name} (set by the loops), not one a map can sweep: "
                          f"use actuated joints ({', '.join(robot.actuated)})", parameter="grid")
    raise RcmKinError(f"{robot.name} has no joint '{name}': its actuated joints are {', '.join(robot.actuated)}",
                      parameter="grid")


def default_pose(robot: Robot) -> np.ndarray:
    """Zero for every actuated joint, moved into its limits where zero is outside them."""
    return np.clip(np.zeros(robot.nq), robot.lower, robot.upper)


def with_counterweights(robot: Robot, counterweights: bool) -> Robot:
    """``robot`` with or without its counterweights' mass (the same description rebuilt if needed)."""
    if bool(robot.with_counterweights) == bool(counterweights):
        return robot
    return _rebuilt(robot, bool(counterweights))


@functools.lru_cache(maxsize=8)
def _rebuilt(robot: Robot, counterweights: bool) -> Robot:
    """``robot``'s description built with or without the counterweights, once per robot in a process
    (so its compiled gravity is found in :func:`_compiled`'s cache the next time)."""
    return build_robot(robot.description, counterweights)


def torque_map(robot: Robot, grid: dict, q=None, drive=None, counterweights: bool = True,
               progress: bool = False, band: float | None = None) -> TorqueMap:
    """Holding effort of ``robot`` over ``grid`` = ``{joint_a: values, joint_b: values}`` (two actuated
    joints, rad or m), the other actuated joints at ``q`` (default :func:`default_pose`): a
    :class:`TorqueMap`. Torque of every actuated joint always; with a drive (``drive`` given,
    checked against the robot, else the sidecar's) its gravity offsets, voltage and PWM of its joints.
    ``counterweights=False``: without the counterweights' mass. ``band``: a level in (0, 1), the map
    gains its drive's holding band as table columns (:func:`rcm_kin.statics.holding_band.band_columns`;
    a drive is then required)."""
    robot = check_robot(robot)
    if band is not None:
        check_level(band, "band")
    names, values = grid_axes(robot, grid)
    if names[0] == names[1]:
        raise RcmKinError(f"the grid names {names[0]} twice: give two different joints", parameter="grid")
    check_map_size(values[0].size * values[1].size)
    robot = with_counterweights(robot, counterweights)
    require_masses(robot, "the torque map")
    params = resolve_drive(robot, drive)
    q = default_pose(robot) if q is None else robot.check_limits(robot.check_q(q))
    ia, ib = (robot.actuated.index(n) for n in names)
    q = q.copy()
    q[ia], q[ib] = values[0][0], values[1][0]
    offsets = {} if params is None else params.gravity_offsets
    tau = map_gravity(robot, offsets, q, (ia, ib), values, progress)
    effort, extra = None, {}
    if params is not None:
        driven = tau[..., [robot.actuated.index(j) for j in params.driven]]
        effort = drive_effort_blocks(params, driven)
    if band is not None:
        if params is None:
            raise RcmKinError(f"a holding band is in PWM and {robot.name} has no drive: give `drive`",
                              parameter="drive")
        poses = {j: (values[0][:, None] if j == names[0] else values[1][None, :] if j == names[1] else
                     np.asarray(q[robot.actuated.index(j)])) for j in params.driven if j in robot.actuated}
        extra = band_columns(params, params.driven, effort.pwm, poses, band)
    return TorqueMap(robot.name, names, values, tuple(unit_of(robot, n) for n in names), q, robot.actuated, tau,
                     effort, model_label(params), () if params is None else params.driven,
                     tuple("N" if unit_of(robot, j) == "m" else "N m" for j in robot.actuated), params, extra)


def map_gravity(robot: Robot, offsets: dict, q: np.ndarray, index: tuple[int, int], values, progress: bool = False,
                block: int = BLOCK) -> np.ndarray:
    """Holding torques (A, B, nq) over the grid ``values`` of the actuated joints ``index``, the
    others at ``q``: :func:`gravity_function` compiled, evaluated over blocks of ``block`` poses
    in one C loop each (:func:`~rcm_kin.symbolic.points.compiled_points`), written in place."""
    gravity = _compiled(robot, tuple((link, tuple(float(x) for x in h)) for link, h in sorted(offsets.items())))
    A, B = values[0].size, values[1].size
    tau = np.empty((A * B, robot.nq))
    Q = np.empty((min(block, A * B), robot.nq))
    Q[:] = q                                        # the fixed joints, once; the grid's two columns per block
    dense = gravity.function.sparsity_out(0).is_dense()
    for start in over_blocks(range(0, A * B, block), progress, "gravity", "block"):
        stop = min(start + block, A * B)
        a, b = np.divmod(np.arange(start, stop), B)
        poses = Q[:stop - start]
        poses[:, index[0]], poses[:, index[1]] = values[0][a], values[1][b]
        if dense:
            gravity([poses], [tau[start:stop]])
        else:
            tau[start:stop] = map_points(gravity.function, poses)[0]
    return tau.reshape(A, B, robot.nq)


def gravity_function(robot: Robot, offsets: dict | None = None) -> ca.Function:
    """``q -> g(q)``: the holding torques (N m, N) of every actuated joint at actuated ``q``, the
    closed chain's generalised gravity plus that of the first-moment ``offsets`` ({link: (3,) kg m
    in the link's frame}, mass-free): the dynamics' own gravity
    (:func:`~rcm_kin.dynamics.state_space.driven_gravity_function`) over every actuated joint."""
    return driven_gravity_function(robot, offsets or {}, joints=robot.actuated)


@functools.lru_cache(maxsize=8)
def _compiled(robot: Robot, offsets: tuple) -> CompiledPoints:
    """:func:`gravity_function` compiled, once per robot and offsets in a process (and on disk)."""
    return compiled_points(gravity_function(robot, {link: np.array(h) for link, h in offsets}))


def write_torque_map(tmap: TorqueMap, out: Path, table: str = "csv", figures: bool = True) -> list[Path]:
    """The map's table ``torque_map.<table>`` (``csv`` or ``npz``) and, with ``figures``, its heat
    maps ``torque_map.png`` (:func:`rcm_kin.plotting.torque_heatmaps`) in folder ``out``."""
    if table not in ("csv", "npz"):
        raise RcmKinError(f"table format '{table}': use one of csv, npz")
    files = [tmap.write(Path(out) / f"torque_map.{table}")]
    if figures:
        files.append(torque_heatmaps(tmap, Path(out) / "torque_map.png"))
    return files

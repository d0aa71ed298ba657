"""Counterweight design: masses and positions that minimise the actuator effort over a workspace.

Gravity is linear in each counterweight's mass and affine in its position, so with the masses
given, the RMS effort over a pose grid is a bounded linear least-squares problem in the
positions (scipy ``lsq_linear``): the global optimum, no starting guess. Two counterweights of
the PSM, as in the osMDV design:

- main-axis counterweight on the roll body, hanging a distance ``r0`` below the roll axis
  at the pitch pivot's station along it;
- DPM counterweight on the drive link, a distance ``r1`` from the pitch pivot at an angle
  ``phi1`` from straight down (positive towards the RCM), turning with pitch.

Effort is measured in PWM counts through the drive's static gain, so joints with different
transmissions are weighed by what their motors must do.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from scipy.optimize import lsq_linear

from rcm_kin.dynamics.drive import DriveParameters, model_label, resolve_drive
from rcm_kin.errors import RcmKinError, as_number
from rcm_kin.hardware import DPM_COUNTERWEIGHT, HOME_INSERTION, MAIN_COUNTERWEIGHT
from rcm_kin.model import load_robot
from rcm_kin.model.gravity import gravity_batch, point_mass_gravity_batch
from rcm_kin.model.robot import check_robot
from rcm_kin.statics.holding import check_actuated, default_pose, grid_axes, with_counterweights
from rcm_kin.statics.maps import check_map_size

if TYPE_CHECKING:
    from rcm_kin.model import Robot

MAX_MASS = 1000.0        # kg: a counterweight the designs consider (the PSM's are 0.5-2.3 kg)
MAX_DISTANCE = 1.0       # m: the largest placement bound per axis (the default 0.3 is the PSM's reach)


@dataclass(frozen=True)
class CounterweightDesign:
    main_mass: float       # kg
    main_distance: float   # m below the roll axis
    dpm_mass: float        # kg
    dpm_distance: float    # m from the pitch pivot
    dpm_angle: float       # rad from straight down, towards the RCM
    rms_pwm: np.ndarray    # (2,) roll, pitch RMS holding PWM over the grid with this design
    peak_pwm: np.ndarray   # (2,) largest |PWM| (both joints, whatever the weights)


def workspace_grid(robot: Robot, roll_deg=None, pitch_deg=None, insertion: float = HOME_INSERTION,
                   points: int = 13) -> np.ndarray:
    """(N, nq) poses on a roll x pitch grid at one insertion (m). ``roll_deg`` and ``pitch_deg``
    are (LO, HI, N) in degrees; by default the joint's whole range (its URDF limits) in ``points``."""

    def axis(spec, joint: str) -> np.ndarray:
        if spec is None:
            i = robot.actuated.index(joint)
            return np.linspace(robot.lower[i], robot.upper[i], points)
        return np.radians(np.linspace(*spec))

    r, p = np.meshgrid(axis(roll_deg, "roll"), axis(pitch_deg, "pitch"))
    Q = np.zeros((r.size, robot.nq))
    Q[:, 0], Q[:, 1], Q[:, 2] = r.ravel(), p.ravel(), insertion
    return Q


def design_counterweights(robot_without: Robot, drive: DriveParameters, Q, main_mass: float, dpm_mass: float,
                          weights=(1.0, 1.0), dpm_position: tuple[float, float] | None = None,
                          max_distance: float = 0.30) -> CounterweightDesign:
    """Positions of counterweights of the given masses (kg) minimising the weighted RMS holding
    PWM of (roll, pitch) over poses ``Q``. ``robot_without`` is the robot loaded with
    counterweights=False. ``dpm_position`` = (distance m, angle rad) holds the DPM counterweight
    where given; otherwise it is designed too. Offsets are bounded by ``max_distance`` (m)."""
    if robot_without.with_counterweights:
        raise RcmKinError("design counterweights on the robot without them: load_robot('psm', counterweights=False)")
    if main_mass <= 0 or dpm_mass <= 0:
        raise RcmKinError("counterweight masses must be positive (kg)")
    pivot = robot_without.tree.frames[robot_without.tree.getFrameId("drive_link")]
    pivot_x = robot_without.tree.jointPlacements[pivot.parentJoint].translation[0]   # pitch pivot on the main axis
    gain = np.array([drive["roll"].pwm_per_torque, drive["pitch"].pwm_per_torque])

    def effort(link, point, mass=1.0):
        return (point_mass_gravity_batch(robot_without, Q, link, point)[:, :2] * gain).ravel() * mass

    base = (gravity_batch(robot_without, Q)[:, :2] * gain).ravel()
    main0 = effort("roll_link", [pivot_x, 0, 0], main_mass)
    dpm0 = effort("drive_link", [0, 0, 0], dpm_mass)
    # holding PWM = A x - b, unknowns x: r0 (main), x1 = r1 sin(phi1), z1 = r1 cos(phi1) (DPM, below the pivot)
    columns = [effort("roll_link", [pivot_x, 0, -1], main_mass) - main0,
               effort("drive_link", [1, 0, 0], dpm_mass) - dpm0,
               effort("drive_link", [0, 0, -1], dpm_mass) - dpm0]
    b = -(base + main0 + dpm0)
    if dpm_position is None:
        A, lo, hi = np.column_stack(columns), [0, -max_distance, 0], [max_distance] * 3
    else:
        r1, phi1 = dpm_position
        b = b - columns[1] * r1 * np.sin(phi1) - columns[2] * r1 * np.cos(phi1)
        A, lo, hi = np.column_stack(columns[:1]), [0], [max_distance]
    w = np.tile(np.asarray(weights, dtype=float), len(Q))        # rows alternate roll, pitch
    sol = lsq_linear(A * w[:, None], b * w, bounds=(lo, hi))
    r0 = sol.x[0]
    x1, z1 = sol.x[1:] if dpm_position is None else (r1 * np.sin(phi1), r1 * np.cos(phi1))
    pwm = (A @ sol.x - b).reshape(-1, 2)
    return CounterweightDesign(main_mass, float(r0), dpm_mass, float(np.hypot(x1, z1)), float(np.arctan2(x1, z1)),
                               np.sqrt(np.mean(pwm**2, axis=0)), np.max(np.abs(pwm), axis=0))


@dataclass(frozen=True)
class OsmdvDesigns:
    """Counterweights of the osMDV masses positioned by :func:`design_counterweights`."""

    roll_only: CounterweightDesign        # the DPM counterweight where osMDV put it, the main one for the roll
    roll_and_pitch: CounterweightDesign   # both positioned for roll and pitch together
    roll_range_deg: tuple[float, float]   # the design grid (deg)
    pitch_range_deg: tuple[float, float]
    points: int                           # per axis
    insertion: float                      # m


def osmdv_designs(drive: DriveParameters, points: int = 13) -> OsmdvDesigns:
    """The osMDV counterweight masses (:data:`rcm_kin.hardware.MAIN_COUNTERWEIGHT`,
    :data:`~rcm_kin.hardware.DPM_COUNTERWEIGHT`) positioned on the CAD model: ``drive``'s joints
    with its calibrated gravity offsets left out, over the joints' whole roll x pitch range at
    the home insertion, ``points`` per axis. Once holding the DPM counterweight where osMDV
    built it and weighing the roll alone (what osMDV balanced), once designing both for roll
    and pitch."""
    without = load_robot("psm", counterweights=False)
    cad = DriveParameters(drive.joints, {})
    Q = workspace_grid(without, points=points)
    main_mass, (dpm_mass, dpm_distance, dpm_angle) = MAIN_COUNTERWEIGHT[0], DPM_COUNTERWEIGHT
    roll_only = design_counterweights(without, cad, Q, main_mass, dpm_mass, weights=(1.0, 0.0),
                                      dpm_position=(dpm_distance, dpm_angle))
    both = design_counterweights(without, cad, Q, main_mass, dpm_mass)
    span = [(float(np.degrees(Q[:, k].min())), float(np.degrees(Q[:, k].max()))) for k in (0, 1)]
    return OsmdvDesigns(roll_only, both, span[0], span[1], points, float(Q[0, 2]))


@dataclass(frozen=True)
class CounterweightPlacement:
    """A counterweight of any robot placed by :func:`place_counterweight`: where its mass best holds
    the arm over a grid, beside the robot as built (the URDF's counterweight) and without it."""

    link: str                  # the counterweight link (the sidecar's ``counterweights``)
    mount: str                 # the link it is fixed to; positions are in this link's frame
    mass: float                # kg
    position: np.ndarray       # (3,) m, designed
    as_built: np.ndarray       # (3,) m, the URDF's centre of mass of the counterweight
    joints: tuple[str, ...]    # the joints weighed
    unit: str                  # of the efforts: "N m" (torque; N for prismatic: see units) or "PWM counts"
    rms: np.ndarray            # per joint, RMS holding effort over the grid with the design
    peak: np.ndarray           # per joint, largest |effort| with the design
    rms_as_built: np.ndarray   # per joint, with the URDF's counterweight
    rms_without: np.ndarray    # per joint, without this counterweight (any other as built)
    rank: int                  # of the design problem: below 3 a direction is free (e.g. along the joint
                               # axis, which never changes a torque): the minimum-norm position is given
    model: str                 # "CAD (URDF inertias)" or "calibration <file>"
    units: tuple[str, ...] = ()   # per joint of ``joints``: "N m", "N" (a prismatic joint's force) or "PWM counts"

    @property
    def distance(self) -> float:
        """Distance (m) of the designed position from the mount link's origin."""
        return float(np.linalg.norm(self.position))


def mount_link(robot: Robot, link: str) -> str:
    """The link a (fixed) counterweight link hangs on: the first body frame above it."""
    model = robot.tree
    index = model.getFrameId(link)
    while index != 0:
        index = model.frames[index].parentFrame
        if model.frames[index].type == pin.FrameType.BODY:
            return model.frames[index].name
    raise RcmKinError(f"the counterweight link {link} of {robot.name} is not fixed to another link", parameter="link")


def place_counterweight(robot: Robot, link: str, grid: dict, q=None, mass: float | None = None, drive=None,
                        joints=None, max_distance: float = 0.30) -> CounterweightPlacement:
    """Position (in the frame of the link it is fixed to) of the counterweight ``link`` (one of the
    sidecar's ``counterweights``), of ``mass`` kg (default: the URDF's), that minimises the RMS holding
    effort of ``joints`` (default: the drive's, weighed in PWM counts; without a drive every actuated
    joint, in N m) over ``grid`` ({joint: values, rad or m}, two actuated joints; the others at ``q``).
    Gravity is affine in the position: a linear least-squares problem (minimum-norm where the grid
    leaves a direction free), bounded by ``max_distance`` (m) per axis."""
    robot = check_robot(robot)
    max_distance = as_number(max_distance, "max_distance", "m", 0.0, MAX_DISTANCE, low_open=True)
    if joints is not None and (isinstance(joints, str) or not _items(joints)
                               or not all(isinstance(j, str) for j in _items(joints))):
        raise RcmKinError(f"`joints` is a non-empty list of joint names, got {' '.join(str(joints).split())[:40]}",
                          parameter="joints")
    if link not in robot.description.counterweights:
        raise RcmKinError(f"{link} is not a counterweight of {robot.name} (its sidecar's counterweights: "
                          f"{', '.join(robot.description.counterweights) or 'none'})", parameter="link")
    full, without = with_counterweights(robot, True), with_counterweights(robot, False)
    params = resolve_drive(full, drive)
    names, values = grid_axes(full, grid)
    check_map_size(values[0].size * values[1].size)
    base_q = default_pose(full) if q is None else full.check_limits(full.check_q(q))
    A_, B_ = np.meshgrid(*values, indexing="ij")
    Q = np.broadcast_to(base_q, (A_.size, full.nq)).copy()
    Q[:, full.actuated.index(names[0])], Q[:, full.actuated.index(names[1])] = A_.ravel(), B_.ravel()
    weighed, gain, units = _weighing(full, params, joints)
    offsets = {} if params is None else params.gravity_offsets
    cols = [full.actuated.index(j) for j in weighed]

    def effort(r: Robot) -> np.ndarray:
        return gravity_batch(r, Q, offsets)[:, cols] * gain

    mount = mount_link(full, link)
    j = full.tree.frames[full.tree.getFrameId(mount)].parentJoint
    built_mass = full.tree.inertias[j].mass - without.tree.inertias[j].mass
    mass = built_mass if mass is None else as_number(mass, "mass", "kg", 0.0, MAX_MASS, low_open=True)
    if not mass > 0:
        raise RcmKinError(f"the counterweight {link} needs a positive mass (kg), got {mass:g}", parameter="mass")
    built = _as_built(full, without, mount, j, built_mass)

    def point_effort(p) -> np.ndarray:
        return point_mass_gravity_batch(full, Q, mount, p)[:, cols] * gain

    # the robot with its other counterweights as built and without this one
    base = effort(full) - (built_mass * point_effort(built) if built_mass > 0 else 0.0)
    point = [point_effort(p) for p in np.vstack([np.zeros(3), np.eye(3)])]
    A = mass * np.column_stack([(p - point[0]).ravel() for p in point[1:]])
    b = -(base + mass * point[0]).ravel()
    x, _, rank, _ = np.linalg.lstsq(A, b, rcond=1e-10)
    if np.abs(x).max() > max_distance:
        x = lsq_linear(A, b, bounds=(-max_distance, max_distance)).x
    residual = (A @ x - b).reshape(-1, len(cols))
    rms = lambda e: np.sqrt(np.mean(e**2, axis=0))  # noqa: E731
    return CounterweightPlacement(link, mount, mass, x, built, weighed,
                                  "PWM counts" if "PWM counts" in units else "N m", rms(residual),
                                  np.abs(residual).max(axis=0), rms(effort(full)), rms(base), int(rank),
                                  model_label(params), units)


def _items(values) -> list:
    try:
        return list(values)
    except TypeError:
        return [values]


def _weighing(robot: Robot, params, joints) -> tuple[tuple[str, ...], np.ndarray, tuple[str, ...]]:
    """The joints weighed by a design, their weights (PWM per N m with a drive, else 1) and units."""
    default = robot.actuated if params is None else params.driven
    weighed = tuple(default if joints is None else joints)
    for name in weighed:
        check_actuated(robot, name)
    if params is None or not set(weighed) <= set(params.driven):
        units = tuple("N" if robot.joint_kind(n) == "prismatic" else "N m" for n in weighed)
        return weighed, np.ones(len(weighed)), units
    return weighed, np.array([params[n].pwm_per_torque for n in weighed]), ("PWM counts",) * len(weighed)


def _as_built(full: Robot, without: Robot, mount: str, joint: int, mass: float) -> np.ndarray:
    """The URDF counterweight's centre of mass in the mount link's frame (from the joint body's
    first moments with and without it)."""
    if mass <= 0:
        return np.full(3, np.nan)
    a, b = full.tree.inertias[joint], without.tree.inertias[joint]
    lever = (a.mass * a.lever - b.mass * b.lever) / mass            # in the joint's frame
    frame = full.tree.frames[full.tree.getFrameId(mount)]
    return frame.placement.actInv(pin.SE3(np.eye(3), lever)).translation.copy()

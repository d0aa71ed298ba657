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

import numpy as np
from scipy.optimize import lsq_linear

from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.dynamics.gravity import gravity_batch, point_mass_gravity_batch
from rcm_kin.errors import RcmKinError


@dataclass(frozen=True)
class CounterweightDesign:
    main_mass: float       # kg
    main_distance: float   # m below the roll axis
    dpm_mass: float        # kg
    dpm_distance: float    # m from the pitch pivot
    dpm_angle: float       # rad from straight down, towards the RCM
    rms_pwm: np.ndarray    # (2,) roll, pitch RMS holding PWM over the grid with this design
    peak_pwm: np.ndarray   # (2,) largest |PWM| (both joints, whatever the weights)


def workspace_grid(robot, roll_deg=(-30, 30, 13), pitch_deg=(-30, 30, 13), insertion: float = 0.080) -> np.ndarray:
    """(N, nq) poses on a roll x pitch grid (degrees LO, HI, N) at one insertion (m)."""
    r, p = np.meshgrid(np.radians(np.linspace(*roll_deg)), np.radians(np.linspace(*pitch_deg)))
    Q = np.zeros((r.size, robot.nq))
    Q[:, 0], Q[:, 1], Q[:, 2] = r.ravel(), p.ravel(), insertion
    return Q


def design_counterweights(robot_without, drive: DriveParameters, Q, main_mass: float, dpm_mass: float,
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

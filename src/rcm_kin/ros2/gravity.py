"""The holding effort of the PSM at a measured pose, as arrays (no rclpy): the driven joints'
gravity with the drive file's calibrated offsets, compiled to C once
(:func:`rcm_kin.dynamics.state_space.driven_gravity_function`, :mod:`rcm_kin.symbolic.compiled`),
then the drive model (:func:`rcm_kin.dynamics.drive.drive_effort`: torque -> PWM at rest).
The same numbers as ``rcm-kin gravity`` (Pinocchio's gravity of the closed chain), by another path.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, drive_effort, resolve_drive
from rcm_kin.dynamics.state_space import driven_gravity_function
from rcm_kin.errors import RcmKinError
from rcm_kin.model import Robot
from rcm_kin.ros2.messages import MalformedMessage
from rcm_kin.symbolic.compiled import compiled, single_call


@dataclass(frozen=True)
class GravityOutput:
    q: np.ndarray          # roll rad, pitch rad, insertion m: the pose evaluated
    tau: np.ndarray        # N m, N m, N: holding torque of roll, pitch, insertion
    pwm: np.ndarray        # counts, hardware sign: the PWM that holds it
    saturated: np.ndarray  # bool: |pwm| beyond the firmware's limit


class GravityStep:
    """Measured (roll, pitch, insertion) (rad, rad, m) -> :class:`GravityOutput`."""

    def __init__(self, psm: Robot, drive: DriveParameters | str | Path | None = None):
        params = resolve_drive(psm, drive)
        if params is None or tuple(params.driven) != DRIVEN:
            raise RcmKinError(f"the gravity node needs a drive of {', '.join(DRIVEN)} (`drive`)", parameter="drive")
        self.psm, self.params = psm, params
        self.source = Path(params.source).name if params.source else "drive parameters"
        self._lower = np.array([psm.lower[psm.actuated.index(j)] for j in DRIVEN])
        self._upper = np.array([psm.upper[psm.actuated.index(j)] for j in DRIVEN])
        self._gravity = single_call(compiled(driven_gravity_function(psm, params.gravity_offsets, joints=DRIVEN)))

    def __call__(self, q) -> GravityOutput:
        q = np.asarray(q, dtype=float)
        if q.shape != (3,) or not np.all(np.isfinite(q)):
            raise MalformedMessage("the measured pose is 3 finite numbers (roll, pitch, insertion)")
        if np.any(q < self._lower - 1e-9) or np.any(q > self._upper + 1e-9):
            raise MalformedMessage("the measured pose is outside the joint limits")
        tau = self._gravity(q)[0]
        effort = drive_effort(self.params, tau)
        return GravityOutput(q, tau, effort.pwm, effort.saturated)

"""One teleoperation step per MTM message, as arrays (no rclpy): the MTM wrist centre by forward
kinematics, its displacement from the MTM zero pose through the teleoperation map
(:mod:`rcm_kin.kinematics.teleop`: scale, rotation, home, and a clutch offset) to the PSM
shaft-tip target, and the PSM joints by the closed-form RCM IK
(:func:`rcm_kin.kinematics.psm_ik.clamped_shaft_tip_ik`).

The models, the zero-pose wrist centre and the RCM geometry are built once, in the constructor;
a step evaluates Pinocchio's forward kinematics (compiled C++) on a preallocated configuration and
the closed-form IK. A target out of reach is clamped into the joint limits as the firmware clamps
its angles, and flagged: the joints returned are always within the limits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.psm_ik import ARM, clamped_shaft_tip_ik, rcm_geometry
from rcm_kin.kinematics.teleop import TeleopMap, default_teleop_map, psm_targets
from rcm_kin.model import Robot
from rcm_kin.ros2.messages import MalformedMessage

WRIST = "wrist_center"


@dataclass(frozen=True)
class TeleopOutput:
    displacement: np.ndarray   # m, MTM wrist centre from its zero pose (MTM base)
    target: np.ndarray         # m, PSM shaft-tip target (PSM base), as the map gives it
    reached: np.ndarray        # m, ``target``, or where the clipped ``joints`` put the shaft tip when clamped
    joints: np.ndarray         # roll rad, pitch rad, insertion m: within the joint limits
    clamped: bool              # the target was out of reach and the joints were clipped


class TeleopStep:
    """MTM joint positions (rad, the joints ``mtm_joints``) -> :class:`TeleopOutput`.

    ``clutch(True)`` holds the PSM target where it is while the MTM moves; ``clutch(False)`` takes
    up the MTM from where it is now (the offset between the two is kept), as a clutch pedal does.
    """

    def __init__(self, mtm: Robot, psm: Robot, teleop: TeleopMap | None = None,
                 mtm_joints: tuple[str, ...] = ("j1", "j2", "j3")):
        self.mtm, self.psm = mtm, psm
        self.map = teleop if teleop is not None else default_teleop_map(psm)
        self.mtm_joints = tuple(mtm_joints)
        self._index = [mtm.actuated.index(j) for j in self.mtm_joints]
        self._q = np.zeros(mtm.nq)
        self._zero = frame_placement(mtm, self._q, WRIST).translation.copy()
        self._data = mtm.create_data()
        self._psm_data = psm.create_data()
        self._arm = [psm.actuated.index(j) for j in ARM]
        self._q_psm = np.zeros(psm.nq)
        self.rcm = rcm_geometry(psm).rcm.copy()
        self.offset = np.zeros(3)       # m, added to the map's target (the clutch's take-up)
        self._engaged = False
        self._last: np.ndarray | None = None

    def clutch(self, engaged: bool) -> None:
        self._engaged = bool(engaged)

    def displacement(self, q_mtm) -> np.ndarray:
        q = np.asarray(q_mtm, dtype=float)
        if q.shape != (len(self._index),) or not np.all(np.isfinite(q)):
            raise MalformedMessage(f"the MTM joints are {len(self._index)} finite angles")
        self._q[self._index] = q
        return frame_placement(self.mtm, self._q, WRIST, self._data).translation - self._zero

    def __call__(self, q_mtm) -> TeleopOutput:
        d = self.displacement(q_mtm)
        mapped = psm_targets(self.map, d)
        if self._engaged and self._last is not None:
            self.offset = self._last - mapped        # held: the target stays, the offset follows the MTM
        target = mapped + self.offset
        joints, clamped = clamped_shaft_tip_ik(self.psm, target)
        reached = target
        if clamped:                                  # where the clipped joints put the tip
            self._q_psm[self._arm] = joints
            reached = frame_placement(self.psm, self._q_psm, "shaft_tip", self._psm_data).translation.copy()
        self._last = reached
        return TeleopOutput(d, target, reached, joints, clamped)

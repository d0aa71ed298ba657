"""MTM -> PSM teleoperation map: scaled wrist-centre displacement added to a PSM home point.

As on this robot (osMDV firmware): the PSM target is the home point (shaft tip at insertion
80 mm, roll = pitch = 0) plus the MTM gimbal-centre displacement from the MTM zero pose,
scaled per axis (firmware x 0.05, y 0.25, z 0.05 in its y-up frame). Both base frames here
are z up with the same horizontal axes as the firmware's, so the firmware's vertical scale
0.25 is our z scale.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.psm_ik import shaft_tip_ik

if TYPE_CHECKING:
    from rcm_kin.model import Robot


@dataclass(frozen=True)
class TeleopMap:
    home: np.ndarray                  # PSM shaft-tip target for zero displacement (m, PSM base)
    scale: np.ndarray = field(default_factory=lambda: np.array([0.05, 0.05, 0.25]))  # per PSM base axis
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))  # MTM base axes -> PSM base axes


def default_teleop_map(psm: Robot) -> TeleopMap:
    q_home = np.zeros(psm.nq)
    q_home[psm.actuated.index("insertion")] = HOME_INSERTION
    return TeleopMap(home=frame_placement(psm, q_home, "shaft_tip").translation.copy())


def psm_targets(teleop: TeleopMap, displacement) -> np.ndarray:
    """PSM shaft-tip targets (m) of MTM wrist-centre displacements (m), shape (3,) or (N, 3)."""
    d = np.asarray(displacement, dtype=float)
    if d.shape[-1:] != (3,) or not np.all(np.isfinite(d)):
        raise RcmKinError("MTM displacements are finite x y z triples in metres")
    return teleop.home + (d @ teleop.rotation.T) * teleop.scale


def teleop_joint_targets(psm: Robot, teleop: TeleopMap, displacements) -> np.ndarray:
    """[roll, pitch, insertion] (rad, rad, m) per displacement, shape (N, 3), by the PSM IK."""
    targets = np.atleast_2d(psm_targets(teleop, displacements))
    out = np.empty((len(targets), 3))
    for k, target in enumerate(targets):
        try:
            out[k] = shaft_tip_ik(psm, target)
        except RcmKinError as exc:
            raise RcmKinError(f"MTM sample {k}: {exc}") from None
    return out

"""How well a chain keeps a remote centre of motion: the point nearest to every instrument-shaft
line over a grid of the two RCM joints, and how far the lines pass from it.

For a true RCM mechanism (the PSM's double parallelogram) the lines meet in one point; for a
chain whose parallelogram is only approximated (the da Vinci mimic chain with the thesis's
parameters) they scatter around it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.kinematics.fk import frame_placement

if TYPE_CHECKING:
    from rcm_kin.model import Robot


@dataclass(frozen=True)
class RcmScatter:
    point: np.ndarray        # m, least-squares intersection of the shaft lines, in ``base_frame``
    max_distance: float      # m, largest distance of a shaft line from the point
    rms_distance: float      # m


def rcm_scatter(robot: Robot, shaft_frame: str, joints: tuple[str, str], base_frame: str | None = None,
                points: int = 15, q=None) -> RcmScatter:
    """Shaft lines = the z axis of ``shaft_frame`` over a ``points x points`` grid spanning the
    limits of ``joints`` (the other joints at ``q``, default 0), expressed in ``base_frame``
    (default the robot's base)."""
    index = []
    for j in joints:
        if j not in robot.actuated:
            raise RcmKinError(f"{robot.name} has no actuated joint '{j}'")
        index.append(robot.actuated.index(j))
    q0 = robot.check_q(np.zeros(robot.nq) if q is None else q)
    origins, directions = [], []
    for a in np.linspace(robot.lower[index[0]], robot.upper[index[0]], points):
        for b in np.linspace(robot.lower[index[1]], robot.upper[index[1]], points):
            q = q0.copy()
            q[index] = a, b
            M = frame_placement(robot, q, shaft_frame)
            R, p = np.eye(3), np.zeros(3)
            if base_frame is not None:
                base = frame_placement(robot, q, base_frame)
                R, p = base.rotation, base.translation
            origins.append(R.T @ (M.translation - p))
            directions.append(R.T @ M.rotation[:, 2])
    projectors = [np.eye(3) - np.outer(u, u) for u in directions]
    point = np.linalg.solve(sum(projectors), sum(P @ o for P, o in zip(projectors, origins)))
    distances = np.array([np.linalg.norm(P @ (point - o)) for P, o in zip(projectors, origins)])
    return RcmScatter(point, float(distances.max()), float(np.sqrt(np.mean(distances**2))))

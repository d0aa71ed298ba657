"""A matplotlib drawing of a robot's URDF geometry (boxes, cylinders, spheres) at a pose: the
picture for documents, where a WebGL page cannot go."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from rcm_kin.atomic import atomic_path
from rcm_kin.model.geometry import visual_geometry
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.plotting import figure_format, subplots

if TYPE_CHECKING:
    from rcm_kin.model import Robot

_CUBE = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) / 2
_CUBE_FACES = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]


def _faces(geometry) -> list[np.ndarray]:
    """Polygons (in the geometry's frame) of a box or a cylinder (axis z); spheres as a small box."""
    name = type(geometry).__name__
    if name == "Box":
        corners = _CUBE * 2 * np.asarray(geometry.halfSide)
        return [corners[f] for f in _CUBE_FACES]
    if name == "Cylinder":
        a = np.linspace(0, 2 * np.pi, 17)[:-1]
        ring = np.column_stack([geometry.radius * np.cos(a), geometry.radius * np.sin(a)])
        bottom = np.column_stack([ring, np.full(16, -geometry.halfLength)])
        top = np.column_stack([ring, np.full(16, geometry.halfLength)])
        sides = [np.array([bottom[i], bottom[(i + 1) % 16], top[(i + 1) % 16], top[i]]) for i in range(16)]
        # the caps as degenerate quads: every polygon has 4 vertices (mplot3d mishandles mixed counts)
        caps = [np.array([ring_[i], ring_[(i + 1) % 16], centre, centre]) for ring_, centre in
                ((bottom, [0.0, 0.0, -geometry.halfLength]), (top, [0.0, 0.0, geometry.halfLength]))
                for i in range(16)]
        return sides + caps
    if name == "Sphere":
        corners = _CUBE * 2 * geometry.radius
        return [corners[f] for f in _CUBE_FACES]
    return []


def robot_drawing(robot: Robot, q, path: str | Path, title: str = "", view=(20.0, -60.0),
                  package_dirs=None) -> Path:
    """Draw ``robot`` at actuated ``q`` (rad, m) in its base frame (z up) and save a PNG
    (``package_dirs`` finds ``package://`` meshes: see :func:`~rcm_kin.model.geometry.visual_geometry`)."""
    visual = visual_geometry(robot, package_dirs)
    data = visual.createData()
    pin.forwardKinematics(robot.tree, robot.tree_data, tree_configuration(robot, robot.check_q(q, allow_short=True)))
    pin.updateGeometryPlacements(robot.tree, robot.tree_data, visual, data)
    fig, ax = subplots(figsize=(6, 6), subplot_kw={"projection": "3d"})
    points = []
    for obj, placement in zip(visual.geometryObjects, data.oMg):
        polygons = [f @ placement.rotation.T + placement.translation for f in _faces(obj.geometry)]
        if not polygons:
            continue
        points.append(np.vstack(polygons))
        ax.add_collection3d(Poly3DCollection(polygons, facecolor=obj.meshColor[:3], edgecolor=(0, 0, 0, 0.15),
                                             linewidth=0.3, alpha=float(obj.meshColor[3])))
    points = np.vstack(points)
    centre, half = points.mean(axis=0), np.ptp(points, axis=0).max() / 2
    ax.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
           zlim=(centre[2] - half, centre[2] + half), xlabel="x (m)", ylabel="y (m)", zlabel="z (m)", title=title)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(*view)
    path = Path(path)
    with atomic_path(path) as temporary:
        fig.savefig(temporary, dpi=110, bbox_inches="tight", format=figure_format(path))
    return path

"""The side camera that frames a robot: one definition for the self-contained meshcat page and the
browser's PNG render.

The camera sits ``distance`` m from ``target`` on the -y side of the base frame and looks along +y
(the plane of the PSM's parallelograms), with meshcat's vertical field of view of 75 deg. The target
is the centre of the box around the robot's visual geometry (each element's own bounding box,
placed by the kinematics); the distance puts the larger of the box's width (x) and height (z)
across ``1 / margin`` of the picture's height at the box's near face.

meshcat (python 0.3.2, its viewer on three.js r129) places the camera as the object
``/Cameras/default/rotated/<object>`` in a frame turned +90 deg about x from the scene's (y up):
a scene point (x, y, z) is (x, z, -y) there. Its orbit controls look at ``controls.target``, in
that same frame; the viewer has no command for it (later meshcat versions send ``set_target``),
so :class:`~rcm_kin.visualization.offline.OfflineWindow` records the ``set_target`` command and
its page sets the target after replaying the scene.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.model.geometry import visual_geometry
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.visualization.offline import OfflineWindow

if TYPE_CHECKING:
    from pinocchio.visualize import MeshcatVisualizer

    from rcm_kin.model import Robot

FIELD_OF_VIEW = np.radians(75.0)     # meshcat's default camera: vertical field of view (rad)
CAMERA_PATH = "/Cameras/default/rotated/<object>"
MARGIN = 1.5                         # the picture's height over the robot's larger extent
_CORNERS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)


@dataclass(frozen=True)
class SideCamera:
    """A camera ``distance`` m on the -y side of ``target`` (m, base frame), looking along +y."""

    target: np.ndarray
    distance: float

    @property
    def position(self) -> np.ndarray:
        """The camera's position (m, base frame)."""
        return np.asarray(self.target, dtype=float) - np.array([0.0, self.distance, 0.0])

    def pixels_per_metre(self, height_px: int) -> float:
        """Image scale at the target's depth (pinhole, meshcat's field of view)."""
        return height_px / (2.0 * self.distance * np.tan(FIELD_OF_VIEW / 2.0))


class SetCameraTarget:
    """The ``set_target`` command of later meshcat viewers: the point the orbit controls look at,
    in the camera's (y-up) frame."""

    def __init__(self, value):
        self.value = [float(v) for v in value]

    def lower(self) -> dict:
        """The command as meshcat sends it."""
        return {"type": "set_target", "path": "", "value": self.value}


def y_up(point) -> list[float]:
    """A scene point (z up) in the camera's frame (y up)."""
    x, y, z = (float(v) for v in point)
    return [x, z, -y]


def geometry_points(visual: pin.GeometryModel, data: pin.GeometryData, corners: list | None = None) -> np.ndarray:
    """The corners (N, 3) m, base frame, of each visual element's own bounding box, placed;
    ``corners``: :func:`local_corners` of ``visual`` when already computed (an animation's frames)."""
    placements = data.oMg
    points = [local @ placements[k].rotation.T + placements[k].translation
              for k, local in (local_corners(visual) if corners is None else corners)]
    return np.vstack(points) if points else np.empty((0, 3))


def local_corners(visual: pin.GeometryModel) -> list[tuple[int, np.ndarray]]:
    """The corners (8, 3) m of each visual element's own bounding box in the element's frame, with
    the element's index: those whose box is finite."""
    corners = []
    for k, obj in enumerate(visual.geometryObjects):
        geometry = obj.geometry
        geometry.computeLocalAABB()
        low, high = np.asarray(geometry.aabb_local.min_), np.asarray(geometry.aabb_local.max_)
        if np.all(np.isfinite(low)) and np.all(np.isfinite(high)):
            corners.append((k, low + _CORNERS * (high - low)))
    return corners


def framing(points: np.ndarray, margin: float = MARGIN) -> SideCamera:
    """The side camera framing ``points`` (N, 3) m: see the module."""
    points = np.atleast_2d(np.asarray(points, dtype=float))
    if len(points) == 0 or not np.all(np.isfinite(points)) or not margin > 0:
        raise RcmKinError("a camera frames at least one finite point with a positive `margin`", parameter="margin")
    low, high = points.min(axis=0), points.max(axis=0)
    extent = max(high[0] - low[0], high[2] - low[2], 1e-3)
    near = margin * extent / (2.0 * np.tan(FIELD_OF_VIEW / 2.0))
    return SideCamera(0.5 * (low + high), float(near + 0.5 * (high[1] - low[1])))


def pose_points(robot: Robot, tree_data: pin.Data, visual: pin.GeometryModel, data: pin.GeometryData,
                q) -> np.ndarray:
    """The points a camera frames with the robot at actuated ``q``: its visual geometry's box
    corners, or its joints' origins when it has no visual geometry."""
    pin.forwardKinematics(robot.tree, tree_data, tree_configuration(robot, robot.check_q(q, allow_short=True)))
    pin.updateGeometryPlacements(robot.tree, tree_data, visual, data)
    points = geometry_points(visual, data)
    return points if len(points) else np.array([m.translation for m in tree_data.oMi])


def side_camera(robot: Robot, q, margin: float = MARGIN, package_dirs=None) -> SideCamera:
    """A side camera framing the robot at actuated ``q`` (rad, m), or over every pose of a
    trajectory ``q`` (N, nq); ``package_dirs`` as for
    :func:`~rcm_kin.model.geometry.visual_geometry`."""
    visual = visual_geometry(robot, package_dirs)
    data, tree_data = visual.createData(), robot.tree.createData()
    poses = np.asarray(q, dtype=float)
    poses = poses.reshape(1, -1) if poses.ndim < 2 else poses
    return framing(np.vstack([pose_points(robot, tree_data, visual, data, p) for p in poses]), margin)


def view_points(viz: MeshcatVisualizer, corners: list | None = None) -> np.ndarray:
    """The points a camera frames in the view ``viz`` at the pose it shows last (``corners`` as for
    :func:`geometry_points`)."""
    points = geometry_points(viz.visual_model, viz.visual_data, corners)
    return points if len(points) else np.array([m.translation for m in viz.data.oMi])


def set_camera(viz: MeshcatVisualizer, camera: SideCamera) -> None:
    """Record ``camera`` in the view: its position as a meshcat property, its target as a
    ``set_target`` command (an offline window only: the live viewer of meshcat 0.3.2 has none)."""
    window = viz.viewer.window
    if not isinstance(window, OfflineWindow):
        raise RcmKinError("a camera target can be recorded in an offline meshcat window only")
    viz.viewer[CAMERA_PATH].set_property("position", y_up(camera.position))
    window.send(SetCameraTarget(y_up(camera.target)))

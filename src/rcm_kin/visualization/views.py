"""meshcat views of a robot through Pinocchio's ``MeshcatVisualizer``: the URDF's primitive
geometry placed by the open tree (the loop's passive joints solved from the actuated ones),
frames of interest on demand, trajectory animations, and a trail of points coloured by a scalar.

A view is served live (``meshcat.Visualizer()`` starts the meshcat server) or kept offline
(:class:`rcm_kin.visualization.offline.OfflineWindow`) and written with :func:`write_html`, which
records the side camera of :mod:`rcm_kin.visualization.camera` in the page (the camera of the
browser's PNG render): the page opens with the robot framed.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib
import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
from meshcat.animation import Animation, AnimationFrameVisualizer

from rcm_kin.atomic import write_text
from rcm_kin.errors import RcmKinError
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.model.geometry import visual_geometry
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.model.robot import check_robot
from rcm_kin.visualization.camera import SideCamera, framing, local_corners, set_camera, view_points
from rcm_kin.visualization.offline import OfflineWindow

if TYPE_CHECKING:
    from rcm_kin.model import Robot


def _meshcat_visualizer() -> type:
    """Pinocchio's ``MeshcatVisualizer``. Its package imports every viewer it has, the Viser one
    with trimesh (0.6-0.8 s: SciPy's spatial, networkx) even when viser is not installed and that
    viewer cannot work; then trimesh is kept out of that one import (the Viser viewer finds no
    viser, as it would anyway) and left for whoever needs it."""
    keep_out = "trimesh" not in sys.modules and importlib.util.find_spec("viser") is None
    if keep_out:
        sys.modules["trimesh"] = None            # `import trimesh` raises ImportError
    try:
        from pinocchio.visualize import MeshcatVisualizer
    finally:
        if keep_out and sys.modules.get("trimesh", 0) is None:
            del sys.modules["trimesh"]
    return MeshcatVisualizer


MeshcatVisualizer = _meshcat_visualizer()


def robot_view(robot: Robot, window=None, frames: tuple[str, ...] = (), package_dirs=None) -> MeshcatVisualizer:
    """A Pinocchio meshcat visualizer of ``robot`` (offline unless a ``window`` is given, e.g. a
    live ``meshcat.Visualizer().window``), showing ``frames`` (names of the robot's frames of
    interest) as axis triads; ``package_dirs`` ({NAME: folder}) finds ``package://`` meshes, as
    for :func:`~rcm_kin.model.geometry.visual_geometry`."""
    visual = visual_geometry(check_robot(robot), package_dirs)
    viz = MeshcatVisualizer(robot.tree, pin.GeometryModel(), visual)
    viz.initViewer(viewer=meshcat.Visualizer(window=window or OfflineWindow(robot.name)))
    viz.loadViewerModel(rootNodeName=robot.name)
    if frames:
        unknown = [f for f in frames if not robot.tree.existFrame(f)]
        if unknown:
            raise RcmKinError(f"{robot.name} has no frame {unknown[0]} (see rcm-kin info {robot.name})")
        viz.displayFrames(True, [robot.tree.getFrameId(f) for f in frames], axis_length=0.05, axis_width=3)
    return viz


def show(viz: MeshcatVisualizer, robot: Robot, q) -> None:
    """Place the robot at actuated ``q`` (rad, m)."""
    viz.display(tree_configuration(robot, robot.check_q(q, allow_short=True)))


def animate(viz: MeshcatVisualizer, robot: Robot, Q: np.ndarray, period: float, every: int = 1) -> None:
    """Record the actuated trajectory ``Q`` (N, nq) sampled every ``period`` s as a meshcat
    animation (every ``every``-th sample), played in the page's controls; an offline view records
    the side camera framing every recorded pose. The keyframes are meshcat's (:class:`KeyframeRecorder`)."""
    Q = np.atleast_2d(Q)
    if not (period > 0 and every >= 1 and len(Q) >= 2):
        raise RcmKinError("an animation needs at least 2 poses, a positive period and every >= 1")
    fps = 1.0 / (period * every)
    animation = Animation(default_framerate=fps)
    live = viz.viewer
    points, kept, corners = [], [], local_corners(viz.visual_model)
    try:
        for k, q in enumerate(Q[::every]):
            viz.viewer = KeyframeRecorder(animation, live.path, k, kept)   # the visualizer's transforms land here
            show(viz, robot, q)
            points.append(view_points(viz, corners))
    finally:
        viz.viewer = live
    write_keyframes(kept)
    live.set_animation(animation, play=False)
    if isinstance(live.window, OfflineWindow):
        set_camera(viz, framing(np.vstack(points)))


class KeyframeRecorder(AnimationFrameVisualizer):
    """meshcat's ``AnimationFrameVisualizer`` (``animation.at_frame``) that keeps what it is sent in
    ``kept`` instead of writing keyframes: :func:`write_keyframes` writes them all at once, the same
    keyframes in the same order, the rotations' quaternions computed together (:func:`js_quaternions`)."""

    __slots__ = ["kept"]

    def __init__(self, animation: Animation, path, current_frame: int, kept: list):
        super().__init__(animation, path, current_frame)
        self.kept = kept

    def set_transform(self, matrix) -> None:
        self.kept.append((self.get_clip(), self.current_frame, np.array(matrix, dtype=np.float64)))

    def set_property(self, prop, jstype, value) -> None:
        self.kept.append((self.get_clip(), self.current_frame, (prop, jstype, value)))

    def __getitem__(self, path) -> KeyframeRecorder:
        return KeyframeRecorder(self.animation, self.path.append(path), self.current_frame, self.kept)


def write_keyframes(kept: list) -> None:
    """Write the keyframes a :class:`KeyframeRecorder` kept, in their order, as meshcat's frame
    visualizer writes them: a transform as its ``position`` then its ``quaternion`` keyframe."""
    transforms = [entry[2] for entry in kept if isinstance(entry[2], np.ndarray)]
    quaternions = iter(js_quaternions(np.array(transforms).reshape(-1, 4, 4)))
    for clip, frame, what in kept:
        if isinstance(what, np.ndarray):
            clip.set_property(frame, "position", "vector3", list(what[:3, 3]))
            clip.set_property(frame, "quaternion", "quaternion", list(next(quaternions)))
        else:
            clip.set_property(frame, what[0], what[1], what[2])


def js_quaternions(matrices: np.ndarray) -> np.ndarray:
    """The quaternions (N, 4), (x, y, z, w), of homogeneous transforms (N, 4, 4): a declared twin
    of meshcat's ``animation.js_quaternion`` (``transformations.quaternion_from_matrix``, the
    eigenvector method), the same floats bit for bit (``tests/visualization/test_views.py``), for
    all the matrices in one ``eigh`` call instead of one call each."""
    m = matrices
    K = np.zeros((len(m), 4, 4))
    K[:, 0, 0] = m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2]
    K[:, 1, 0], K[:, 1, 1] = m[:, 0, 1] + m[:, 1, 0], m[:, 1, 1] - m[:, 0, 0] - m[:, 2, 2]
    K[:, 2, 0], K[:, 2, 1] = m[:, 0, 2] + m[:, 2, 0], m[:, 1, 2] + m[:, 2, 1]
    K[:, 2, 2] = m[:, 2, 2] - m[:, 0, 0] - m[:, 1, 1]
    K[:, 3, 0], K[:, 3, 1], K[:, 3, 2] = m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]
    K[:, 3, 3] = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    K /= 3.0
    w, V = np.linalg.eigh(K)
    q = np.take_along_axis(V, np.argmax(w, axis=1)[:, None, None], axis=2)[:, [3, 0, 1, 2], 0]   # (w, x, y, z)
    q = np.where(q[:, :1] < 0.0, -q, q)
    return q[:, [1, 2, 3, 0]]


def scalar_trail(viz: MeshcatVisualizer, name: str, points: np.ndarray, values: np.ndarray,
                 cmap: str = "coolwarm", size: float = 0.004) -> tuple[float, float]:
    """Points (N, 3) m in the base frame coloured by ``values`` (N,) through a matplotlib colour
    map (symmetric about 0 when the values change sign). Returns the colour range."""
    points, values = np.atleast_2d(points), np.asarray(values, dtype=float)
    if points.shape[1:] != (3,) or len(points) != len(values) or not np.all(np.isfinite(values)):
        raise RcmKinError("a trail needs N finite values for N points (x, y, z in m)")
    low, high = float(values.min()), float(values.max())
    if low < 0 < high:
        low, high = -max(-low, high), max(-low, high)
    span = high - low or 1.0
    colours = matplotlib.colormaps[cmap]((values - low) / span)[:, :3]
    viz.viewer[f"trails/{name}"].set_object(mg.PointCloud(points.T, colours.T, size=size))
    return low, high


def frame_path(robot: Robot, Q: np.ndarray, frame: str) -> np.ndarray:
    """Positions (N, 3) m of ``frame`` along the actuated trajectory ``Q``."""
    return np.array([frame_placement(robot, q, frame).translation for q in np.atleast_2d(Q)])


def write_html(viz: MeshcatVisualizer, path: str | Path, camera: SideCamera | None = None) -> Path:
    """Write the view as one self-contained HTML page. An offline view's page opens on ``camera``:
    by default the camera already recorded in the view (:func:`animate` records one), else the
    side camera framing the pose the view shows (:func:`~rcm_kin.visualization.camera.side_camera`'s).
    (A live view's page is the meshcat server's, on meshcat's default camera.)"""
    if not isinstance(viz, MeshcatVisualizer):
        raise RcmKinError(f"`viz` is a view (rk.robot_view), got {type(viz).__name__}", parameter="viz")
    path = Path(path)
    window = viz.viewer.window
    if isinstance(window, OfflineWindow) and (camera is not None or window.camera_target is None):
        set_camera(viz, camera or framing(view_points(viz)))
    try:
        write_text(path, viz.viewer.static_html())
    except OSError as exc:
        raise RcmKinError(f"cannot write {path}: {exc.strerror}") from None
    return path

"""The meshcat page rendered by a real browser: headless Chromium draws the WebGL scene (software
GL, SwiftShader) and writes a PNG screenshot.

The screenshot scene is the robot alone on white (grid and axes hidden), seen from the side: the
camera sits ``distance`` m from ``target`` on the -y side of the base frame, looking along +y
(the plane of the PSM's parallelograms), with meshcat's vertical field of view of 75 deg. (The
meshcat camera looks at the scene origin, so the robot is shifted by ``-target``.)
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import meshcat.transformations as tf
import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError
from rcm_kin.model.geometry import visual_geometry
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.visualization.views import robot_view, show, write_html

if TYPE_CHECKING:
    from rcm_kin.model import Robot

HIDE_CONTROLS = ".dg{display:none !important}"   # CSS: the screenshot leaves out meshcat's control panel (dat.GUI)
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
FIELD_OF_VIEW = np.radians(75.0)     # meshcat's default camera: vertical field of view (rad)
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
LOG_PREFIX = re.compile(r"^\[[\d:/.]+:(?P<level>[A-Z]+):[^\]]*\]\s*")   # Chromium's "[pid:tid:time:LEVEL:file(line)] "


@dataclass(frozen=True)
class SideCamera:
    target: np.ndarray     # m, base frame: the point looked at
    distance: float        # m: along -y from the target to the camera

    def pixels_per_metre(self, height_px: int) -> float:
        """Image scale at the target's depth (pinhole, meshcat's field of view)."""
        return height_px / (2.0 * self.distance * np.tan(FIELD_OF_VIEW / 2.0))


def find_browser() -> str | None:
    """The path of a Chromium-family browser on PATH, or None."""
    return next((path for name in BROWSERS if (path := shutil.which(name))), None)


def side_camera(robot: Robot, q, margin: float = 1.5) -> SideCamera:
    """A side camera framing the robot's visual geometry at actuated ``q`` (its placements' box)."""
    visual = visual_geometry(robot)
    data = visual.createData()
    pin.forwardKinematics(robot.tree, robot.tree_data, tree_configuration(robot, robot.check_q(q, allow_short=True)))
    pin.updateGeometryPlacements(robot.tree, robot.tree_data, visual, data)
    points = np.array([m.translation for m in data.oMg])
    low, high = points.min(axis=0), points.max(axis=0)
    extent = max(high[0] - low[0], high[2] - low[2])
    return SideCamera(0.5 * (low + high), margin * extent / (2.0 * np.tan(FIELD_OF_VIEW / 2.0)))


def screenshot(page: str | Path, png: str | Path, size: tuple[int, int] = (800, 600),
               budget_ms: int = 5000, timeout: float = 120.0) -> Path:
    """Render the HTML ``page`` in headless Chromium and write the ``size`` (w, h px) screenshot.

    Chromium draws into a fresh temporary file, moved onto ``png`` only when it is a PNG (Chromium
    exits 0 even when it writes nothing): a failure leaves an existing ``png`` as it was and raises
    :class:`RcmKinError` with Chromium's last error line."""
    browser = find_browser()
    if browser is None:
        raise RcmKinError("no Chromium to render the page: install it (Debian: apt-get install chromium) "
                          "or use the matplotlib `renderer`", parameter="renderer")
    page, png = Path(page).resolve(), Path(png).resolve()
    with tempfile.TemporaryDirectory(prefix="rcm-kin-chromium-") as folder:
        shot, profile = Path(folder) / "screenshot.png", Path(folder) / "profile"
        try:
            run = subprocess.run([browser, *FLAGS, f"--user-data-dir={profile}", f"--virtual-time-budget={budget_ms}",
                                  f"--window-size={size[0]},{size[1]}", f"--screenshot={shot}", page.as_uri()],
                                 capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired:
            raise RcmKinError(f"{browser} did not render {page.name} within {timeout:g} s") from None
        if run.returncode != 0 or not _is_png(shot):
            outcome = "no PNG written" if run.returncode == 0 else f"exit {run.returncode}"
            raise RcmKinError(f"{browser} could not render {page.name} ({outcome}): {_last_error(run.stderr)}")
        shutil.move(shot, png)
    return png


def _is_png(path: Path) -> bool:
    """Whether ``path`` is a file starting with the PNG signature."""
    if not path.is_file():
        return False
    with path.open("rb") as f:
        return f.read(len(PNG_SIGNATURE)) == PNG_SIGNATURE


def _last_error(log: str) -> str:
    """Chromium's last ERROR or FATAL line of ``log`` (else its last line), without the
    ``[pid:tid:time:LEVEL:file(line)]`` prefix: one readable line."""
    lines = [line.strip() for line in log.splitlines() if line.strip()]
    errors = [line for line in lines if (m := LOG_PREFIX.match(line)) and m["level"] in ("ERROR", "FATAL")]
    last = (errors or lines or ["no message"])[-1]
    return LOG_PREFIX.sub("", last) or "no message"


def browser_png(robot: Robot, q, png: str | Path, frames: tuple[str, ...] = (), size: tuple[int, int] = (800, 600),
                camera: SideCamera | None = None) -> Path:
    """The robot at actuated ``q`` (rad, m) in its meshcat page, as Chromium draws it, in ``png``."""
    viz = robot_view(robot, frames=frames)
    show(viz, robot, q)
    camera = camera or side_camera(robot, q)
    viewer = viz.viewer
    for side in ("top_color", "bottom_color"):
        viewer["/Background"].set_property(side, [1.0, 1.0, 1.0])
    viewer["/Grid"].set_property("visible", False)
    viewer["/Axes"].set_property("visible", False)
    # the viewer's camera always looks at the origin: the robot moves so that the target sits there
    viewer[robot.name].set_transform(tf.translation_matrix(-camera.target))
    viewer["/Cameras/default/rotated/<object>"].set_property("position", [0.0, 0.0, camera.distance])  # y-up frame
    with tempfile.TemporaryDirectory(prefix="rcm-kin-page-") as folder:
        page = write_html(viz, Path(folder) / "view.html")
        page.write_text(page.read_text().replace("</style>", HIDE_CONTROLS + "</style>", 1))
        return screenshot(page, png, size)

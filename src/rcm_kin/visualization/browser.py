"""The meshcat page rendered by a real browser: headless Chromium draws the WebGL scene (software
GL, SwiftShader) and writes a PNG screenshot.

The screenshot scene is the robot alone on white (grid and axes hidden), seen from the side
camera of :mod:`rcm_kin.visualization.camera`: the page is the one :func:`write_html` writes, with
the same camera.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from rcm_kin.atomic import atomic_path, write_text
from rcm_kin.errors import RcmKinError
from rcm_kin.visualization.camera import FIELD_OF_VIEW, SideCamera, side_camera
from rcm_kin.visualization.views import robot_view, show, write_html

__all__ = ["FIELD_OF_VIEW", "SideCamera", "browser_png", "find_browser", "screenshot", "side_camera"]

if TYPE_CHECKING:
    from rcm_kin.model import Robot

HIDE_CONTROLS = ".dg{display:none !important}"   # CSS: the screenshot leaves out meshcat's control panel (dat.GUI)
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars")
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
LOG_PREFIX = re.compile(r"^\[[\d:/.]+:(?P<level>[A-Z]+):[^\]]*\]\s*")   # Chromium's "[pid:tid:time:LEVEL:file(line)] "


def find_browser() -> str | None:
    """The path of a Chromium-family browser on PATH, or None."""
    return next((path for name in BROWSERS if (path := shutil.which(name))), None)


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
    page, out = Path(page).resolve(), Path(png)        # out unresolved: a link out of its folder is refused
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
        with atomic_path(out) as temporary:       # the folders may be on different file systems
            shutil.copyfile(shot, temporary)
    return out.resolve()


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
                camera: SideCamera | None = None, package_dirs=None) -> Path:
    """The robot at actuated ``q`` (rad, m) in its meshcat page, as Chromium draws it, in ``png``:
    the page :func:`write_html` writes (on ``camera``, by default the side camera framing the
    pose), on white, without grid, axes and controls."""
    viz = robot_view(robot, frames=frames, package_dirs=package_dirs)
    show(viz, robot, q)
    viewer = viz.viewer
    for side in ("top_color", "bottom_color"):
        viewer["/Background"].set_property(side, [1.0, 1.0, 1.0])
    viewer["/Grid"].set_property("visible", False)
    viewer["/Axes"].set_property("visible", False)
    with tempfile.TemporaryDirectory(prefix="rcm-kin-page-") as folder:
        page = write_html(viz, Path(folder) / "view.html", camera)
        write_text(page, page.read_text().replace("</style>", HIDE_CONTROLS + "</style>", 1))
        return screenshot(page, png, size)

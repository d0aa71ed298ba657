"""A drawing and a self-contained meshcat page of each bundled robot."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.model import load_robot
from rcm_kin.report.render import relative

VIEW_POSES = {"psm": [np.radians(10.0), np.radians(-15.0), 0.10], "mtm": [0.3, 0.2, 0.4],
              "davinci": [0.0, 0.3, -0.4, 0.2, 0.0, 0.0, 0.2, 0.3, 0.05]}
VIEW_FRAMES = {"psm": ("rcm", "shaft_tip", "tool_tip"), "mtm": ("wrist_center", "tool_tip"),
               "davinci": ("rcm_base_link", "jaw_right_link")}


@dataclass(frozen=True)
class RobotView:
    name: str
    picture: str     # PNG, relative to the report folder
    page: str        # meshcat HTML


@dataclass(frozen=True)
class RobotsSection:
    template: ClassVar[str] = "robots.html.j2"
    views: tuple[RobotView, ...]


def robots_section(out: Path, names=tuple(VIEW_POSES)) -> RobotsSection:
    """Draw each robot of ``names`` at its view pose and write its meshcat page into ``out``."""
    from rcm_kin.visualization.drawing import robot_drawing
    from rcm_kin.visualization.views import robot_view, show, write_html

    views = []
    for name in names:
        robot, q = load_robot(name), VIEW_POSES[name]
        picture = robot_drawing(robot, q, out / f"{name}.png", title=name.upper())
        viz = robot_view(robot, frames=VIEW_FRAMES[name])
        show(viz, robot, q)
        page = write_html(viz, out / f"{name}_view.html")
        views.append(RobotView(name, relative(picture, out), relative(page, out)))
    return RobotsSection(tuple(views))

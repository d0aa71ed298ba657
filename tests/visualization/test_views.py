"""meshcat views: self-contained pages with the robots' geometry, animations, scalar trails."""

from __future__ import annotations

import base64
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import umsgpack

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.visualization.drawing import robot_drawing
from rcm_kin.visualization.views import animate, frame_path, robot_view, scalar_trail, show, write_html


def page_commands(path):
    """The meshcat commands a page replays, decoded (what the viewer will draw)."""
    text = path.read_text()
    return text, [umsgpack.unpackb(base64.b64decode(c)) for c in re.findall(r'load\("([A-Za-z0-9+/=]+)"\)', text)]


def urdf_visuals(robot):
    """(link, geometry kind) of every visual element in the robot's URDF, read with ElementTree."""
    kinds = {"box": "BoxGeometry", "cylinder": "CylinderGeometry", "sphere": "SphereGeometry"}
    out = []
    for link in ET.parse(robot.description.urdf).getroot().iter("link"):
        for k, visual in enumerate(link.iter("visual")):
            shape = next(iter(visual.find("geometry")))
            out.append((f"{link.get('name')}_{k}", kinds[shape.tag]))
    return out


@pytest.mark.parametrize("name", ["psm", "mtm", "davinci"])
def test_static_page_holds_the_robot_geometry(tmp_path, name):
    from rcm_kin import load_robot

    robot = load_robot(name)
    viz = robot_view(robot)
    show(viz, robot, np.zeros(robot.nq))
    text, commands = page_commands(write_html(viz, tmp_path / "view.html"))
    assert "<script src" not in text and "http://" not in text.split("<script>")[0]
    objects = {c["path"].rsplit("/", 1)[-1]: c["object"]["geometries"][0]["type"]
               for c in commands if c["type"] == "set_object" and "/visuals/" in c["path"]}
    assert objects == dict(urdf_visuals(robot))
    placed = {c["path"].rsplit("/", 1)[-1] for c in commands if c["type"] == "set_transform"}
    assert set(objects) <= placed


def test_placements_follow_the_kinematics(tmp_path, psm):
    """The shaft-tip marker is drawn where FK puts the shaft tip."""
    from rcm_kin.kinematics.fk import frame_placement

    q = [0.2, -0.3, 0.12, 0, 0, 0, 0]
    viz = robot_view(psm)
    show(viz, psm, q)
    _, commands = page_commands(write_html(viz, tmp_path / "view.html"))
    T = [np.array(c["matrix"]).reshape(4, 4).T for c in commands
         if c["type"] == "set_transform" and c["path"].endswith("shaft_tip_0")][-1]
    np.testing.assert_allclose(T[:3, 3], frame_placement(psm, q, "shaft_tip").translation, atol=1e-6)


def test_animation_and_scalar_trail(tmp_path, psm):
    Q = np.zeros((20, psm.nq))
    Q[:, 0] = np.linspace(-0.3, 0.3, 20)
    Q[:, 2] = 0.08
    viz = robot_view(psm, frames=("rcm", "tool_tip"))
    animate(viz, psm, Q, 0.05)
    low, high = scalar_trail(viz, "pwm", frame_path(psm, Q, "tool_tip"), np.linspace(-20.0, 60.0, 20))
    assert (low, high) == (-60.0, 60.0)                               # symmetric about zero
    _, commands = page_commands(write_html(viz, tmp_path / "anim.html"))
    animation = [c for c in commands if c["type"] == "set_animation"]
    assert len(animation) == 1 and len(animation[0]["animations"]) >= 20
    trail = [c for c in commands if c["type"] == "set_object" and c["path"].endswith("trails/pwm")]
    assert len(trail) == 1
    with pytest.raises(RcmKinError, match="frame"):
        robot_view(psm, frames=("nowhere",))


def test_drawing_and_view_cli(tmp_path, capsys):
    assert main(["view", "psm", "--q", "10", "-5", "0.08", "--deg", "--html", str(tmp_path / "p.html"),
                 "--png", str(tmp_path / "p.png"), "--frames", "rcm"]) == 0
    assert (tmp_path / "p.html").stat().st_size > 100_000 and (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"
    assert main(["view", "psm", "--frames", "nowhere", "--html", str(tmp_path / "x.html")]) == 2
    assert capsys.readouterr().err.startswith("error:")


def test_drawing_is_a_png(tmp_path, mtm):
    assert robot_drawing(mtm, [0.3, 0.2, 0.4], tmp_path / "m.png").read_bytes()[:4] == b"\x89PNG"

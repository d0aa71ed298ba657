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
from rcm_kin.visualization.views import animate, frame_path, js_quaternions, robot_view, scalar_trail, show, write_html


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


def test_quaternions_together_are_meshcats_bit_for_bit():
    """js_quaternions is a declared twin of meshcat's js_quaternion (quaternion_from_matrix)."""
    from meshcat.animation import js_quaternion
    from meshcat.transformations import random_rotation_matrix, rotation_matrix

    rng = np.random.default_rng(3)
    matrices = [random_rotation_matrix(rng.random(3)) for _ in range(500)]
    matrices += [np.eye(4), np.diag([1.0, -1.0, -1.0, 1.0]), np.diag([-1.0, 1.0, -1.0, 1.0]),
                 rotation_matrix(np.pi, [0.0, 0.0, 1.0]), rotation_matrix(1e-9, [1.0, 2.0, 3.0])]
    for m in matrices[:50]:
        m[:3, :3] *= 1.7          # a scaled transform, as meshcat's visualizer sends for a mesh's scale
    expected = np.array([js_quaternion(m) for m in matrices])
    got = js_quaternions(np.array(matrices))
    assert got.tobytes() == expected.tobytes()


def test_animation_keyframes_are_meshcats(psm):
    """animate writes the keyframes meshcat's own frame visualizer (animation.at_frame) writes."""
    from meshcat.animation import Animation

    Q = np.zeros((30, psm.nq))
    Q[:, 0], Q[:, 1], Q[:, 2] = np.linspace(-0.3, 0.4, 30), np.linspace(0.2, -0.5, 30), 0.1
    viz = robot_view(psm, frames=("rcm", "tool_tip"))
    sent = []
    viz.viewer.window.send = sent.append
    animate(viz, psm, Q, 0.01, every=2)
    reference, live = Animation(default_framerate=50.0), viz.viewer
    for k, q in enumerate(Q[::2]):
        with reference.at_frame(live, k) as frame:
            viz.viewer = frame
            show(viz, psm, q)
    viz.viewer = live
    animation = next(c for c in sent if type(c).__name__ == "SetAnimation").animation
    assert animation.lower() == reference.lower() and len(animation.clips) > 5


def test_offline_commands_packed_as_umsgpack_does(psm):
    """OfflineWindow's pack is a declared twin of umsgpack.packb (what meshcat's server sends)."""
    from rcm_kin.visualization.offline import OfflineWindow, pack

    sent = []

    class Recording(OfflineWindow):
        def send(self, command):
            sent.append(command.lower())
            super().send(command)

    viz = robot_view(psm, window=Recording(), frames=("tool_tip",))
    Q = np.zeros((5, psm.nq))
    Q[:, 0] = np.linspace(0.0, 0.2, 5)
    animate(viz, psm, Q, 0.1)
    scalar_trail(viz, "x", frame_path(psm, Q, "tool_tip"), np.arange(5.0))
    kinds = {c["type"] for c in sent}
    assert {"set_object", "set_transform", "set_property", "set_animation"} <= kinds
    assert all(pack(c) == umsgpack.packb(c) for c in sent)

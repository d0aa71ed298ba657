"""Framed meshcat pages: every page records the side camera (the browser PNG's), the robot fills
the picture Chromium draws of the page, two poses look different, and ``view`` takes any robot
with its ``package://`` meshes (``--package-dir``), refusing missing ones on one line."""

from __future__ import annotations

import base64
import json
import re

import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from matplotlib.image import imread

import rcm_kin as rk
from rcm_kin.cli import main
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.visualization.browser import find_browser, screenshot
from rcm_kin.visualization.camera import MARGIN, side_camera
from rcm_kin.visualization.views import animate, robot_view

needs_browser = pytest.mark.skipif(find_browser() is None, reason="no Chromium on PATH (Debian: apt-get install "
                                                                  "chromium; .ci/run installs it)")
W, H = 800, 600
FOCAL = H / (2 * np.tan(np.radians(75.0) / 2))          # meshcat's camera: 75 deg vertical field of view
INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'


def box_stl(size) -> str:
    """An ASCII STL of a box ``size`` (m) centred on its origin (12 triangles)."""
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * np.asarray(size) / 2
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    facets = []
    for a, b, c, d in quads:
        for tri in ((a, b, c), (a, c, d)):
            vertices = "".join(f"vertex {' '.join(f'{v:.6f}' for v in corners[i])}\n" for i in tri)
            facets.append(f"facet normal 0 0 0\nouter loop\n{vertices}endloop\nendfacet\n")
    return "solid box\n" + "".join(facets) + "endsolid box\n"


def arm(tmp_path):
    """A two-joint arm (both about y, so it moves in the side camera's plane): a base box, an upper
    arm that is a ``package://armpkg`` mesh, a forearm cylinder. Returns (sidecar path, package folder)."""
    package = tmp_path / "pkgs" / "armpkg"
    (package / "meshes").mkdir(parents=True)
    (package / "package.xml").write_text("<package format='2'><name>armpkg</name></package>")
    (package / "meshes" / "upper.stl").write_text(box_stl([0.06, 0.06, 0.5]))
    joint = ('<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/><origin xyz="0 0 {z}"/>'
             '<axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="1"/></joint>')
    (tmp_path / "arm.urdf").write_text(
        '<robot name="arm">'
        f'<link name="base"><visual><origin xyz="0 0 0.05"/><geometry><box size="0.3 0.3 0.1"/></geometry>'
        f'</visual>{INERTIAL}</link>'
        f'<link name="upper"><visual><origin xyz="0 0 0.25"/><geometry><mesh filename="package://armpkg/meshes/'
        f'upper.stl"/></geometry></visual>{INERTIAL}</link>'
        f'<link name="fore"><visual><origin xyz="0 0 0.2"/><geometry><cylinder radius="0.03" length="0.4"/>'
        f'</geometry></visual>{INERTIAL}</link>'
        + joint.format(n="shoulder", p="base", c="upper", z=0.1) + joint.format(n="elbow", p="upper", c="fore", z=0.5)
        + "</robot>")
    (tmp_path / "arm.toml").write_text('robot = "arm"\nurdf = "arm.urdf"\nactuated = ["shoulder", "elbow"]\n')
    return tmp_path / "arm.toml", package


ROBOTS = {"psm": [0.0, 0.0, 0.08], "mtm": [0.3, 0.2, 0.4], "davinci": [0.0, 0.3, -0.4, 0.2, 0.0, 0.0, 0.2, 0.3, 0.05],
          "arm": [0.6, -1.2]}


@pytest.fixture
def robot_args(tmp_path, monkeypatch):
    """(robot, the ``view`` arguments naming it, package folders for plain Pinocchio) of a name in ROBOTS."""
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)

    def make(name):
        if name != "arm":
            return rk.load_robot(name), [name], []
        sidecar, package = arm(tmp_path)
        return rk.load_robot(sidecar), [str(sidecar), "--package-dir", f"armpkg={package}"], [str(package.parent)]
    return make


def page_camera(text: str):
    """The camera a page records, read back from its commands (scene frame, z up): (position, target)."""
    commands = [umsgpack.unpackb(base64.b64decode(c)) for c in re.findall(r'load\("([A-Za-z0-9+/=]+)"\)', text)]
    positions = [c["value"] for c in commands if c["type"] == "set_property" and c["property"] == "position"
                 and c["path"] == "/Cameras/default/rotated/<object>"]
    targets = re.findall(r"viewer\.controls\.target\.set\(\.\.\.(\[[^\]]*\])\)", text)
    assert len(positions) == 1 and len(targets) == 1
    scene = [np.array([a, -c, b]) for a, b, c in (positions[0], json.loads(targets[0]))]    # y up -> z up
    return scene[0], scene[1]


def project(points, position):
    """Pixels (u right, v down) of ``points`` (N, 3) seen from ``position`` looking along +y, z up."""
    rel = np.atleast_2d(points) - position
    return np.column_stack([W / 2 + FOCAL * rel[:, 0] / rel[:, 1], H / 2 - FOCAL * rel[:, 2] / rel[:, 1]])


def plain_geometry_points(robot, q, package_folders):
    """Origins and box corners of the robot's visual elements, from Pinocchio's own URDF parser."""
    visual = pin.buildGeomFromUrdf(robot.tree, str(robot.description.urdf), pin.GeometryType.VISUAL,
                                   package_dirs=package_folders)
    data, tree_data = visual.createData(), robot.tree.createData()
    pin.forwardKinematics(robot.tree, tree_data, tree_configuration(robot, robot.check_q(q, allow_short=True)))
    pin.updateGeometryPlacements(robot.tree, tree_data, visual, data)
    points = []
    for obj, m in zip(visual.geometryObjects, data.oMg):
        points.append(m.translation)
        if type(obj.geometry).__name__ == "Box":
            corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * obj.geometry.halfSide
            points.extend(corners @ m.rotation.T + m.translation)
    return np.array(points)


def write_page(args, q, path) -> str:
    assert main(["view", *args, "--q", *map(str, q), "--html", str(path)]) == 0
    return path.read_text()


@pytest.mark.parametrize("name", list(ROBOTS))
def test_the_page_records_a_camera_that_frames_the_robot(tmp_path, capsys, robot_args, name):
    """Read back from the page, the camera looks along +y and every visual element (as plain
    Pinocchio places it) projects inside the picture, the larger extent across at least 40 % of
    its height (meshcat's default camera: the PSM in 0.3 % of the picture)."""
    robot, args, folders = robot_args(name)
    q = ROBOTS[name]
    position, target = page_camera(write_page(args, q, tmp_path / "page.html"))
    look = target - position
    np.testing.assert_allclose(look[[0, 2]], 0.0, atol=1e-9)
    assert look[1] > 0
    pixels = project(plain_geometry_points(robot, q, folders), position)
    assert np.all((pixels >= 0) & (pixels <= [W, H])), pixels
    assert np.ptp(pixels, axis=0).max() > 0.4 * H
    # the PNG render's camera is the page's
    camera = side_camera(robot, q, package_dirs=dict(p.split("=", 1) for p in args[2:3]) or None)
    np.testing.assert_allclose(camera.position, position, atol=1e-9)
    np.testing.assert_allclose(camera.target, target, atol=1e-9)


def test_an_animation_is_framed_over_all_its_poses(tmp_path, psm):
    Q = np.zeros((15, psm.nq))
    Q[:, 1] = np.linspace(-0.5, 0.5, 15)
    Q[:, 2] = 0.1
    viz = robot_view(psm)
    animate(viz, psm, Q, 0.1)
    position, target = page_camera(rk.write_html(viz, tmp_path / "anim.html").read_text())
    camera = side_camera(psm, Q)
    np.testing.assert_allclose(camera.position, position, atol=1e-9)
    for q in Q[[0, -1]]:
        assert np.all((project(plain_geometry_points(psm, q, []), position) >= 0)
                      & (project(plain_geometry_points(psm, q, []), position) <= [W, H]))


def robot_mask(page, png_folder, robot_name):
    """Pixels where Chromium's picture of ``page`` differs from the same page with the robot hidden."""
    text = page.read_text()
    hide = base64.b64encode(umsgpack.packb({"type": "set_property", "path": f"/meshcat/{robot_name}",
                                            "property": "visible", "value": False})).decode()
    empty = page.with_name("empty.html")
    empty.write_text(text.replace("\n</script></body>", f'\nload("{hide}");\n</script></body>'))
    shots = [imread(screenshot(p, png_folder / f"{p.stem}.png", (W, H)))[..., :3] for p in (page, empty)]
    return np.abs(shots[0] - shots[1]).max(axis=2) > 0.03


@needs_browser
@pytest.mark.parametrize("name", list(ROBOTS))
def test_chromium_shows_the_page_framed(tmp_path, capsys, robot_args, name):
    """The side camera puts the robot's box, at its near face, across 1/MARGIN of the picture's
    height about the centre: what differs from the empty scene lies in that centred square (a
    third of the picture at most) and spans most of it (the far parts look smaller, round parts
    fill less than their boxes: at least 0.75 of it)."""
    robot, args, _ = robot_args(name)
    page = tmp_path / "page.html"
    write_page(args, ROBOTS[name], page)
    mask = robot_mask(page, tmp_path, robot.name)
    rows, cols = np.nonzero(mask)
    half = H / (2 * MARGIN) + 3                           # px, antialiasing
    assert W / 2 - half <= cols.min() and cols.max() <= W / 2 + half, (cols.min(), cols.max())
    assert H / 2 - half <= rows.min() and rows.max() <= H / 2 + half, (rows.min(), rows.max())
    span = max(np.ptp(cols), np.ptp(rows))
    assert span >= 0.75 * H / MARGIN, span
    assert 0.005 < mask.mean() < 1 / MARGIN**2 * H / W, mask.mean()


@needs_browser
@pytest.mark.parametrize("name", ["arm", "mtm"])
def test_two_poses_look_different(tmp_path, capsys, robot_args, name):
    robot, args, _ = robot_args(name)
    masks = []
    for k, q in enumerate((ROBOTS[name], np.zeros(len(ROBOTS[name])))):
        folder = tmp_path / f"pose{k}"
        folder.mkdir()
        write_page(args, q, folder / "page.html")
        masks.append(robot_mask(folder / "page.html", folder, robot.name))
    assert (masks[0] ^ masks[1]).sum() > 0.3 * (masks[0] | masks[1]).sum()


@pytest.mark.parametrize("case", ["no package", "missing mesh", "not a folder"])
@pytest.mark.parametrize("output", ["--html", "--png"])
def test_view_refuses_missing_meshes_on_one_line_and_writes_nothing(tmp_path, capsys, monkeypatch, case, output):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    sidecar, package = arm(tmp_path)
    extra = {"no package": [], "missing mesh": ["--package-dir", f"armpkg={package}"],
             "not a folder": ["--package-dir", f"armpkg={package / 'package.xml'}"]}[case]
    if case == "missing mesh":
        (package / "meshes" / "upper.stl").unlink()
    out = tmp_path / ("view.html" if output == "--html" else "view.png")
    assert main(["view", str(sidecar), *extra, output, str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
    expected = {"no package": "in package 'armpkg', which neither --package-dir (armpkg=DIR)",
                "missing mesh": "upper.stl) does not exist", "not a folder": "is not a folder"}[case]
    assert expected in err
    assert not out.exists() and not list(tmp_path.glob("*.html")) and not list(tmp_path.glob("*.png"))


def test_package_dirs_in_the_python_api(tmp_path, monkeypatch):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    sidecar, package = arm(tmp_path)
    robot = rk.load_robot(sidecar)
    with pytest.raises(rk.RcmKinError, match="package_dirs"):
        rk.robot_view(robot)
    viz = rk.robot_view(robot, package_dirs={"armpkg": package})
    rk.show(viz, robot, ROBOTS["arm"])
    text = rk.write_html(viz, tmp_path / "arm.html").read_text()
    commands = [umsgpack.unpackb(base64.b64decode(c)) for c in re.findall(r'load\("([A-Za-z0-9+/=]+)"\)', text)]
    meshes = [c for c in commands if c["type"] == "set_object" and c["path"].endswith("upper_0")]
    assert len(meshes) == 1 and meshes[0]["object"]["geometries"][0]["format"] == "stl"

"""Visual geometry with its meshes found: package:// through package_dirs and ROS_PACKAGE_PATH, and
one error line for each way a mesh can be missing."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import rcm_kin as rk
from rcm_kin.model.geometry import visual_geometry

TRIANGLE = ("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 0.1 0 0\nvertex 0 0.2 0\n"
            "endloop\nendfacet\nendsolid t\n")
INERTIAL = '<inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial>'


def _robot(tmp_path, uri: str):
    """A one-joint robot whose link shows the mesh ``uri``; a package 'meshpkg' holds a triangle."""
    package = tmp_path / "pkgs" / "meshpkg"
    (package / "meshes").mkdir(parents=True)
    (package / "package.xml").write_text("<package format='2'><name>meshpkg</name></package>")
    (package / "meshes" / "tri.stl").write_text(TRIANGLE)
    (tmp_path / "r.urdf").write_text(
        f'<robot name="r"><link name="base"/><link name="a"><visual><origin xyz="0 0 0.3"/><geometry>'
        f'<mesh filename="{uri}"/></geometry></visual>{INERTIAL}</link><joint name="j" type="revolute">'
        '<parent link="base"/><child link="a"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" '
        'velocity="1"/></joint></robot>')
    (tmp_path / "r.toml").write_text('robot = "r"\nurdf = "r.urdf"\nactuated = ["j"]\n')
    return rk.load_robot(tmp_path / "r.toml"), package


@pytest.mark.parametrize("name", ["psm", "mtm", "davinci"])
def test_bundled_geometry_is_pinocchios(name):
    """Without meshes the geometry is what Pinocchio's own parser gives from the file."""
    robot = rk.load_robot(name)
    ours = visual_geometry(robot)
    plain = pin.buildGeomFromUrdf(robot.tree, str(robot.description.urdf), pin.GeometryType.VISUAL)
    assert [g.name for g in ours.geometryObjects] == [g.name for g in plain.geometryObjects]
    for a, b in zip(ours.geometryObjects, plain.geometryObjects):
        assert a.parentJoint == b.parentJoint
        np.testing.assert_array_equal(a.placement.homogeneous, b.placement.homogeneous)


def test_package_meshes_are_found(tmp_path, monkeypatch):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    robot, package = _robot(tmp_path, "package://meshpkg/meshes/tri.stl")
    geometry = visual_geometry(robot, {"meshpkg": package})
    assert geometry.geometryObjects[0].meshPath == str((package / "meshes" / "tri.stl").resolve())
    np.testing.assert_allclose(geometry.geometryObjects[0].placement.translation, [0, 0, 0.3])
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(package.parent))      # a folder holding packages
    assert visual_geometry(robot).geometryObjects[0].meshPath.endswith("tri.stl")
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(package))             # the package itself
    assert visual_geometry(robot).ngeoms == 1


def test_relative_mesh_is_beside_the_urdf(tmp_path):
    robot, package = _robot(tmp_path, "pkgs/meshpkg/meshes/tri.stl")
    assert visual_geometry(robot).geometryObjects[0].meshPath == str((package / "meshes" / "tri.stl").resolve())


@pytest.mark.parametrize("uri, match", [
    ("package://meshpkg/meshes/tri.stl", r"in package 'meshpkg', which neither `package_dirs` \(meshpkg=DIR\)"),
    ("package://otherpkg/tri.stl", "in package 'otherpkg'"),
    ("missing.stl", r"mesh file .*missing.stl \(from missing.stl\) does not exist"),
    ("http://example.com/tri.stl", "only relative paths, file:// and package:// are read"),
])
def test_missing_meshes_are_one_line(tmp_path, monkeypatch, uri, match):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    robot, _ = _robot(tmp_path, uri)
    with pytest.raises(rk.RcmKinError, match=match) as info:
        visual_geometry(robot)
    assert "\n" not in str(info.value)


def test_unreadable_mesh_is_one_line(tmp_path):
    robot, package = _robot(tmp_path, "package://meshpkg/meshes/tri.stl")
    (package / "meshes" / "tri.stl").write_bytes(b"\x00garbage" * 3)
    with pytest.raises(rk.RcmKinError) as info:
        visual_geometry(robot, {"meshpkg": package})
    assert "\n" not in str(info.value)


def test_package_dir_must_be_a_folder(tmp_path):
    robot, package = _robot(tmp_path, "package://meshpkg/meshes/tri.stl")
    with pytest.raises(rk.RcmKinError, match="is not a folder") as info:
        visual_geometry(robot, {"meshpkg": package / "nope"})
    assert info.value.parameters == ("package_dirs",)

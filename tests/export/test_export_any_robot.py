"""``rcm-kin export --mjcf`` for any robot: a user's description by path with package:// meshes (STL
and OBJ as MuJoCo mesh assets, other formats left out with a warning), the model named in the file
and in --json, and bad input as one line, status 2, nothing written."""

from __future__ import annotations

import json
import struct
import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.dynamics.drive import write_parameters

TETRA = np.array([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05]])
FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
INERTIAL = ('<inertial><origin xyz="0.1 0 0"/><mass value="0.5"/><inertia ixx="1e-3" iyy="2e-3" izz="2e-3" '
            'ixy="0" ixz="0" iyz="0"/></inertial>')


def _binary_stl(path):
    data = b"\0" * 80 + struct.pack("<I", len(FACES))
    for f in FACES:
        n = np.cross(TETRA[f[1]] - TETRA[f[0]], TETRA[f[2]] - TETRA[f[0]])
        data += struct.pack("<12fH", *(n / np.linalg.norm(n)), *TETRA[f[0]], *TETRA[f[1]], *TETRA[f[2]], 0)
    path.write_bytes(data)


def _files(tmp_path, meshes=("package://arm_description/meshes/a.stl", "b.obj", "c.ply")):
    """A two-link serial arm 'arm': link a shows a binary STL from the package 'arm_description',
    link b an OBJ beside the URDF and a PLY; the sidecar names no drive."""
    package = tmp_path / "pkgs" / "arm_description"
    (package / "meshes").mkdir(parents=True)
    (package / "package.xml").write_text("<package format='2'><name>arm_description</name></package>")
    _binary_stl(package / "meshes" / "a.stl")
    (tmp_path / "b.obj").write_text("".join(f"v {a} {b} {c}\n" for a, b, c in TETRA)
                                    + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in FACES))
    (tmp_path / "c.ply").write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                                    "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
                                    "end_header\n" + "".join(f"{a} {b} {c}\n" for a, b, c in TETRA)
                                    + "".join(f"3 {a} {b} {c}\n" for a, b, c in FACES))

    def visual(uri):
        return f'<visual><geometry><mesh filename="{uri}" scale="2 2 2"/></geometry></visual>'

    def joint(name, parent, child):
        return (f'<joint name="{name}" type="revolute"><origin xyz="0 0 0.2"/><parent link="{parent}"/>'
                f'<child link="{child}"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="1"/>'
                '</joint>')
    (tmp_path / "arm.urdf").write_text(
        f'<robot name="arm"><link name="base"/><link name="a">{visual(meshes[0])}{INERTIAL}</link>'
        f'<link name="b">{"".join(visual(m) for m in meshes[1:])}{INERTIAL}</link>'
        f'{joint("j1", "base", "a")}{joint("j2", "a", "b")}</robot>')
    (tmp_path / "arm.toml").write_text('robot = "arm"\nurdf = "arm.urdf"\nactuated = ["j1", "j2"]\n')
    return str(tmp_path / "arm.toml"), package


def test_user_robot_with_package_meshes(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    sidecar, package = _files(tmp_path)
    out = tmp_path / "arm.xml"
    assert main(["export", sidecar, "--mjcf", str(out), "--package-dir", f"arm_description={package}", "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == {"files": [str(out)], "model": "CAD (URDF inertias)"}
    assert captured.err.count("\n") == 1 and "c.ply" in captured.err and "left out" in captured.err
    root = ET.parse(out).getroot()
    assets = {m.get("name"): m for m in root.find("asset")}
    assert sorted(m.get("file") for m in assets.values()) == sorted(
        [str((package / "meshes" / "a.stl").resolve()), str((tmp_path / "b.obj").resolve())])
    assert {m.get("scale") for m in assets.values()} == {"2 2 2"}
    geoms = [g for g in root.iter("geom")]
    assert [g.get("type") for g in geoms] == ["mesh", "mesh"] and {g.get("mesh") for g in geoms} == set(assets)
    assert root.find("custom/text").get("data") == "CAD (URDF inertias)"
    assert "<!-- rcm-kin: arm, model CAD (URDF inertias) -->" in out.read_text()
    mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the optional extra [mujoco]")
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.nmesh == 2 and model.nu == 2
    np.testing.assert_array_equal(model.body_mass[1:], [0.5, 0.5])


def test_mesh_without_its_package_or_file_is_one_line_and_writes_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    sidecar, package = _files(tmp_path)
    out = tmp_path / "arm.xml"
    assert main(["export", sidecar, "--mjcf", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("error: ") and "--package-dir" in err and "arm_description" in err
    assert not out.exists()
    (package / "meshes" / "a.stl").unlink()
    assert main(["export", sidecar, "--mjcf", str(out), "--package-dir", f"arm_description={package}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a.stl" in err and "does not exist" in err
    assert not out.exists()
    assert main(["export", sidecar, "--mjcf", str(out), "--package-dir", "arm_description"]) == 2
    assert "NAME=DIR" in capsys.readouterr().err and not out.exists()


def test_params_of_another_robot_is_one_line_and_writes_nothing(tmp_path, capsys, params):
    other = write_parameters(replace(params, robot="mtm"), tmp_path / "other.toml")
    out = tmp_path / "psm.xml"
    assert main(["export", "psm", "--mjcf", str(out), "--params", str(other)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "describes robot 'mtm', not 'psm'" in err and not out.exists()
    assert main(["export", "mtm", "--mjcf", str(out), "--params", str(write_parameters(params, tmp_path / "p.toml"))]) \
        == 2
    assert "not 'mtm'" in capsys.readouterr().err and not out.exists()


def test_c_export_is_the_bundled_psms_only(tmp_path, capsys):
    sidecar, _ = _files(tmp_path)
    for robot in ("mtm", sidecar):
        assert main(["export", robot, "--c", str(tmp_path / "c")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "bundled PSM" in err
    assert not (tmp_path / "c").exists()


@pytest.mark.parametrize("robot, model", [("psm", "calibration psm_drive.toml"), ("mtm", "CAD (URDF inertias)"),
                                          ("davinci", "CAD (URDF inertias)")])
def test_the_file_and_json_say_which_model(tmp_path, capsys, robot, model):
    out = tmp_path / f"{robot}.xml"
    assert main(["export", robot, "--mjcf", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["model"] == model
    assert ET.parse(out).getroot().find("custom/text").get("data") == model
    assert f"<!-- rcm-kin: {robot}, model {model} -->" in out.read_text()
    assert main(["export", robot, "--mjcf", str(out), "--force"]) == 0
    assert capsys.readouterr().out == f"wrote {out}\nmodel: {model}\n"

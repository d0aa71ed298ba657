"""``gravity``, ``torque-map``, ``counterweights``, ``calibrate``: flags reach the library, another robot's
drive file is one line (status 2, nothing written), grids are checked alike, efforts carry their units.
The other robots' files are made here from the shipped ones (name and drive line changed)."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles.cli_calls import run

import rcm_kin as rk
from rcm_kin.cli.statics import EPILOG_TORQUE_MAP
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
from rcm_kin.model.loading import urdf_dir
from rcm_kin.statics import maps


@pytest.fixture(scope="module")
def other(tmp_path_factory):
    """A renamed copy of the PSM without a drive (mypsm.toml) and a drive file of it (mypsm_drive.toml)."""
    folder = tmp_path_factory.mktemp("mypsm")
    shutil.copy(urdf_dir() / "psm.urdf", folder / "psm.urdf")
    text = re.sub(r'^robot = "psm"$', 'robot = "mypsm"', (urdf_dir() / "psm.toml").read_text(), flags=re.M)
    (folder / "mypsm.toml").write_text(re.sub(r"^drive = .*$", "", text, flags=re.M))
    drive = re.sub(r'^robot = "psm"', 'robot = "mypsm"', DEFAULT_PARAMETERS.read_text(), flags=re.M)
    (folder / "mypsm_drive.toml").write_text(re.sub(r"^(volts_per_pwm = .*)$", r"\1\npwm_limit = 255.0", drive,
                                                    flags=re.M))
    return folder


def test_torque_map_without_counterweights_is_the_robot_without_them(capsys, tmp_path):
    """Before: the map was rebuilt with the counterweights. Now its j1 torque is `gravity`'s and plain
    Pinocchio's on the MTM without its counterweight's mass, and differs from the one with it."""
    code, out, err = run(capsys, "gravity", "mtm", 10, 0, 20, "--deg", "--no-counterweights", "--json")
    assert code == 0, err
    held = json.loads(out)["tau"]
    code, out, err = run(capsys, "torque-map", "mtm", "--grid", "j1=10:10:1", "j3=20:20:1", "--no-counterweights",
                         "--out", tmp_path / "m", "--format", "npz", "--no-figures")
    assert code == 0, err
    table = np.load(tmp_path / "m" / "torque_map.npz")
    without = rk.load_robot("mtm", counterweights=False)
    q = np.radians([10.0, 0, 20.0, 0, 0, 0, 0])
    plain = pin.computeGeneralizedGravity(without.tree, without.tree.createData(), q)    # serial: tree q = q
    assert table["tau_j1"][0] == pytest.approx(held[0], abs=1e-9) == pytest.approx(plain[0], abs=1e-9)
    full = rk.load_robot("mtm")
    assert abs(pin.computeGeneralizedGravity(full.tree, full.tree.createData(), q)[0] - plain[0]) > 0.1


def test_the_psm_form_refuses_another_robots_drive_file(capsys, tmp_path, other):
    code, out, err = run(capsys, "torque-map", "psm", "--params", other / "mypsm_drive.toml", "--roll", "0:0:1",
                         "--pitch", "0:0:1", "--out", tmp_path / "x", "--no-figures")
    assert code == 2 and err.count("\n") == 1 and "describes robot 'mypsm', not 'psm'" in err and not out
    assert not (tmp_path / "x").exists()


def test_the_psm_form_names_its_model(capsys, tmp_path):
    code, out, err = run(capsys, "torque-map", "psm", "--roll", "0:10:2", "--pitch", "0:0:1", "--out", tmp_path / "a",
                         "--no-figures", "--json")
    assert code == 0, err
    payload = json.loads(out)
    assert list(payload) == ["files", "poses", "model"] and payload["model"] == "calibration psm_drive.toml"
    assert payload["poses"] == 2
    code, out, err = run(capsys, "torque-map", "psm", "--roll", "0:10:2", "--pitch", "0:0:1", "--out", tmp_path / "b",
                         "--no-figures")
    assert code == 0, err
    assert out.splitlines()[:-1] == [f"wrote {tmp_path / 'b' / f}" for f in ("torque_map.csv", "insertion_map.csv")]
    assert out.splitlines()[-1] == "model: calibration psm_drive.toml"


def test_calibrate_refuses_another_robots_drive_file(capsys, tmp_path, other):
    """Before: the file was read, fitted and written out relabelled as the psm's."""
    code, out, err = run(capsys, "calibrate", tmp_path, "--params", other / "mypsm_drive.toml",
                         "--out", tmp_path / "fit.toml")
    assert code == 2 and err.count("\n") == 1 and "describes robot 'mypsm', not 'psm'" in err
    assert not (tmp_path / "fit.toml").exists()


def test_counterweights_checks_the_grid_as_torque_map(capsys, monkeypatch, tmp_path):
    """The map-size limit and --at on a grid joint (before: no limit, and --at silently overridden)."""
    out_flag = {"counterweights": [], "torque-map": ["--out", tmp_path / "x"]}
    monkeypatch.setattr(maps, "MAX_POSES", 20)           # the limit of any map, made small
    for command, flags in out_flag.items():
        code, out, err = run(capsys, command, "mtm", "--grid", "j1=-60:60:5", "j3=-30:80:5", *flags)
        assert code == 2 and "a map of 25 poses is beyond the 20" in err and err.count("\n") == 1, (command, err)
    monkeypatch.undo()
    for command, flags in out_flag.items():
        code, out, err = run(capsys, command, "mtm", "--grid", "j1=-60:60:5", "j3=-30:80:5", "--at", "j1=10", *flags)
        assert code == 2 and "--at j1: j1 is a joint of the grid" in err and err.count("\n") == 1, (command, err)
    assert not (tmp_path / "x").exists()


def test_counterweights_without_a_drive_labels_a_force_in_newtons(capsys, other):
    """No drive: every actuated joint weighed in its own unit, the prismatic insertion's force in N (before:
    labelled "(N m)"), the revolute joints' torques in N m; "unit" stays the torque family's "N m"."""
    code, out, err = run(capsys, "counterweights", other / "mypsm.toml", "--grid", "roll=-30:30:5", "pitch=-30:30:5",
                         "--link", "main_counterweight", "--json")
    assert code == 0, err
    (design,) = json.loads(out)["counterweights"]
    kinds = dict(zip(design["joints"], design["units"]))
    assert kinds["insertion"] == "N" and kinds["roll"] == kinds["pitch"] == "N m" and design["unit"] == "N m"
    code, out, err = run(capsys, "counterweights", other / "mypsm.toml", "--grid", "roll=-30:30:5", "pitch=-30:30:5",
                         "--link", "main_counterweight")
    assert code == 0, err
    line = next(x for x in out.splitlines() if x.strip().startswith("insertion"))
    assert line.endswith("(N)")
    assert next(x for x in out.splitlines() if x.strip().startswith("roll ")).endswith("(N m)")


def test_a_grid_range_error_names_the_joints_unit(capsys, monkeypatch, tmp_path):
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, "torque-map", "psm", "--grid", "insertion=0.05:0.1", "roll=0:10:3", "--out", "x")
    assert code == 2 and "--grid insertion must be LO:HI:N (m, m, count)" in err
    code, out, err = run(capsys, "counterweights", "mtm", "--grid", "j1=-60:60", "j3=0:10:3")
    assert code == 2 and "--grid j1 must be LO:HI:N (deg, deg, count)" in err


def test_the_epilog_example_maps_joints_that_carry_gravity():
    """The example's two joints are ones whose own holding torque changes over their range on the MTM (plain
    Pinocchio on its URDF); j2's axis is vertical (before: the example mapped it)."""
    (example,) = [line for line in EPILOG_TORQUE_MAP.splitlines() if "torque-map mtm" in line]
    grid = dict(word.split("=") for word in re.findall(r"\bj\d=[-\d.:]+", example))
    assert sorted(grid) == ["j1", "j3"]
    model = pin.buildModelFromUrdf(str(urdf_dir() / "mtm.urdf"))
    data = model.createData()
    names = [model.names[i] for i in range(1, model.njoints)]
    for joint in ("j1", "j2", "j3"):
        lo, hi, _ = (float(x) for x in (grid.get(joint) or "-40:60:2").split(":"))
        k = names.index(joint)
        taus = []
        for angle in np.linspace(lo, hi, 5):
            q = pin.neutral(model)
            q[k] = np.radians(angle)
            taus.append(pin.computeGeneralizedGravity(model, data, q)[k])
        spread = max(taus) - min(taus)
        assert (spread > 0.05) if joint in grid else (spread < 0.01), (joint, spread)


def test_a_map_of_another_robot_without_grid_names_its_own_joints(capsys):
    """`torque-map mtm --out D` (no --grid): one line that suggests a --grid over the MTM's own joints, in
    degrees over their limits, and that does not blame options the user never gave."""
    code, out, err = run(capsys, "torque-map", "mtm", "--out", "m")
    assert code == 2 and err.count("\n") == 1
    assert "--grid j1=-90:90:61 j2=-90:90:61" in err and "--roll" not in err


def test_torque_map_refuses_a_table_linked_out_of_its_folder(capsys, tmp_path):
    """Before: a link out/torque_map.csv -> ../notes.txt was followed and the notes overwritten."""
    notes, out = tmp_path / "notes.txt", tmp_path / "out"
    notes.write_text("my notes\n")
    out.mkdir()
    (out / "torque_map.csv").symlink_to(Path("..") / "notes.txt")
    code, stdout, err = run(capsys, "torque-map", "psm", "--roll", "0:10:2", "--pitch", "0:0:1", "--out", out,
                            "--no-figures")
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: ") and "outside its folder" in err
    assert notes.read_text() == "my notes\n" and (out / "torque_map.csv").is_symlink()
    assert not stdout

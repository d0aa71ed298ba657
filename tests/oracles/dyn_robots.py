"""Robots no code names, generated in the tests: a renamed, re-massed PSM copy with a drive file of
its own, a UR5 sidecar over example-robot-data's URDF, and drive files of any robot."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pinocchio as pin
import pytest

from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
from rcm_kin.model.loading import urdf_dir

DRIVE_KEYS = ("gear_ratio", "torque_constant", "resistance", "volts_per_pwm", "pwm_sign", "rotor_inertia",
              "viscous", "coulomb", "coulomb_velocity")


def drive_text(robot: str, joints: dict, limit: float = 100.0) -> str:
    """A drive file of ``robot`` for the joints ``joints`` ({name: {key: value}}), pwm_limit given."""
    lines = [f'robot = "{robot}"']
    for joint, values in joints.items():
        lines += [f"[{joint}]"] + [f"{k} = {float(v)!r}" for k, v in values.items()] + [f"pwm_limit = {limit!r}"]
    return "\n".join(lines) + "\n"


def write_mypsm(folder: Path) -> tuple[Path, dict]:
    """``mypsm.toml``: the PSM with roll_link 1.5 kg (not 0.875), renamed, with its own drive file
    (the PSM's drive constants, roll gear 25, no calibrated first moments). Returns the sidecar and
    the drive constants per joint."""
    text = (urdf_dir() / "psm.urdf").read_text()
    old = '<mass value="0.875" />'
    assert text.count(old) == 1
    (folder / "mypsm.urdf").write_text(text.replace(old, '<mass value="1.5" />'))
    sidecar = (urdf_dir() / "psm.toml").read_text()
    sidecar = sidecar.replace('robot = "psm"', 'robot = "mypsm"').replace('urdf = "psm.urdf"', 'urdf = "mypsm.urdf"')
    (folder / "mypsm.toml").write_text(sidecar.replace('drive = "psm_drive.toml"', 'drive = "mypsm_drive.toml"'))
    shipped = tomllib.loads(DEFAULT_PARAMETERS.read_text())
    joints = {j: {k: shipped[j][k] for k in DRIVE_KEYS} for j in ("roll", "pitch", "insertion")}
    joints["roll"]["gear_ratio"] = 25.0
    (folder / "mypsm_drive.toml").write_text(drive_text("mypsm", joints))
    return folder / "mypsm.toml", joints


def ur5_urdf() -> Path:
    """example-robot-data's UR5 URDF (skips without the package)."""
    erd = pytest.importorskip("example_robot_data")
    return Path(erd.getModelPath("ur_description/urdf/ur5_robot.urdf")) / "ur_description/urdf/ur5_robot.urdf"


def write_ur5(folder: Path) -> Path:
    """``ur5.toml``: a two-line sidecar, every joint of the URDF actuated."""
    urdf = ur5_urdf()
    names = list(pin.buildModelFromUrdf(str(urdf)).names[1:])
    path = folder / "ur5.toml"
    path.write_text(f'robot = "ur5"\nurdf = "{urdf}"\nactuated = {names!r}\n'.replace("'", '"'))
    return path

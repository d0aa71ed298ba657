"""Drive files hold constants a robot can have and tables the reader knows: a value inside the old
ranges but far from any hardware (``1e-300``) and a misspelt table are one-line errors naming the
key or table and what is plausible."""

from __future__ import annotations

import pytest

from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, load_drive_parameters
from rcm_kin.dynamics.drive_schema import JOINT_DRIVE
from rcm_kin.errors import ParameterFileError

SHIPPED = DEFAULT_PARAMETERS.read_text()


def variant(tmp_path, old: str, new: str):
    assert old in SHIPPED
    path = tmp_path / "drive.toml"
    path.write_text(SHIPPED.replace(old, new, 1))
    return path


@pytest.mark.parametrize("old, new, key", [
    ("gear_ratio = 20.0", "gear_ratio = 1e-300", "gear_ratio"),
    ("coulomb_velocity = 0.02", "coulomb_velocity = 1e-300", "coulomb_velocity"),
    ("torque_constant = 0.0302", "torque_constant = 1e-300", "torque_constant"),
    ("resistance = 0.582", "resistance = 1e-300", "resistance"),
    ("volts_per_pwm = 0.117", "volts_per_pwm = 1e-300  #", "volts_per_pwm"),
    ("stribeck_velocity = 0.01", "stribeck_velocity = 1e-300", "stribeck_velocity"),
])
def test_implausible_drive_constants_are_refused_with_what_is_plausible(tmp_path, old, new, key):
    path = variant(tmp_path, old, new)
    with pytest.raises(ParameterFileError) as raised:
        load_drive_parameters(path)
    message = str(raised.value)
    assert "\n" not in message and str(path) in message
    assert raised.value.key == key and f"{key} = {new.split()[2]} is outside" in message
    assert "plausible: " in message and "the PSM's" in message


def test_shipped_file_lies_inside_every_band():
    params = load_drive_parameters()
    for joint in params.driven:
        for key, rule in JOINT_DRIVE.items():
            value = getattr(params[joint], key)
            assert rule.lo <= value <= rule.hi, (joint, key, value)


@pytest.mark.parametrize("robot", ["psm", "other_arm"])
def test_a_misspelt_table_is_an_error_naming_it_and_the_known_ones(tmp_path, robot):
    text = SHIPPED.replace("[drive_train.roll]", "[drive-train.roll]").replace('robot = "psm"', f'robot = "{robot}"')
    path = tmp_path / "drive.toml"
    path.write_text(text)
    with pytest.raises(ParameterFileError) as raised:
        load_drive_parameters(path)
    message = str(raised.value)
    assert "unknown table [drive-train.roll]" in message and "did you mean [drive_train]?" in message
    assert all(f"[{t}]" in message for t in ("gravity_offsets", "drive_train", "uncertainty"))
    assert raised.value.table == "drive-train" and "\n" not in message


@pytest.mark.parametrize("old, new, named", [
    ("\n[gravity_offsets]\n", "\n[gravity-offsets]\n", "unknown table [gravity-offsets]"),
    ('robot = "psm"', 'robot = "psm"\nvolts_per_pwm = 0.1', "unknown key volts_per_pwm"),
])
def test_other_unknown_top_level_entries_are_errors(tmp_path, old, new, named):
    with pytest.raises(ParameterFileError, match="a drive file holds") as raised:
        load_drive_parameters(variant(tmp_path, old, new))
    assert named in str(raised.value)

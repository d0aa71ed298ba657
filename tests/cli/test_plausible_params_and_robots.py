"""Implausible drive parameter files and impossible robot descriptions are one ``error:`` line at exit 2."""

from __future__ import annotations

import pytest

from rcm_kin.cli import main
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
from rcm_kin.model.loading import urdf_dir


def one_error_line(capsys, argv) -> str:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("old, new, says", [
    ("gear_ratio = 20.0", "gear_ratio = 1e-300", "gear_ratio = 1e-300 is outside [0.1, 10000]"),
    ("coulomb_velocity = 0.02", "coulomb_velocity = 1e-300", "coulomb_velocity = 1e-300 is outside [0.0001, 1]"),
    ("[drive_train.roll]", "[drive-train.roll]", "unknown table [drive-train.roll]"),
])
def test_implausible_param_file_is_one_error_line(capsys, tmp_path, old, new, says):
    path = tmp_path / "drive.toml"
    path.write_text(DEFAULT_PARAMETERS.read_text().replace(old, new, 1))
    assert says in one_error_line(capsys, ["gravity", "psm", "0.1", "--params", path])


@pytest.mark.parametrize("old, new, says", [
    ('<mass value="0.875" />', '<mass value="-0.875" />', "link 'roll_link': mass = -0.875 kg"),
    ('<mass value="0.875" />', '<mass value="nan" />', "link 'roll_link': mass = nan kg"),
    ('ixx="0.0015166666666666666"', 'ixx="0.015"', "link 'roll_link': principal moments"),
])
def test_impossible_robot_urdf_is_one_error_line(capsys, tmp_path, old, new, says):
    path = tmp_path / "psm_variant.urdf"
    path.write_text((urdf_dir() / "psm.urdf").read_text().replace(old, new, 1))
    assert says in one_error_line(capsys, ["info", path])

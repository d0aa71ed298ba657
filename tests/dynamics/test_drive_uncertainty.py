"""The ``[uncertainty]`` tables of a drive file: written and read back, bad ones refused in one line."""

from dataclasses import replace

import numpy as np
import pytest

from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.dynamics.drive import load_drive_parameters, write_parameters
from rcm_kin.dynamics.drive_uncertainty import DriveUncertainty, FoldSet
from rcm_kin.errors import ParameterFileError


def test_round_trip(tmp_path):
    base = load_drive_parameters()
    u = DriveUncertainty(folds={"roll": (FoldSet('odd "name".csv', AxisFriction(coulomb=0.1, viscous=2.0)),
                                         FoldSet("b.csv", AxisFriction(presliding_force=1.5)))},
                         ranges={"roll": {"presliding_force": (0.9, 5.0)}},
                         holding_residuals={"roll": np.array([1.0, -2.5]), "pitch": np.array([3.0])},
                         hull={"roll": (-0.26, 0.35), "pitch": (-0.29, 0.26)},
                         preloads={"roll": (-0.375, 0.079, 0.157)}, discrepancy={"roll": (0.0, 1.25)})
    back = load_drive_parameters(write_parameters(replace(base, uncertainty=u), tmp_path / "u.toml")).uncertainty
    assert back.folds == u.folds and back.ranges == u.ranges and back.hull == u.hull
    assert back.preloads == {"roll": (-0.375, 0.079, 0.157)} and back.discrepancy == {"roll": (0.0, 1.25)}
    assert {j: v.tolist() for j, v in back.holding_residuals.items()} == {"roll": [1.0, -2.5], "pitch": [3.0]}


def test_a_file_without_uncertainty_has_none(tmp_path):
    assert not DriveUncertainty()
    plain = replace(load_drive_parameters(), uncertainty=DriveUncertainty())
    text = write_parameters(plain, tmp_path / "plain.toml").read_text()
    assert "uncertainty" not in text and not load_drive_parameters(tmp_path / "plain.toml").uncertainty


@pytest.mark.parametrize("table, needle", [
    ('[uncertainty.hull]\nroll = [0.3, -0.3]', "lo 0.3 above hi -0.3"),
    ('[uncertainty.hull]\nelbow = [0.0, 0.1]', "elbow, not a joint"),
    ('[uncertainty.holding_residuals]\nroll = "big"', "list of numbers"),
    ('[uncertainty.ranges.roll]\nmystery = [0, 1]', "must name drive-train parameters"),
    ('[[uncertainty.folds.roll]]\ncoulomb = 0.1', "names the log it left out"),
    ('[[uncertainty.folds.roll]]\nleft_out = "a.csv"\ncoulomb = -1.0', "coulomb = -1 is outside"),
    ('[uncertainty.extra]\nx = 1', "holds the tables hull"),
    ('[uncertainty.preloads]\nroll = [0.2, 1.5]', "outside"),
    ('[uncertainty.preloads]\nroll = []', "list of numbers (fraction of the slip force)"),
    ('[uncertainty.discrepancy]\nroll = [-0.5]', "outside"),
])
def test_bad_tables_are_one_line_errors(tmp_path, table, needle):
    path = tmp_path / "bad.toml"
    plain = write_parameters(replace(load_drive_parameters(), uncertainty=DriveUncertainty()), tmp_path / "p.toml")
    path.write_text(plain.read_text() + "\n" + table + "\n")
    with pytest.raises(ParameterFileError) as err:
        load_drive_parameters(path)
    assert needle in str(err.value) and "\n" not in str(err.value)

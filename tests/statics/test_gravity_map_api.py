"""The torque map as a labelled result: named axes, selection by name, writing itself; checked
against the holding effort computed pose by pose (Pinocchio gravity through the drive model)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import rcm_kin as rk


@pytest.fixture(scope="module")
def tmap():
    return rk.gravity_map(rk.load_robot("psm"), roll_deg=[-20.0, 0.0, 10.0], pitch_deg=[-15.0, 5.0], insertion=0.08)


def test_the_axes_are_named(tmap):
    assert tmap.dims == ("pitch", "roll", "insertion", "joint")
    assert tmap.effort.pwm.shape == tuple(len(tmap.coords[d]) for d in tmap.dims)
    assert tmap.coords["joint"] == ("roll", "pitch", "insertion")


@pytest.mark.parametrize("roll, pitch", [(10.0, -15.0), (-20.0, 5.0), (0.0, 5.0)])
def test_sel_by_name_is_the_pose_named(roll, pitch):
    """With the calibrated offsets set to zero the map is the URDF's own gravity: at each pose the
    effort selected by name equals plain Pinocchio's constrained gravity (loop solve and
    projection), through the drive's physics written out here (tau / N / k_t * R, over volts
    per count, with the hardware sign)."""
    psm = rk.load_robot("psm")
    drive = dataclasses.replace(rk.load_drive_parameters(), gravity_offsets={})
    tmap = rk.gravity_map(psm, drive, roll_deg=[-20.0, 0.0, 10.0], pitch_deg=[-15.0, 5.0], insertion=0.08)
    q = [np.radians(roll), np.radians(pitch), 0.08, 0, 0, 0, 0]
    tau = rk.gravity_torque(psm, q, method="constrained")[:3]
    got = tmap.sel(roll=roll, pitch=pitch)
    np.testing.assert_allclose(got.tau, tau, atol=1e-9)
    for k, joint in enumerate(("roll", "pitch", "insertion")):
        d = drive[joint]
        pwm = d.pwm_sign * d.resistance * tau[k] / d.gear_ratio / d.torque_constant / d.volts_per_pwm
        assert got.pwm[k] == pytest.approx(pwm, rel=1e-12, abs=1e-9)


def test_roll_and_pitch_are_not_interchangeable(tmap):
    """Reading [roll, pitch] where the axes are [pitch, roll] is the silent error the names prevent."""
    assert not np.allclose(tmap.sel(roll=10.0, pitch=5.0).pwm, tmap.effort.pwm[0, 1, 0])
    np.testing.assert_array_equal(tmap.sel(roll=10.0, pitch=5.0).pwm, tmap.effort.pwm[1, 2, 0])


def test_a_pose_off_the_grid_is_refused(tmap):
    with pytest.raises(rk.RcmKinError, match="roll 7 deg is not on the map's grid .nearest 10 deg"):
        tmap.sel(roll=7.0, pitch=5.0)


def test_the_map_writes_itself(tmp_path, tmap):
    table = np.load(tmap.write(tmp_path / "map.npz"))
    assert table["pwm_roll"].size == tmap.effort.pwm[..., 0].size
    csv = tmap.write(tmp_path / "map.csv").read_text().splitlines()
    assert csv[0].startswith("roll_deg,pitch_deg,insertion_m") and len(csv) == 1 + 6
    with pytest.raises(rk.RcmKinError, match="written as .csv or .npz"):
        tmap.write(tmp_path / "map.xlsx")


def test_the_drive_defaults_to_the_shipped_set():
    psm = rk.load_robot("psm")
    a = rk.gravity_map(psm, None, [0.0], [10.0], [0.1])
    b = rk.gravity_map(psm, rk.load_drive_parameters(), [0.0], [10.0], [0.1])
    np.testing.assert_array_equal(a.effort.pwm, b.effort.pwm)
    with pytest.raises(rk.RcmKinError, match="no drive parameter file at psm_drive.toml"):
        rk.gravity_map(psm, "psm_drive.toml", [0.0], [10.0], [0.1])      # a path: read (here: not found)
    with pytest.raises(rk.RcmKinError, match="`drive` is DriveParameters, the path of a drive file, None"):
        rk.gravity_map(psm, 42, [0.0], [10.0], [0.1])


def test_one_joint_by_name(tmap):
    both = tmap.sel(roll=10.0, pitch=5.0)
    pitch = tmap.sel(roll=10.0, pitch=5.0, joint="pitch")
    assert pitch.pwm == both.pwm[1] and pitch.tau == both.tau[1]
    with pytest.raises(rk.RcmKinError, match="joint 'elbow' is not an axis of the map"):
        tmap.sel(roll=10.0, pitch=5.0, joint="elbow")


@pytest.mark.parametrize("change, message", [
    (dict(roll_deg=[]), "`roll_deg` must be a non-empty list of finite numbers"),
    (dict(pitch_deg=[np.nan, 0.0]), "`pitch_deg` must be a non-empty list of finite numbers"),
    (dict(insertion="far"), "`insertion` must be numbers"),
])
def test_bad_grids_are_refused_by_name(change, message):
    arguments = dict(roll_deg=[0.0], pitch_deg=[0.0], insertion=0.08) | change
    with pytest.raises(rk.RcmKinError, match=message) as raised:
        rk.gravity_map(rk.load_robot("psm"), **arguments)
    assert raised.value.parameters == tuple(change)


def test_a_robot_without_the_driven_joints_is_refused():
    with pytest.raises(rk.RcmKinError, match="mtm has no roll, pitch, insertion"):
        rk.gravity_map(rk.load_robot("mtm"), roll_deg=[0.0], pitch_deg=[0.0])


def test_the_shipped_calibration_is_not_applied_to_another_robot(tmp_path):
    """A renamed copy of the PSM gets no default drive parameters: the shipped calibration belongs
    to the bundled robot, and the map says so instead of applying it silently, also when it is given."""
    import shutil

    from rcm_kin.model.loading import urdf_dir

    shutil.copy(urdf_dir() / "psm.urdf", tmp_path / "psm.urdf")
    text = (urdf_dir() / "psm.toml").read_text().replace('robot = "psm"', 'robot = "mypsm"')
    text = text.replace('drive = "psm_drive.toml"\n', "")
    (tmp_path / "mypsm.toml").write_text(text)
    mine = rk.load_robot(str(tmp_path / "mypsm.toml"))
    with pytest.raises(rk.RcmKinError, match="mypsm has no drive .*: give `drive`"):
        rk.gravity_map(mine, roll_deg=[0.0], pitch_deg=[0.0])
    with pytest.raises(rk.RcmKinError, match="describes robot 'psm', not 'mypsm'"):     # given: checked too
        rk.gravity_map(mine, rk.load_drive_parameters(), roll_deg=[0.0], pitch_deg=[0.0])

"""Which drive a statics result uses: ``gravity_map`` takes the same one as ``holding_effort`` (the
sidecar's, else none: then an error, as the map is in volts and PWM), checks a given one against
the robot, and ``holding_effort`` still takes its former keyword ``params=``. Copies of the PSM are
made in the tests from the shipped files (only the robot name / drive line / one constant changed)."""

from __future__ import annotations

import re
import shutil

import numpy as np
import pytest

import rcm_kin as rk
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, drive_effort, load_drive_parameters
from rcm_kin.model.gravity import gravity_batch
from rcm_kin.model.loading import urdf_dir
from rcm_kin.statics import holding, maps

Q = [np.radians(10.0), np.radians(-15.0), 0.08, 0, 0, 0, 0]


def psm_copy(folder, robot="psm", drive_line=None, volts_per_pwm=None):
    """The PSM's URDF and sidecar in ``folder``, named ``robot``, with ``drive_line`` (None: no drive
    line) and, if given, a copy of the shipped drive file whose every volts_per_pwm is changed."""
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(urdf_dir() / "psm.urdf", folder / "psm.urdf")
    text = re.sub(r'^robot = "psm"$', f'robot = "{robot}"', (urdf_dir() / "psm.toml").read_text(), flags=re.M)
    text = re.sub(r"^drive = .*$", "" if drive_line is None else drive_line, text, flags=re.M)
    (folder / f"{robot}.toml").write_text(text)
    if volts_per_pwm is not None:
        drive = DEFAULT_PARAMETERS.read_text()
        drive = re.sub(r'^robot = "psm"', f'robot = "{robot}"', drive, flags=re.M)
        limit = "" if robot == "psm" else "\npwm_limit = 255.0"      # another robot's file states its limit
        drive = re.sub(r"^volts_per_pwm = .*$", f"volts_per_pwm = {volts_per_pwm!r}{limit}", drive, flags=re.M)
        (folder / "own_drive.toml").write_text(drive)
    return folder / f"{robot}.toml"


def test_a_psm_named_copy_without_a_drive_line_gets_no_calibration_from_either(tmp_path):
    """Named "psm" but its sidecar names no drive: holding_effort runs on the CAD, and gravity_map (before:
    the shipped calibration, by the name) says it needs a drive instead of applying another one."""
    copy = rk.load_robot(psm_copy(tmp_path / "a"))
    assert copy.name == "psm" and copy.description.drive is None
    effort = rk.holding_effort(copy, Q)
    assert effort.drive is None and effort.model == "CAD (URDF inertias)"
    np.testing.assert_allclose(effort.tau, gravity_batch(copy, np.array([Q]))[0], rtol=0, atol=1e-12)
    with pytest.raises(rk.RcmKinError, match="psm has no drive .*use torque_map for its holding torques") as err:
        rk.gravity_map(copy, roll_deg=[10.0], pitch_deg=[-15.0], insertion=[0.08])
    assert "\n" not in str(err.value)


def test_gravity_map_and_holding_effort_use_the_sidecars_own_drive(tmp_path):
    """A copy (named psm) whose sidecar names its own drive file (volts_per_pwm changed): both use it; the
    PWM is the independent drive model on the calibrated gravity, and not the shipped file's."""
    copy = rk.load_robot(psm_copy(tmp_path / "b", drive_line='drive = "own_drive.toml"', volts_per_pwm=0.04))
    own = load_drive_parameters(tmp_path / "b" / "own_drive.toml")
    gmap = rk.gravity_map(copy, roll_deg=[10.0], pitch_deg=[-15.0], insertion=[0.08])
    one = rk.holding_effort(copy, Q)
    assert one.model == "calibration own_drive.toml"
    tau = gravity_batch(copy, np.array([Q]), own.gravity_offsets)[0]
    want = drive_effort(own, tau[[copy.actuated.index(j) for j in own.driven]])
    np.testing.assert_allclose(one.drive.pwm, want.pwm, rtol=0, atol=1e-9)
    np.testing.assert_allclose(gmap.sel(roll=10.0, pitch=-15.0).pwm, want.pwm, rtol=0, atol=1e-9)
    shipped = rk.holding_effort(rk.load_robot("psm"), Q)
    assert np.abs(shipped.drive.pwm - want.pwm).max() > 1.0


def test_gravity_map_checks_a_given_drive_against_the_robot(tmp_path):
    """Another robot's drive file given to gravity_map (before: applied silently) is a one-line error naming
    both robots, as for holding_effort; the bundled PSM's own file runs."""
    mine = psm_copy(tmp_path / "c", robot="mypsm", volts_per_pwm=0.04)
    psm = rk.load_robot("psm")
    theirs = load_drive_parameters(tmp_path / "c" / "own_drive.toml")
    for drive in (theirs, tmp_path / "c" / "own_drive.toml"):
        with pytest.raises(rk.RcmKinError, match="describes robot 'mypsm', not 'psm'"):
            rk.gravity_map(psm, drive, [0.0], [0.0], [0.08])
    with pytest.raises(rk.RcmKinError, match="describes robot 'psm', not 'mypsm'"):
        rk.gravity_map(rk.load_robot(mine), load_drive_parameters(), [0.0], [0.0], [0.08])
    rk.gravity_map(rk.load_robot(mine), theirs, [0.0], [0.0], [0.08])          # its own: it runs


def test_a_drive_file_in_another_joint_order_maps_the_same(tmp_path):
    """The shipped drive file with [pitch] before [roll]: the map's joint axis stays roll, pitch, insertion."""
    text = DEFAULT_PARAMETERS.read_text()
    tables = re.split(r"(?m)^(?=\[)", text)
    head, rest = tables[0], tables[1:]
    order = sorted(range(len(rest)), key=lambda k: (not rest[k].startswith("[pitch]"), k))
    (tmp_path / "reorder.toml").write_text(head + "".join(rest[k] for k in order))
    reordered = load_drive_parameters(tmp_path / "reorder.toml")
    assert set(reordered.driven) == {"roll", "pitch", "insertion"}
    psm = rk.load_robot("psm")
    a = rk.gravity_map(psm, reordered, [-10.0, 20.0], [5.0], [0.1])
    b = rk.gravity_map(psm, None, [-10.0, 20.0], [5.0], [0.1])
    for name in ("tau", "pwm", "voltage"):
        np.testing.assert_array_equal(getattr(a.effort, name), getattr(b.effort, name))


def test_holding_effort_still_takes_params(tmp_path):
    """The former keyword ``params=`` (before: TypeError) gives the numbers of ``drive=``; both is an error."""
    psm = rk.load_robot("psm")
    by_drive = rk.holding_effort(psm, Q, drive=DEFAULT_PARAMETERS)
    by_params = rk.holding_effort(psm, Q, params=DEFAULT_PARAMETERS)
    np.testing.assert_array_equal(by_params.tau, by_drive.tau)
    np.testing.assert_array_equal(by_params.drive.pwm, by_drive.drive.pwm)
    assert by_params.model == "calibration psm_drive.toml"
    with pytest.raises(rk.RcmKinError, match="give `drive` .* not both"):
        rk.holding_effort(psm, Q, drive=DEFAULT_PARAMETERS, params=DEFAULT_PARAMETERS)


def test_one_drive_effort_blocks():
    """The maps of the PSM and of any robot run the drive model through the same function."""
    assert holding.drive_effort_blocks is maps.drive_effort_blocks
    assert not hasattr(maps, "SHIPPED_ROBOT")


def test_parse_range_names_the_unit():
    with pytest.raises(rk.RcmKinError, match=r"--grid insertion must be LO:HI:N \(m, m, count\)"):
        maps.parse_range("0.1:0.2", "--grid insertion", "m")
    with pytest.raises(rk.RcmKinError, match=r"--roll must be LO:HI:N \(deg, deg, count\)"):
        maps.parse_range("1:2", "--roll")

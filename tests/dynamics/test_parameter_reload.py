"""A parameter file edited on disk gives the new model at the next call: nothing caches a file by
its path, and the caches keyed by a parameter set see the edit."""

from __future__ import annotations

import re

import numpy as np

import rcm_kin as rk
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS


def test_an_edited_parameter_file_gives_the_new_holding_pwm(tmp_path):
    path = tmp_path / "drive.toml"
    text = DEFAULT_PARAMETERS.read_text()
    path.write_text(text)
    psm = rk.load_robot("psm")
    q = [np.radians(10), np.radians(-15), 0.08, 0, 0, 0, 0]
    before = rk.holding_effort(psm, q, path).drive
    # the roll driver's volts per PWM count doubled: at rest V = R i is unchanged, so the roll PWM halves
    roll = re.search(r"^\[roll\]$", text, re.M).start()
    end = text.index("\n[", roll + 1)
    edited = re.sub(r"volts_per_pwm = ([0-9.eE+-]+)", lambda m: f"volts_per_pwm = {2 * float(m.group(1))!r}",
                    text[roll:end], count=1)
    path.write_text(text[:roll] + edited + text[end:])
    after = rk.holding_effort(psm, q, path).drive
    np.testing.assert_allclose(after.pwm[0], before.pwm[0] / 2, rtol=1e-12)
    np.testing.assert_allclose(after.voltage, before.voltage, rtol=1e-12)
    # the compiled map sees the same file: its cache is keyed by the parameter values
    tmap = rk.gravity_map(psm, rk.load_drive_parameters(path), [10.0], [-15.0], [0.08])
    np.testing.assert_allclose(tmap.sel(roll=10.0, pitch=-15.0).pwm, after.pwm, atol=1e-9)


def test_edited_gravity_offsets_reach_every_cache(tmp_path):
    """The first moments of [gravity_offsets] are baked into the compiled gravity and enter the
    gain schedule's linear models: after an edit, both follow the file, and the map equals the
    independent NumPy gravity of the edited offsets."""
    from rcm_kin.model.gravity import gravity_batch
    from rcm_kin.simulation.experiments import psm_schedule

    path = tmp_path / "drive.toml"
    text = DEFAULT_PARAMETERS.read_text()
    path.write_text(text)
    psm = rk.load_robot("psm")
    before = rk.load_drive_parameters(path)
    map_before = rk.gravity_map(psm, before, [10.0], [-15.0], [0.08]).sel(roll=10.0, pitch=-15.0)
    schedule_before = psm_schedule(before)
    path.write_text(re.sub(r"^drive_link = \[([0-9.eE+-]+),", lambda m: f"drive_link = [{2 * float(m.group(1))!r},",
                           text, count=1, flags=re.M))
    after = rk.load_drive_parameters(path)
    assert not np.array_equal(after.gravity_offsets["drive_link"], before.gravity_offsets["drive_link"])
    map_after = rk.gravity_map(psm, after, [10.0], [-15.0], [0.08]).sel(roll=10.0, pitch=-15.0)
    q = np.array([[np.radians(10), np.radians(-15), 0.08, 0, 0, 0, 0]])
    np.testing.assert_allclose(map_after.tau, gravity_batch(psm, q, after.gravity_offsets)[0, :3], atol=1e-9)
    assert abs(map_after.tau[1] - map_before.tau[1]) > 0.1            # the pitch carries the drive link
    schedule_after = psm_schedule(after)
    assert schedule_after is not schedule_before
    assert not np.allclose(schedule_after.k_pitch, schedule_before.k_pitch)

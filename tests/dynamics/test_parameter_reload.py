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

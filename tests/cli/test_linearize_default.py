"""``linearize`` is the schedule's model by default: no smoothed-Coulomb slope unless ``--coulomb``."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

import rcm_kin as rk


def run(*args):
    return subprocess.run([sys.executable, "-m", "rcm_kin.cli", "linearize", "psm", "--roll", "10", "--pitch=-5",
                           *args], capture_output=True, text=True)


def test_default_is_without_the_slope_and_coulomb_adds_it():
    psm = rk.load_robot("psm")
    q = [np.radians(10), np.radians(-5), 0.08]
    plain = rk.linearize(rk.driven_dynamics(psm, coulomb=False), q)
    smooth = rk.linearize(rk.driven_dynamics(psm, coulomb=True), q)
    default, with_slope, without = (json.loads(run(*a, "--json").stdout) for a in ((), ("--coulomb",),
                                                                                    ("--no-coulomb",)))
    np.testing.assert_array_equal(default["A"], plain.A)
    np.testing.assert_array_equal(without["A"], plain.A)
    np.testing.assert_array_equal(with_slope["A"], smooth.A)
    assert not default["coulomb_slope"] and with_slope["coulomb_slope"]
    # the slope is F_c / v_c on the velocity diagonal: the two differ there and only there
    diff = np.array(with_slope["A"]) - np.array(default["A"])
    drive = rk.load_drive_parameters()
    inertia_scaled = -diff[3, 3] * drive["roll"].coulomb_velocity / drive["roll"].coulomb
    assert diff[3, 3] < -10 and inertia_scaled > 0


def test_coulomb_and_no_coulomb_together_is_one_line():
    out = run("--coulomb", "--no-coulomb")
    assert out.returncode == 2 and out.stderr.strip().splitlines() == [
        "error: --coulomb and --no-coulomb contradict each other: give one"]

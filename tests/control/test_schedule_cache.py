"""Gain schedules kept on disk: read back bit for bit, designed once per key, a damaged file
designed anew with a warning, the folder bounded."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import fields

import numpy as np
import pytest

from rcm_kin.control.friction import FrictionCompensation
from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG, GainSchedule, schedule_gains
from rcm_kin.control.schedule_cache import cached_schedule, schedule_folder, schedule_key
from rcm_kin.control.weights import Weights
from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.errors import RcmKinWarning


@pytest.fixture(autouse=True)
def fresh_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))


@pytest.fixture(scope="module")
def designed(psm):
    return schedule_gains(driven_dynamics(psm, coulomb=False), THESIS_ROLL_DEG, THESIS_PITCH_DEG,
                          weights=Weights(roll_pwm=80.0), friction_ramp_deg_s=7.5)


def counting(schedule: GainSchedule):
    calls = []

    def design():
        calls.append(1)
        return schedule
    return design, calls


def assert_identical(a: GainSchedule, b: GainSchedule):
    for f in fields(GainSchedule):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), f.name
        else:
            assert x == y, f.name


def test_a_stored_schedule_reads_back_bit_for_bit_without_designing(designed):
    design, calls = counting(designed)
    key = schedule_key("test", "a")
    assert_identical(cached_schedule(key, design), designed)
    again = cached_schedule(key, design)
    assert calls == [1]
    assert_identical(again, designed)
    assert again.friction == FrictionCompensation(designed.friction.pwm, 7.5) and again.weights.roll_pwm == 80.0
    assert len(list(schedule_folder().glob("*.npz"))) == 1


def test_another_key_designs_anew(designed):
    design, calls = counting(designed)
    cached_schedule(schedule_key("test", "a"), design)
    cached_schedule(schedule_key("test", "b"), design)
    assert calls == [1, 1]


def test_a_schedule_without_friction_compensation(designed):
    bare = GainSchedule(**{f.name: getattr(designed, f.name) for f in fields(GainSchedule)} | {"friction": None})
    key = schedule_key("bare")
    cached_schedule(key, lambda: bare)
    assert cached_schedule(key, lambda: pytest.fail("designed again")).friction is None


@pytest.mark.parametrize("damage", ["truncate", "swap", "no checksum"])
def test_a_damaged_file_is_designed_anew_with_a_warning(designed, damage):
    design, calls = counting(designed)
    key = schedule_key("test", damage)
    cached_schedule(key, design)
    path = next(schedule_folder().glob("*.npz"))
    if damage == "truncate":
        path.write_bytes(path.read_bytes()[:100])
    elif damage == "swap":
        path.write_bytes(path.read_bytes().replace(b"NUMPY", b"NUMPZ", 1))
    else:
        path.with_name(path.name + ".sha256").unlink()
    with pytest.warns(RcmKinWarning, match="designed anew"):
        assert_identical(cached_schedule(key, design), designed)
    assert calls == [1, 1]
    assert_identical(cached_schedule(key, design), designed)      # stored again, sound
    assert calls == [1, 1]


def test_the_key_follows_the_parts():
    assert schedule_key("a", "b") == schedule_key("a", "b") != schedule_key("a", "c")


def test_a_fresh_process_reads_the_simulations_schedule_from_disk(psm):
    """``psm_schedule`` in two fresh processes: the second reads the file the first stored, and
    both give the design made here directly."""
    code = ("import sys, numpy as np; from rcm_kin.simulation.experiments import psm_schedule; s = psm_schedule(); "
            "print(np.concatenate([s.k_roll.ravel(), s.k_pitch.ravel()]).tobytes().hex()); "
            "print('control' in sys.modules, 'scipy.linalg' in sys.modules)")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
            for _ in range(2)]
    design = schedule_gains(driven_dynamics(psm, coulomb=False), THESIS_ROLL_DEG, THESIS_PITCH_DEG)
    expected = np.concatenate([design.k_roll.ravel(), design.k_pitch.ravel()]).tobytes().hex()
    assert runs[0][0] == runs[1][0] == expected
    assert runs[0][1] == "False"                           # python-control is not imported to design
    assert len(list(schedule_folder().glob("*.npz"))) == 1


def test_the_folder_keeps_the_most_recently_used(designed, monkeypatch):
    import rcm_kin.control.schedule_cache as cache

    monkeypatch.setattr(cache, "CACHE_SCHEDULES", 2)
    for part in "abc":
        cached_schedule(schedule_key(part), lambda: designed)
    assert len(list(schedule_folder().glob("*.npz"))) == len(list(schedule_folder().glob("*.sha256"))) == 2


def test_a_file_that_matches_its_checksum_but_does_not_read_is_designed_anew(designed):
    """A file whose checksum file was written for its (bad) bytes: read, refused, designed anew."""
    import hashlib

    key = schedule_key("test", "unreadable")
    cached_schedule(key, lambda: designed)
    path = next(schedule_folder().glob("*.npz"))
    path.write_bytes(b"not a zip archive")
    path.with_name(path.name + ".sha256").write_text(f"{hashlib.sha256(b'not a zip archive').hexdigest()} {key}\n")
    with pytest.warns(RcmKinWarning, match="does not read"):
        assert_identical(cached_schedule(key, lambda: designed), designed)

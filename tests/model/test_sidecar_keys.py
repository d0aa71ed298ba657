"""A misspelt sidecar key is an error: it would otherwise drop a calibration or a tilt silently."""

from __future__ import annotations

import shutil

import pytest

import rcm_kin as rk
from rcm_kin.model.loading import urdf_dir


@pytest.fixture()
def folder(tmp_path):
    for name in ("psm.urdf", "psm_drive.toml", "mtm.urdf"):
        shutil.copy(urdf_dir() / name, tmp_path / name)
    return tmp_path


@pytest.mark.parametrize("text, match", [
    ('urdf = "mtm.urdf"\ndrvie = "psm_drive.toml"\n', r"unknown keys \['drvie'\]"),
    ('urdf = "mtm.urdf"\n[bsae]\nrpy = [0, 1, 0]\n', r"unknown keys \['bsae'\]"),
    ('urdf = "mtm.urdf"\n[rcm]\nshaft_frame = "tool_tip"\njoints = ["j1", "j2"]\nbase = "x"\n',
     r"\[rcm\]: unknown keys \['base'\]"),
    ('urdf = "mtm.urdf"\n[[passive]]\njoint = "j2"\nfollows = "j1"\nmultiplier = 1\nofset = 0\n',
     r"passive 1: unknown keys \['ofset'\]"),
    ('urdf = "mtm.urdf"\ndrive = 5\n', r"'drive' must be a text \(a name\), got 5"),
    ('urdf = "mtm.urdf"\npassive = 3\n', r"'passive' must be \[\[passive\]\] tables"),
])
def test_unknown_or_mistyped_keys_are_one_line(folder, text, match):
    (folder / "r.toml").write_text(text)
    with pytest.raises(rk.RcmKinError, match=match) as info:
        rk.load_robot(folder / "r.toml")
    assert "\n" not in str(info.value)


def test_every_bundled_sidecar_uses_known_keys():
    for name in rk.robot_names():
        rk.load_robot(name)

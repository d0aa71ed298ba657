"""The holding band's rule (the conformal quantile, checked against hand-sorted residuals), its centre
(the holding effort's PWM), and the extrapolated flag outside the calibrated poses. The drive files
are copies of the shipped one with hand-made [uncertainty] tables."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import rcm_kin as rk
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, load_drive_parameters
from rcm_kin.statics.holding import torque_map
from rcm_kin.statics.holding_band import band_columns, check_level, conformal_half_width, holding_band
from rcm_kin.statics.maps import holding_effort

RESIDUALS = [3.0, -1.0, 4.0, -1.5, 5.0, -9.0, 2.0, 6.0, 5.5, -3.5]   # |r| sorted: 1 1.5 2 3 3.5 4 5 5.5 6 9


def without_uncertainty() -> str:
    return DEFAULT_PARAMETERS.read_text().split("[uncertainty.")[0]


@pytest.fixture(scope="module")
def banded(tmp_path_factory):
    """The shipped drive with roll residuals 1..11 (a 0.9 band: the 11th smallest, 11), pitch RESIDUALS
    (n = 10: the 10th, 9) and the hull roll [-0.1, 0.2], pitch [-0.3, 0.3] rad."""
    path = tmp_path_factory.mktemp("band") / "banded.toml"
    path.write_text(without_uncertainty() + "\n[uncertainty.hull]\nroll = [-0.1, 0.2]\npitch = [-0.3, 0.3]\n"
                    "\n[uncertainty.holding_residuals]\nroll = [" + ", ".join(str(float(k)) for k in range(1, 12))
                    + "]\npitch = [" + ", ".join(map(str, RESIDUALS)) + "]\n")
    return path


@pytest.mark.parametrize("level, expected", [(0.5, 4.0), (0.8, 6.0), (0.9, 9.0), (0.05, 1.0)])
def test_half_width_is_the_conformal_quantile(level, expected):
    """n = 10: the ceil(11 L)-th smallest |r|: L 0.5 -> 6th (4), 0.8 -> 9th (6), 0.9 -> 10th (9), 0.05 -> 1st."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert conformal_half_width(RESIDUALS, level) == expected


def test_a_level_the_holds_cannot_support_takes_the_largest_and_warns():
    with pytest.warns(rk.RcmKinWarning, match="10 left-out residuals cannot support a 0.95 band"):
        assert conformal_half_width(RESIDUALS, 0.95) == 9.0      # ceil(11 x 0.95) = 11 > 10
    with warnings.catch_warnings():
        warnings.simplefilter("error")                            # n = 9, L = 0.9: index 9 exactly, no warning
        assert conformal_half_width(np.arange(1.0, 10.0), 0.9) == 9.0


@pytest.mark.parametrize("level", [0, 1, -0.1, 1.5, float("nan"), "x", None])
def test_a_bad_level_is_one_line(level):
    with pytest.raises(rk.RcmKinError, match="band level must be"):
        check_level(level)


def test_band_is_centred_on_the_holding_effort_and_flags_outside_the_hull(psm, banded):
    inside, outside = np.array([0.1, 0.2, 0.08, 0, 0, 0, 0]), np.array([0.3, 0.2, 0.08, 0, 0, 0, 0])
    for q, flagged in ((inside, ()), (outside, ("roll",))):
        band = holding_band(psm, q, 0.9, banded)
        pwm = holding_effort(psm, q, banded).drive.pwm[:2]       # roll, pitch: the file's first two joints
        assert band.joints == ("roll", "pitch")
        np.testing.assert_allclose(band.nominal, pwm, rtol=0, atol=1e-12)
        np.testing.assert_allclose(band.half_width, [11.0, 9.0])
        np.testing.assert_allclose(band.lower, pwm - [11.0, 9.0], atol=1e-12)
        np.testing.assert_allclose(band.upper, pwm + [11.0, 9.0], atol=1e-12)
        assert band.extrapolated == bool(flagged) and band.outside == flagged
    d = holding_band(psm, outside, 0.5, banded).as_dict()
    assert d["half_width_pwm"] == {"roll": 6.0, "pitch": 4.0} and d["extrapolated"] is True   # 6th of 11, 6th of 10
    assert d["hull_deg"]["roll"] == pytest.approx(np.degrees([-0.1, 0.2]).tolist())


def test_a_file_without_holding_residuals_says_run_calibrate(psm, tmp_path):
    (tmp_path / "bare.toml").write_text(without_uncertainty())
    assert not load_drive_parameters(tmp_path / "bare.toml").uncertainty
    with pytest.raises(rk.RcmKinError, match=r"no holding residuals in bare.toml: run rcm-kin calibrate"):
        holding_band(psm, np.zeros(7), 0.9, tmp_path / "bare.toml")


def test_torque_map_band_columns(psm, banded):
    """--grid form: lower/upper = pwm -+ the half-width; extrapolated where roll or pitch is outside the hull."""
    roll, pitch = np.radians([-10.0, 0.0, 15.0]), np.radians([-20.0, 10.0])
    tmap = torque_map(psm, {"roll": roll, "pitch": pitch}, drive=banded, band=0.9)
    pwm = tmap.effort.pwm
    np.testing.assert_allclose(tmap.extra["lower_pwm_roll"], pwm[..., 0] - 11.0)
    np.testing.assert_allclose(tmap.extra["upper_pwm_pitch"], pwm[..., 1] + 9.0)
    expected = ((roll < -0.1) | (roll > 0.2))[:, None] | (np.abs(pitch) > 0.3)[None, :]    # the hull by hand
    np.testing.assert_array_equal(tmap.extra["extrapolated"], expected.astype(float))
    assert tmap.header()[-5:] == ["lower_pwm_roll", "upper_pwm_roll", "lower_pwm_pitch", "upper_pwm_pitch",
                                  "extrapolated"]
    assert tmap.rows(0, tmap.poses).shape[1] == len(tmap.header())
    cols = band_columns(load_drive_parameters(banded), ("roll", "pitch", "insertion"), np.zeros((4, 3)),
                        {"roll": np.array([0.0, 0.15, -0.2, 0.0]), "pitch": np.array([0.0, 0.0, 0.0, 0.31])}, 0.9)
    np.testing.assert_array_equal(cols["extrapolated"], [0.0, 0.0, 1.0, 1.0])
    assert not re.search("insertion", " ".join(cols))

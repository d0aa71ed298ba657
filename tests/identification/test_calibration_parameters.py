"""The calibration keeps what it does not fit (the file's robot and drive-train model), refuses another
robot's starting file, and reads the joints of the file by name (any table order). The holding points are
synthetic: made from a known drive model, which the fit must then recover."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest

import rcm_kin as rk
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, load_drive_parameters
from rcm_kin.identification.calibration import HoldingPoint, apply_values, calibrate, predict_pwm


def synthetic_points(psm, params):
    grid = [(r, p) for r in np.radians([-20.0, 0.0, 15.0]) for p in np.radians([-25.0, 5.0, 30.0])]
    points = [HoldingPoint(f"p{k}", r, p, 0.0, 0.0) for k, (r, p) in enumerate(grid)]
    pwm = predict_pwm(psm, params, points)
    return [replace(point, pwm_roll=a, pwm_pitch=b) for point, (a, b) in zip(points, pwm)]


def test_apply_values_keeps_the_robot_and_the_drive_train():
    base = replace(load_drive_parameters(), robot="another")
    assert base.drive_train                                  # the shipped file has [drive_train.roll]
    got = apply_values(base, [0.05, 0.01, -0.02, 0.03])
    assert got.robot == "another" and got.drive_train == base.drive_train and got.source == base.source
    assert got["roll"].volts_per_pwm == got["pitch"].volts_per_pwm == 0.05
    np.testing.assert_array_equal(got.gravity_offsets["roll_link"], [0.0, 0.01, -0.02])
    np.testing.assert_array_equal(got.gravity_offsets["drive_link"], [0.03, 0.0, 0.0])


def test_calibrate_recovers_a_known_model_and_refuses_another_robots_file(tmp_path):
    psm = rk.load_robot("psm")
    truth = apply_values(load_drive_parameters(), [0.07, 0.004, -0.03, -0.4])
    points = synthetic_points(psm, truth)
    fit = calibrate(psm, load_drive_parameters(), points)
    np.testing.assert_allclose(fit.values, [0.07, 0.004, -0.03, -0.4], rtol=1e-6, atol=1e-8)
    assert fit.parameters.robot == "psm" and fit.parameters.drive_train == truth.drive_train
    with pytest.raises(rk.RcmKinError, match="describes robot 'another', not 'psm'"):
        calibrate(psm, replace(load_drive_parameters(), robot="another"), points)


def test_the_file_order_of_the_joints_does_not_matter(tmp_path):
    text = DEFAULT_PARAMETERS.read_text()
    head, *tables = re.split(r"(?m)^(?=\[)", text)
    order = sorted(range(len(tables)), key=lambda k: (not tables[k].startswith("[pitch]"), k))
    (tmp_path / "reorder.toml").write_text(head + "".join(tables[k] for k in order))
    psm = rk.load_robot("psm")
    reordered, shipped = load_drive_parameters(tmp_path / "reorder.toml"), load_drive_parameters()
    points = synthetic_points(psm, shipped)
    np.testing.assert_allclose(predict_pwm(psm, reordered, points), predict_pwm(psm, shipped, points), rtol=0,
                               atol=1e-12)

"""Counterweight placement for any counterweight link, checked on the MTM's J1 counterweight against the
analytic balance: a point mass m at distance l from the shoulder axis adds m g l cos(q1 + phi) to J1's
holding torque (robot-parameters.md), fitted here by least squares to Pinocchio's gravity of the arm."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import rcm_kin as rk
from rcm_kin.statics.counterweights import mount_link, place_counterweight

GRID = {"j1": np.radians(np.linspace(-60, 60, 13)), "j3": np.radians(np.linspace(-30, 80, 12))}


@pytest.fixture(scope="module")
def design():
    return place_counterweight(rk.load_robot("mtm"), "counterweight", GRID, joints=["j1"])


def test_the_mtm_counterweight_design_is_the_analytic_balance(design):
    without = rk.load_robot("mtm", counterweights=False)
    data = without.tree.createData()
    q1, q3 = (x.ravel() for x in np.meshgrid(GRID["j1"], GRID["j3"], indexing="ij"))
    arm = np.array([pin.computeGeneralizedGravity(without.tree, data, np.array([a, 0, b, 0, 0, 0, 0]))[0]
                    for a, b in zip(q1, q3)])
    m, g = design.mass, 9.81
    # J1 axis horizontal: the counterweight's torque m g l cos(q1 + phi) = m g (c cos q1 - s sin q1)
    basis = m * g * np.column_stack([np.cos(q1), -np.sin(q1)])
    (c, s), *_ = np.linalg.lstsq(basis, -arm, rcond=None)
    assert design.mass == pytest.approx(0.317)
    assert np.hypot(*design.position[:2]) == pytest.approx(np.hypot(c, s), rel=1e-9)
    rms = np.sqrt(np.mean((arm + basis @ [c, s]) ** 2))
    assert design.rms[0] == pytest.approx(rms, rel=1e-9)
    assert design.rms[0] < design.rms_as_built[0] < design.rms_without[0]
    assert design.rank == 2                     # the position along the J1 axis never changes a torque


def test_the_as_built_counterweight_is_the_urdf_one(design):
    assert design.mount == "shoulder_link"
    assert np.hypot(*design.as_built[:2]) == pytest.approx(0.0725, abs=1e-6)       # 72.5 mm (robot-parameters.md)
    np.testing.assert_allclose(design.as_built, [-0.071648492390876034, -0.011078968278435472, 0.0], atol=1e-12)


def test_a_brute_force_search_finds_no_better_position(design):
    """Evaluate J1's RMS over a fine (x, y) grid around the design with the counterweight's mass moved,
    with Pinocchio on the robot without counterweights plus a point mass model of it."""
    without = rk.load_robot("mtm", counterweights=False)
    model = pin.Model(without.tree)
    data = model.createData()
    q1, q3 = (x.ravel() for x in np.meshgrid(GRID["j1"], GRID["j3"], indexing="ij"))
    j = model.frames[model.getFrameId("shoulder_link")].parentJoint
    base = model.inertias[j].copy()
    best = np.inf
    for dx in np.linspace(-0.01, 0.01, 5):
        for dy in np.linspace(-0.01, 0.01, 5):
            p = design.position + [dx, dy, 0]
            model.inertias[j] = base + pin.Inertia.FromSphere(design.mass, 1e-3).se3Action(pin.SE3(np.eye(3), p))
            tau = [pin.computeGeneralizedGravity(model, data, np.array([a, 0, b, 0, 0, 0, 0]))[0]
                   for a, b in zip(q1, q3)]
            best = min(best, float(np.sqrt(np.mean(np.square(tau)))))
    assert best >= design.rms[0] - 1e-12
    assert best == pytest.approx(design.rms[0], rel=1e-9)       # the design point (dx = dy = 0) is on the grid


def test_the_psm_counterweights_hang_on_their_links():
    psm = rk.load_robot("psm")
    assert mount_link(psm, "main_counterweight") == "roll_link" and mount_link(psm, "dpm_counterweight") == "drive_link"
    d = place_counterweight(psm, "main_counterweight", {"roll": np.radians([-30, 0, 30]), "pitch": [0.0, 0.2]},
                            q=[0, 0, 0.08, 0, 0, 0, 0])
    assert d.unit == "PWM counts" and d.joints == ("roll", "pitch", "insertion")
    assert d.rms[0] <= d.rms_as_built[0] + 1e-9
    np.testing.assert_allclose(d.rms[1:], d.rms_without[1:], rtol=1e-9)    # the roll body's mass never loads pitch


def test_a_link_that_is_no_counterweight_is_refused():
    with pytest.raises(rk.RcmKinError, match="upper_arm is not a counterweight of mtm .its sidecar's counterweights: "
                                             "counterweight"):
        place_counterweight(rk.load_robot("mtm"), "upper_arm", GRID)
    with pytest.raises(rk.RcmKinError, match=r"`mass` is a number in \(0, 1000\] kg, got 0.0"):
        place_counterweight(rk.load_robot("mtm"), "counterweight", GRID, mass=0.0)

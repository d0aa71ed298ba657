"""The torque map's fast path changes no number: blocks of any size (remainders included) equal
plain Pinocchio per pose and the compiled gravity called pose by pose, bit for bit; the drive's
blocks equal one drive_effort call; a robot without counterweights is rebuilt once."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pinocchio as pin
import pytest

import rcm_kin as rk
from rcm_kin.dynamics.drive import DriveEffort, drive_effort
from rcm_kin.statics import holding, maps


@pytest.fixture(scope="module")
def mtm():
    return rk.load_robot("mtm")


def grid_poses(q, index, values):
    A, B = np.meshgrid(*values, indexing="ij")
    poses = np.broadcast_to(q, (A.size, len(q))).copy()
    poses[:, index[0]], poses[:, index[1]] = A.ravel(), B.ravel()
    return poses


@pytest.mark.parametrize("block", [1, 7, 64, holding.BLOCK])
def test_blocks_equal_the_compiled_gravity_pose_by_pose(mtm, block):
    values = (np.radians(np.linspace(-40, 60, 9)), np.radians(np.linspace(-30, 80, 11)))
    q = np.radians([20.0, 0, 0, 10, 0, -5, 0])
    tau = holding.map_gravity(mtm, {}, q, (1, 2), values, block=block)
    poses = grid_poses(q, (1, 2), values)
    assert tau.shape == (9, 11, mtm.nq)
    compiled = holding._compiled(mtm, ()).function
    by_pose = np.array([np.array(compiled(p)).ravel() for p in poses])
    assert tau.reshape(-1, mtm.nq).tobytes() == by_pose.tobytes()
    model, data = mtm.tree, mtm.tree.createData()           # a serial arm: tree q = actuated q
    plain = np.array([pin.computeGeneralizedGravity(model, data, p) for p in poses])
    np.testing.assert_allclose(tau.reshape(-1, mtm.nq), plain, rtol=1e-9, atol=1e-9)


def test_the_drive_in_blocks_equals_one_drive_effort_call(psm, params):
    tmap = rk.torque_map(psm, {"roll": np.radians(np.linspace(-30, 30, 71)),
                               "pitch": np.radians(np.linspace(-20, 20, 67))}, [0, 0, 0.1, 0, 0, 0, 0])
    assert tmap.poses > maps.DRIVE_BLOCK                    # several blocks and a remainder
    driven = tmap.tau[..., [psm.actuated.index(j) for j in params.driven]]
    whole = drive_effort(params, driven.reshape(-1, 3))
    for f in fields(DriveEffort):
        got, want = getattr(tmap.effort, f.name), getattr(whole, f.name)
        assert got.shape == (71, 67, 3) and got.tobytes() == want.reshape(got.shape).tobytes(), f.name


def test_a_robot_without_counterweights_is_built_once(mtm):
    grid = {"j2": np.radians([0.0, 10.0]), "j3": np.radians([5.0, 20.0, 30.0])}
    first = holding.with_counterweights(mtm, False)
    assert holding.with_counterweights(mtm, False) is first and not first.with_counterweights
    assert holding.with_counterweights(mtm, True) is mtm
    light = rk.torque_map(mtm, grid, counterweights=False)
    reference = rk.load_robot("mtm", counterweights=False)
    poses = grid_poses(holding.default_pose(mtm), (1, 2), tuple(grid.values()))
    model, data = reference.tree, reference.tree.createData()
    plain = np.array([pin.computeGeneralizedGravity(model, data, p) for p in poses])
    np.testing.assert_allclose(light.tau.reshape(-1, mtm.nq), plain, rtol=1e-9, atol=1e-9)

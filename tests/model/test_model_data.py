"""Pinocchio's Model/Data split in rcm_kin: the robot cache follows the files' content, and no two
threads (or callers with their own workspaces) share scratch data."""

from __future__ import annotations

import dataclasses
import re
import shutil
import threading

import numpy as np
import pinocchio as pin
import pytest

import rcm_kin as rk
from rcm_kin.errors import JointLimitError, RcmKinError
from rcm_kin.model.loading import urdf_dir


@pytest.fixture()
def psm_copy(tmp_path):
    for suffix in (".toml", ".urdf", "_drive.toml"):
        shutil.copy(urdf_dir() / f"psm{suffix}", tmp_path / f"psm{suffix}")
    return tmp_path / "psm.toml"


def plain_gravity(urdf, q_tree):
    """Open-tree gravity of a URDF by plain Pinocchio (the independent reference)."""
    model = pin.buildModelFromUrdf(str(urdf))
    model.gravity.linear = np.array([0.0, 0.0, -9.81])
    return pin.computeGeneralizedGravity(model, model.createData(), q_tree)


def test_an_edited_urdf_is_reloaded(psm_copy):
    q = np.array([0.2, -0.3, 0.1, 0, 0, 0, 0])
    before = rk.load_robot(str(psm_copy))
    assert rk.load_robot(str(psm_copy)) is before                      # unchanged files: one build
    tau_before = rk.gravity_torque(before, q, method="constrained")
    urdf = psm_copy.with_suffix(".urdf")
    # every mass tripled, centres of mass kept: gravity is linear in the masses, so it triples
    urdf.write_text(re.sub(r'<mass value="([^"]+)"', lambda m: f'<mass value="{3 * float(m.group(1))!r}"',
                           urdf.read_text()))
    after = rk.load_robot(str(psm_copy))
    assert after is not before
    np.testing.assert_allclose(rk.gravity_torque(after, q, method="constrained"), 3 * tau_before, rtol=1e-12,
                               atol=1e-12)
    # the reloaded model is the edited file's: open-tree gravity equals plain Pinocchio on it
    from rcm_kin.model.constrained import solve_loops
    q_tree = solve_loops(after, q)
    np.testing.assert_allclose(pin.computeGeneralizedGravity(after.tree, after.create_data().tree, q_tree),
                               plain_gravity(urdf, q_tree), atol=1e-12)


def test_an_edited_sidecar_is_reloaded(psm_copy):
    before = rk.load_robot(str(psm_copy))
    text = psm_copy.read_text()
    psm_copy.write_text(text + "\n# an edit that changes the bytes only\n")
    assert rk.load_robot(str(psm_copy)) is not before


def test_each_caller_owns_its_data():
    psm = rk.load_robot("psm")
    a, b = psm.create_data(), psm.create_data()
    assert a.tree is not b.tree and a.reduced is not b.reduced
    assert all(x is not y for x, y in zip(a.constraints, b.constraints))
    q1, q2 = [0.1, -0.2, 0.09, 0, 0, 0, 0], [-0.3, 0.25, 0.15, 0, 0, 0, 0]
    fk1 = rk.forward_kinematics(psm, q1, data=a)
    rk.forward_kinematics(psm, q2, data=b)
    # a's workspace still holds q1's placements
    fid = psm.frame_id("tool_tip")
    np.testing.assert_allclose(a.reduced.oMf[fid].translation, fk1.frames["tool_tip"].translation, atol=0)


def test_two_threads_do_not_share_scratch_data():
    psm = rk.load_robot("psm")
    rng = np.random.default_rng(7)
    poses = rng.uniform(psm.lower[:3], psm.upper[:3], size=(400, 3))
    poses = np.column_stack([poses, np.zeros((len(poses), 4))])
    expected = [rk.forward_kinematics(psm, q).frames["tool_tip"].translation for q in poses]
    seen, errors, barrier = {}, [], threading.Barrier(2)

    def work(name, order):
        barrier.wait()
        seen[name] = psm.scratch
        for _ in range(3):
            for i in order:
                got = rk.forward_kinematics(psm, poses[i]).frames["tool_tip"].translation
                if not np.allclose(got, expected[i], atol=1e-12):
                    errors.append((name, i))

    threads = [threading.Thread(target=work, args=(n, o)) for n, o in
               (("a", range(len(poses))), ("b", range(len(poses) - 1, -1, -1)))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert seen["a"] is not seen["b"] and seen["a"].tree is not seen["b"].tree
    assert not errors, f"{len(errors)} poses computed wrong under two threads"


def test_a_workspace_of_another_robot_or_without_its_loops_is_refused():
    psm, mtm = rk.load_robot("psm"), rk.load_robot("mtm")
    q = [0.1, -0.2, 0.09, 0, 0, 0, 0]
    loopless = rk.RobotData(psm.tree.createData(), psm.reduced.createData(), ())
    with pytest.raises(rk.RcmKinError, match="not a workspace of psm"):
        rk.forward_kinematics(psm, q, data=loopless)
    with pytest.raises(rk.RcmKinError, match="not a workspace of psm"):
        rk.forward_kinematics(psm, q, data=mtm.create_data())
    with pytest.raises(rk.RcmKinError, match="data must be this robot's RobotData"):
        rk.gravity_torque(psm, q, data=psm.tree.createData())


def test_the_constrained_gravity_works_in_the_callers_workspace():
    """Loop solve, constraint Jacobian and projection all in the caller's data: the thread's own
    workspace is left as it was."""
    psm = rk.load_robot("psm")
    mine = psm.create_data()
    rk.forward_kinematics(psm, [0.0] * 7)                           # the thread's workspace at q = 0
    before = [m.copy() for m in psm.scratch.tree.oMi]
    q = [0.2, -0.3, 0.1, 0, 0, 0, 0]
    tau = rk.gravity_torque(psm, q, method="constrained", data=mine)
    assert all(np.array_equal(a.homogeneous, b.homogeneous) for a, b in zip(before, psm.scratch.tree.oMi))
    np.testing.assert_allclose(tau, rk.gravity_torque(psm, q, method="reduced"), atol=1e-9)


def test_check_pose_one_pass_agrees_with_the_checks(psm):
    """The one-pass check of a float array (finite and within the limits) refuses what check_q and
    check_limits refuse, and the limits it reads once cannot change under it."""
    inside = (psm.lower + psm.upper) / 2
    assert np.array_equal(psm.check_pose(inside), inside) and psm.check_pose(inside) is not inside
    for bad, error in ((np.nan, RcmKinError), (np.inf, RcmKinError), (psm.upper[1] + 1e-6, JointLimitError)):
        q = inside.copy()
        q[1] = bad
        with pytest.raises(error):
            psm.check_pose(q)
    q = inside.copy()
    q[1] = psm.upper[1] + 0.5e-9                      # within the tolerance, as check_limits takes it
    assert np.array_equal(psm.check_pose(q), psm.check_limits(q))
    with pytest.raises(ValueError):
        psm.lower[0] = 0.0


def test_check_pose_reads_limits_and_size_set_after_its_first_check(psm):
    """The bounds and the pose's size that check_pose keeps are made again when ``lower``,
    ``upper`` or ``description`` is set (a copy of the bundled robot, not the cached one)."""
    robot = dataclasses.replace(psm)
    inside = (psm.lower + psm.upper) / 2
    assert np.array_equal(robot.check_pose(inside), inside)              # the bounds made here
    robot.upper = np.where(np.arange(7) == 1, inside[1] - 0.1, psm.upper)
    with pytest.raises(JointLimitError, match="outside the joint limits: pitch"):
        robot.check_pose(inside)
    robot.upper = psm.upper
    robot.lower = np.where(np.arange(7) == 2, inside[2] + 0.01, psm.lower)
    with pytest.raises(JointLimitError, match="outside the joint limits: insertion"):
        robot.check_pose(inside)
    robot.lower = psm.lower
    assert np.array_equal(robot.check_pose(inside), inside)
    robot.description = dataclasses.replace(psm.description, actuated=psm.description.actuated[:6])
    assert np.array_equal(robot.check_pose(inside[:6]), inside[:6])
    with pytest.raises(RcmKinError, match="takes 6 joint values"):
        robot.check_pose(inside)
    assert np.array_equal(psm.check_pose(inside), inside)                # the bundled robot unchanged

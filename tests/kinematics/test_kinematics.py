"""FK against an independent implementation of the osMDV DH tables; IK round trips; error paths."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from oracles.dh_reference import mtm_frames, psm_frames

from rcm_kin import RcmKinError
from rcm_kin.kinematics.fk import forward_kinematics, frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.psm_ik import shaft_tip_ik, tool_pose_ik, wrist_ik
from rcm_kin.kinematics.teleop import default_teleop_map, psm_targets, teleop_joint_targets

TIP_OFFSET = 0.02349  # m: l_RCM - l_tool, the shaft tip is q3 - 23.49 mm beyond the RCM


def unit_box(n):
    return st.lists(st.floats(0.0, 1.0), min_size=n, max_size=n).map(np.array)


def within(robot, u, margin=0.0):
    """Map the unit box onto the joint ranges, ``margin`` (fraction of the range) inside them."""
    u = margin + (1 - 2 * margin) * u
    return robot.lower + u * (robot.upper - robot.lower)


# IK round trips stay 1 % of the range inside the limits: the corners of the ranges are the
# wrist singularity (wrist pitch +-90 deg: instrument roll and wrist yaw share an axis) and the
# MTM's stretched arm (elbow +90 deg), where only the sum of two joints is defined or
# Gauss-Newton converges linearly. The error paths for targets beyond the limits are below.
IK_MARGIN = 0.01


@given(u=unit_box(7))
@settings(max_examples=200, deadline=None)
def test_psm_fk_matches_dh_table(psm, u):
    q = within(psm, u)
    fk = forward_kinematics(psm, q)
    ref = psm_frames(q)
    np.testing.assert_allclose(fk.frames["shaft_tip"].translation, ref["shaft_tip"][:3, 3], atol=1e-12)
    np.testing.assert_allclose(fk.frames["shaft_tip"].rotation[:, 2], ref["shaft_tip"][:3, 2], atol=1e-12)
    np.testing.assert_allclose(fk.frames["tool_tip"].homogeneous, ref["tool_tip"], atol=1e-12)
    assert fk.closure_residual < 1e-12


@given(u=unit_box(7))
@settings(max_examples=200, deadline=None)
def test_mtm_fk_matches_dh_table(mtm, u):
    q = within(mtm, u)
    fk = forward_kinematics(mtm, q)
    ref = mtm_frames(q)
    np.testing.assert_allclose(fk.frames["wrist_center"].translation, ref["wrist_center"][:3, 3], atol=1e-12)
    np.testing.assert_allclose(fk.frames["tool_tip"].homogeneous, ref["tool_tip"], atol=1e-12)


def test_zero_poses(psm, mtm):
    """At q = 0 the PSM shaft points straight down through the RCM; the MTM tip is at
    (262.5, -217.5, 8.7) mm in its y-up DH frame 0, i.e. (262.5, 8.7, -217.5) mm z up."""
    q = np.zeros(7)
    q[2] = 0.1
    fk = forward_kinematics(psm, q)
    np.testing.assert_allclose(fk.frames["rcm"].translation, 0.0, atol=1e-15)
    np.testing.assert_allclose(fk.frames["shaft_tip"].translation, [0, 0, -(0.1 - TIP_OFFSET)], atol=1e-12)
    np.testing.assert_allclose(fk.frames["shaft_tip"].rotation[:, 2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(forward_kinematics(mtm, np.zeros(7)).frames["wrist_center"].translation,
                               [0.2625, 0.0087, -0.2175], atol=1e-12)


@given(u=unit_box(7))
@settings(max_examples=100, deadline=None)
def test_rcm_is_fixed(psm, u):
    """The shaft line passes through the RCM (the base origin) in every configuration, and
    the whole distal chain (tool tip included) stays on it."""
    fk = forward_kinematics(psm, within(psm, u))
    tip = fk.frames["shaft_tip"]
    np.testing.assert_allclose(fk.frames["rcm"].translation, 0.0, atol=1e-15)
    assert np.linalg.norm(np.cross(tip.translation, tip.rotation[:, 2])) < 1e-12


@given(u=unit_box(3))
@settings(max_examples=200, deadline=None)
def test_shaft_tip_ik_round_trip(psm, u):
    q = np.zeros(7)
    q[:3] = within(psm, np.concatenate([u, np.zeros(4)]))[:3]
    q[2] = max(q[2], TIP_OFFSET + 1e-3)  # tip beyond the RCM: the solution is unique
    target = frame_placement(psm, q, "shaft_tip").translation
    q_ik = shaft_tip_ik(psm, target)
    np.testing.assert_allclose(q_ik, q[:3], atol=1e-9)


def test_shaft_tip_ik_between_rcm_and_interface(psm):
    """Insertion below 23.49 mm puts the tip on the other side of the RCM: still exact."""
    q = np.array([0.1, -0.2, 0.01, 0, 0, 0, 0])
    target = frame_placement(psm, q, "shaft_tip").translation
    np.testing.assert_allclose(shaft_tip_ik(psm, target), q[:3], atol=1e-9)


def test_shaft_tip_ik_is_not_the_thesis_scaling(psm):
    """The thesis firmware's q2 = atan2(x, y)/4 is a motion scaling; the real inverse differs."""
    q = np.array([0.0, np.radians(20), 0.1, 0, 0, 0, 0])
    x, y, z = frame_placement(psm, q, "shaft_tip").translation
    assert shaft_tip_ik(psm, [x, y, z])[1] == pytest.approx(np.radians(20), abs=1e-12)
    assert abs(np.arctan2(abs(x), abs(z)) / 4 - np.radians(20)) > np.radians(10)


@given(u=unit_box(7))
@settings(max_examples=100, deadline=None)
def test_wrist_ik_round_trip(psm, u):
    q = within(psm, u, IK_MARGIN)
    R = frame_placement(psm, q, "tool_tip").rotation
    q_wrist = wrist_ik(psm, q[:3], R)
    q2 = q.copy()
    q2[3:6] = q_wrist
    np.testing.assert_allclose(frame_placement(psm, q2, "tool_tip").rotation, R, atol=1e-9)


@given(u=unit_box(7))
@settings(max_examples=30, deadline=None)
def test_tool_pose_ik_round_trip(psm, u):
    q = within(psm, u, IK_MARGIN)
    q[2] = max(q[2], 0.04)
    M = frame_placement(psm, q, "tool_tip")
    result = tool_pose_ik(psm, M.translation, M.rotation, jaw=q[6])
    reached = frame_placement(psm, result.q, "tool_tip")
    assert np.linalg.norm(reached.translation - M.translation) < 1e-9
    np.testing.assert_allclose(reached.rotation, M.rotation, atol=1e-9)
    assert np.all(result.q >= psm.lower - 1e-12) and np.all(result.q <= psm.upper + 1e-12)


@given(u=unit_box(3))
@settings(max_examples=30, deadline=None)
def test_mtm_wrist_center_ik_round_trip(mtm, u):
    q = np.zeros(7)
    q[:3] = within(mtm, np.concatenate([u, np.zeros(4)]), IK_MARGIN)[:3]
    target = frame_placement(mtm, q, "wrist_center").translation
    result = solve_ik(mtm, "wrist_center", target, joints=("j1", "j2", "j3"))
    assert result.position_error < 1e-9
    assert np.all(result.q >= mtm.lower - 1e-12) and np.all(result.q <= mtm.upper + 1e-12)


def test_mtm_wrist_center_ik_next_to_a_singularity(mtm):
    """j1 and j2 at 1 % of their range from the lower limits: the Jacobian's smallest singular value
    is 4e-6 m/rad, where the fixed damping stalled at about 1e-9 m (found by Hypothesis); the
    adaptive damping from the closest attempt reaches the tolerance."""
    q = np.zeros(7)
    q[:3] = within(mtm, np.array([0.0, 0.0, 0.18062670564077934, 0, 0, 0, 0]), IK_MARGIN)[:3]
    target = frame_placement(mtm, q, "wrist_center").translation
    result = solve_ik(mtm, "wrist_center", target, joints=("j1", "j2", "j3"))
    assert np.linalg.norm(frame_placement(mtm, result.q, "wrist_center").translation - target) < 1e-10
    assert np.all(result.q >= mtm.lower) and np.all(result.q <= mtm.upper)


def test_unreachable_targets_are_errors_not_clamped(psm, mtm):
    with pytest.raises(RcmKinError, match="out of reach: it needs pitch"):
        # 40 deg of pitch at 80 mm: outside the +-30 deg limit
        shaft_tip_ik(psm, 0.0565 * np.array([np.sin(np.radians(40)), 0, -np.cos(np.radians(40))]))
    with pytest.raises(RcmKinError, match="insertion"):
        shaft_tip_ik(psm, [0, 0, -0.5])
    with pytest.raises(RcmKinError, match="no configuration within the joint limits"):
        solve_ik(mtm, "wrist_center", [1.0, 0.0, 0.0], joints=("j1", "j2", "j3"), restarts=2)
    with pytest.raises(RcmKinError, match="3 finite numbers"):
        shaft_tip_ik(psm, [0, np.nan, 0])
    with pytest.raises(RcmKinError, match="rotation matrix"):
        wrist_ik(psm, np.zeros(3), np.ones((3, 3)))
    with pytest.raises(RcmKinError, match="takes 7 joint values"):
        forward_kinematics(psm, np.zeros(8))
    with pytest.raises(RcmKinError, match="no frame 'elbow'"):
        frame_placement(psm, np.zeros(7), "elbow")


def test_teleop_map(psm):
    teleop = default_teleop_map(psm)
    np.testing.assert_allclose(teleop.home, [0, 0, -(0.080 - TIP_OFFSET)], atol=1e-12)
    d = np.array([[0.0, 0.0, 0.0], [0.1, -0.04, 0.02]])
    np.testing.assert_allclose(psm_targets(teleop, d)[1] - teleop.home, [0.005, -0.002, 0.005], atol=1e-15)
    q = teleop_joint_targets(psm, teleop, d)
    np.testing.assert_allclose(q[0], [0, 0, 0.080], atol=1e-12)
    for k in range(2):
        full = np.concatenate([q[k], np.zeros(4)])
        np.testing.assert_allclose(frame_placement(psm, full, "shaft_tip").translation,
                                   psm_targets(teleop, d[k]), atol=1e-12)
    with pytest.raises(RcmKinError, match="MTM sample 0"):
        teleop_joint_targets(psm, teleop, [[5.0, 0, 0]])


def test_clamped_shaft_tip_ik_is_the_ik_within_reach_and_clips_beyond_it(psm):
    import pinocchio as pin

    from rcm_kin.kinematics.psm_ik import ARM, clamped_shaft_tip_ik, shaft_tip_ik

    index = [psm.actuated.index(j) for j in ARM]
    inside = frame_placement(psm, psm.check_q([0.2, -0.3, 0.1], allow_short=True), "shaft_tip").translation
    q, clamped = clamped_shaft_tip_ik(psm, inside)
    np.testing.assert_array_equal(q, shaft_tip_ik(psm, inside))
    assert not clamped
    # 60 deg of roll is beyond its 30 deg limit: the roll clips to it, pitch and insertion are the line's
    beyond = frame_placement(psm, psm.check_q([0.0, 0.0, 0.1], allow_short=True), "shaft_tip").translation
    rcm = frame_placement(psm, np.zeros(psm.nq), "rcm").translation
    turned = rcm + pin.utils.rotate("x", np.radians(60)) @ (beyond - rcm)     # about the roll axis (x)
    q, clamped = clamped_shaft_tip_ik(psm, turned)
    assert clamped
    assert np.all(q >= psm.lower[index]) and np.all(q <= psm.upper[index])
    assert abs(abs(q[0]) - np.radians(30)) < 1e-12 and abs(q[1]) < 1e-9 and abs(q[2] - 0.1) < 1e-9


def test_forward_kinematics_is_the_plain_pinocchio_calls(psm):
    """The thin path (frame ids looked up once, the float array taken as it is) gives what
    ``pin.forwardKinematics`` + ``updateFramePlacement`` give; the caller's array is copied, not kept."""
    import pinocchio as pin

    q = np.array([0.2, -0.3, 0.1, 0.4, 0.3, -0.2, 0.5])
    fk = forward_kinematics(psm, q)
    model = psm.reduced
    data = model.createData()
    q_reduced = np.zeros(model.nq)
    q_reduced[psm.reduced_q_actuated] = q
    pin.forwardKinematics(model, data, q_reduced)
    for name, placement in fk.frames.items():
        expected = pin.updateFramePlacement(model, data, model.getFrameId(name))
        assert placement.isApprox(expected, 0.0)
    assert fk.q is not q and np.array_equal(fk.q, q)
    q[0] = 0.25
    assert fk.q[0] == 0.2
    assert list(forward_kinematics(psm, q, ["tool_tip", "rcm"]).frames) == ["tool_tip", "rcm"]


@pytest.mark.parametrize("q", [np.array([np.nan, 0, 0, 0, 0, 0, 0.0]), np.array([np.inf, -np.inf, 0, 0, 0, 0, 0.0]),
                               np.zeros(6), np.zeros(7, dtype=np.float32) + np.float32(np.nan)])
def test_forward_kinematics_refuses_what_the_fast_path_does_not_take(psm, q):
    with pytest.raises(RcmKinError, match="finite|takes 7"):
        forward_kinematics(psm, q)


def test_an_unknown_frame_is_an_error_every_time(psm):
    for _ in range(2):
        with pytest.raises(RcmKinError, match="no frame 'nowhere'"):
            forward_kinematics(psm, np.zeros(7), ("tool_tip", "nowhere"))

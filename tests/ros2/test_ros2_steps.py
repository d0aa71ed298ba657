"""The per-message maths without rclpy: message fields, the teleoperation step's clutch, the gravity
step; expected values from the library's offline functions."""

from __future__ import annotations

import numpy as np
import pytest

from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.teleop import default_teleop_map, teleop_joint_targets
from rcm_kin.ros2.gravity import GravityStep
from rcm_kin.ros2.messages import MalformedMessage, Tally, joint_values
from rcm_kin.ros2.teleop import TeleopStep
from rcm_kin.statics.maps import holding_effort


@pytest.mark.parametrize("names, values, reason", [
    (["a", "b"], [1.0, 2.0], "joint 'c' missing"),
    (["a", "b", "c", "c"], [1, 2, 3, 4], "joint 'c' named twice"),
    (["a", "b", "c"], [1.0, 2.0], "2 values for 3 joint names"),
    (["a", "b", "c"], [1.0, np.inf, 2.0], "non-finite position of b"),
])
def test_malformed_fields_say_why(names, values, reason):
    with pytest.raises(MalformedMessage, match=reason):
        joint_values(names, values, ("a", "b", "c"))


def test_joint_values_pick_by_name():
    np.testing.assert_array_equal(joint_values(["c", "x", "a", "b"], [3, 9, 1, 2], ("a", "b", "c")), [1, 2, 3])


def test_tally_counts_reasons_and_latency():
    tally = Tally()
    tally.bad("joint 'c' missing (names: a, b)")
    tally.bad("joint 'c' missing (names: x)")
    for s in (1e-4, 2e-4, 3e-4):
        tally.latency(s)
    summary = tally.summary()
    assert summary["malformed_reasons"] == {"joint 'c' missing": 2}
    assert summary["latency_median_s"] == pytest.approx(2e-4)


def _displacement(mtm, q):
    zero = frame_placement(mtm, np.zeros(mtm.nq), "wrist_center").translation
    return frame_placement(mtm, np.r_[q, np.zeros(mtm.nq - 3)], "wrist_center").translation - zero


def test_teleop_step_and_its_clutch(mtm, psm):
    step, teleop = TeleopStep(mtm, psm), default_teleop_map(psm)
    q = np.radians([[0, 0, 0], [10, 5, -5], [20, 10, -10], [25, 12, -8]])
    first = step(q[1])
    np.testing.assert_allclose(first.joints, teleop_joint_targets(psm, teleop, _displacement(mtm, q[1]))[0], atol=1e-12)
    step.clutch(True)                       # the MTM moves, the PSM target stays
    held = step(q[2])
    np.testing.assert_allclose(held.target, first.target, atol=1e-12)
    step.clutch(False)                      # taken up: later motion adds to where the PSM is
    moved = step(q[3])
    expected = first.target + (_displacement(mtm, q[3]) - _displacement(mtm, q[2])) * teleop.scale
    np.testing.assert_allclose(moved.target, expected, atol=1e-12)
    assert not (first.clamped or held.clamped or moved.clamped)


def test_gravity_step_is_the_holding_effort(psm):
    step = GravityStep(psm)
    for q in ([0.1, -0.2, 0.08], [-0.45, 0.5, 0.14]):
        out = step(np.array(q))
        effort = holding_effort(psm, psm.check_q(q, allow_short=True))
        np.testing.assert_allclose(out.pwm, effort.drive.pwm, rtol=0, atol=1e-9)
        np.testing.assert_allclose(out.tau, effort.tau[:3], rtol=0, atol=1e-9)
    with pytest.raises(MalformedMessage, match="outside the joint limits"):
        step(np.array([0.0, np.radians(-35.07), 0.08]))      # the pitch resting on its stop


@pytest.mark.parametrize("command", ["teleop", "gravity", "record-check", "view"])
def test_every_node_has_help_with_units_and_an_example(command, capsys):
    from rcm_kin.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["ros2", command, "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert stop.value.code == 0
    assert "example" in text and "deg" in text and f"rcm-kin ros2 {command}" in text

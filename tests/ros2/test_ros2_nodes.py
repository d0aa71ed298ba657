"""The nodes' failures: malformed messages counted and survived, a clean SIGTERM, the one-line
errors without the extra or without a DDS transport, and the loopback-only profile."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from ros2_graph import as_array, played

from rcm_kin.identification.telemetry import load_telemetry

MTM_NAMES = ["j1", "j2", "j3"]


def test_malformed_messages_are_counted_and_the_node_survives(graph, node_process):
    node = node_process("teleop", "--json", "--depth", "2000", "--warn-period", "0.5")
    mtm = graph.publisher("mtm_joint_states")
    answers = graph.collect("psm_joint_targets")
    graph.wait_matched([mtm], ["psm_joint_targets"])
    graph.handshake(mtm, graph.message(MTM_NAMES, [0, 0, 0], probe=True), answers)
    good = [graph.message(MTM_NAMES, [5.0 * k, 2.0, -3.0], k=k) for k in range(4)]
    bad = [graph.message(["j1", "j2", "jx"], [1, 2, 3], k=100),          # a joint missing
           graph.message(MTM_NAMES, [1, float("nan"), 3], k=101),         # not finite
           graph.message(MTM_NAMES, [1, 2], k=102),                       # a field shorter than the names
           graph.message(MTM_NAMES, [], k=103),                           # no positions at all
           graph.message(["j1", "j1", "j2", "j3"], [1, 1, 2, 3], k=104),  # a joint named twice
           graph.message(MTM_NAMES, [1e300, 2, 3], k=105)]                # finite: clamped and answered
    messages = [m for pair in zip(good, bad) for m in pair] + good[len(bad):] + bad[len(good):]
    graph.play(mtm, messages, rate=100.0)
    assert graph.spin_until(lambda: len(played(good, answers)) >= len(good), 10.0)
    graph.spin_until(lambda: False, 0.3)
    status, seconds = node.stop()
    assert status == 0 and seconds < 2.0
    assert len(played(messages, answers)) == len(good) + 1          # nothing for a malformed message
    tally = json.loads(node.output()[0])
    assert tally["malformed"] == len(bad) - 1 and tally["received"] == tally["published"] + tally["malformed"]
    assert tally["clamped"] == 1
    q = as_array(played(messages, answers))
    assert np.all(np.isfinite(q)) and np.all(np.abs(q[:, :2]) <= 30.0)
    assert np.all((q[:, 2] >= 0) & (q[:, 2] <= 160.0))
    assert "left out" in node.output()[1]                            # warned (at most every 0.5 s)


@pytest.mark.parametrize("command", ["teleop", "gravity"])
def test_sigterm_ends_each_node_within_two_seconds(node_process, graph, command):
    node = node_process(command, "--json")
    assert graph.spin_until(lambda: "ready" in node.output()[1], 60.0), node.output()
    status, seconds = node.stop()
    assert status == 0 and seconds < 2.0, node.output()


def test_record_check_reads_a_live_topic_into_the_telemetry_log_of_the_csv_reader(graph, node_process, tmp_path):
    out = tmp_path / "capture.csv"
    node = node_process("record-check", "--json", "--depth", "2000", "--out", str(out))
    source = graph.publisher("/psm_joint_telemetry")
    graph.wait_matched([source], [])
    graph.spin_until(lambda: "ready" in node.output()[1], 60.0)
    graph.spin_until(lambda: False, 1.0)                      # discovery in both directions
    rows = np.column_stack([np.linspace(-10, 10, 40), np.linspace(5, -5, 40), np.full(40, 80.0)])
    pwm = np.column_stack([np.linspace(-30, 30, 40), np.full(40, 12.0), np.zeros(40)])
    messages = [graph.message(["roll", "pitch", "insertion"], r, u, r, k=k) for k, (r, u) in enumerate(zip(rows, pwm))]
    graph.play(source, messages, rate=200.0)
    graph.spin_until(lambda: False, 0.5)
    status, seconds = node.stop()
    assert status == 0 and seconds < 2.0, node.output()
    summary = json.loads(node.output()[0])
    assert summary["samples"] == len(messages) and summary["joints"] == ["insertion", "pitch", "roll"]
    log = load_telemetry(out)                                  # the CSV reader reads the capture back
    np.testing.assert_allclose(log.time, np.arange(len(messages)) * 1e-3, atol=1e-9)   # the stamps, from 0
    np.testing.assert_array_equal(log.position["roll"], rows[:, 0])
    np.testing.assert_array_equal(log.pwm["roll"], pwm[:, 0])
    np.testing.assert_array_equal(log.setpoint["pitch"], rows[:, 1])


def test_a_missing_extra_is_one_line_naming_it():
    code = ("import sys; sys.modules['rclpy'] = None; from rcm_kin.cli import main; "
            "sys.exit(main(['ros2', 'gravity', '--duration', '1']))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    expected = "error: the ROS 2 nodes need the ros2 extra: pip install 'rcm-kin[ros2]'"
    assert run.stderr.strip().splitlines() == [expected]


def test_no_dds_transport_is_one_line(ros_env):
    env = {**os.environ, "RMW_IMPLEMENTATION": "rmw_no_such_transport_cpp"}
    run = subprocess.run([sys.executable, "-m", "rcm_kin.cli", "ros2", "gravity", "--duration", "1"],
                         capture_output=True, text=True, timeout=120, env=env)
    lines = [line for line in run.stderr.splitlines() if line.startswith("error:")]
    assert run.returncode == 2 and len(lines) == 1 and "no DDS transport" in lines[0], run.stderr


def test_the_test_profile_keeps_traffic_on_loopback(ros_env):
    root = ET.parse(ros_env["FASTDDS_DEFAULT_PROFILES_FILE"]).getroot()
    ns = {"d": "http://www.eprosima.com"}
    descriptors = root.findall(".//d:transport_descriptor", ns)
    assert [d.findtext("d:type", namespaces=ns) for d in descriptors] == ["UDPv4"]
    assert [a.text for a in root.findall(".//d:interfaceWhiteList/d:address", ns)] == ["127.0.0.1"]
    assert root.findtext(".//d:useBuiltinTransports", namespaces=ns) == "false"
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_view_draws_both_robots_from_their_topics(graph, node_process):
    node = node_process("view", "--json", "--depth", "2000", "--rate", "20")
    mtm, psm = graph.publisher("mtm_joint_states"), graph.publisher("/psm_joint_telemetry")
    graph.wait_matched([mtm, psm], [])
    assert graph.spin_until(lambda: "ready" in node.output()[1], 60.0), node.output()
    graph.spin_until(lambda: False, 1.0)                      # discovery in both directions
    messages = 0
    for k in range(20):
        mtm.publish(graph.message(["j1", "j2", "j3", "g0"], [k, -k, 2 * k, 10], k=k))
        psm.publish(graph.message(["roll", "pitch", "insertion"], [k, -k, 333.4], k=k))
        messages += 2                                             # a burst: far faster than 20 redraws a second
    psm.publish(graph.message(["a", "b"], [1, 2], k=99))        # not the PSM's joints
    graph.spin_until(lambda: False, 0.5)
    status, seconds = node.stop()
    assert status == 0 and seconds < 2.0, node.output()
    tally = json.loads(node.output()[0])
    assert tally["received"] == messages + 1 and tally["malformed"] == 1
    assert 1 <= tally["published"] <= 10                            # redrawn at most 20 times a second, not per message
    assert "http://" in node.output()[1]                              # the meshcat URL, on stderr


def test_a_ros_parameter_wins_over_the_option(ros_env):
    run = subprocess.run([sys.executable, "-m", "rcm_kin.cli", "ros2", "gravity", "--depth", "5", "--duration", "1",
                          "--ros-args", "-p", "depth:=0"], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and run.stderr.strip().splitlines()[-1] == \
        "error: QoS depth is at least 1 message, got 0"

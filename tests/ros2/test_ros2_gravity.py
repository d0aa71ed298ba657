"""``rcm-kin ros2 gravity`` as a process: a played telemetry log answered with the holding PWM that
``rcm-kin gravity`` gives at each measured pose."""

from __future__ import annotations

import json

import numpy as np
from ros2_graph import as_array, played

from rcm_kin.cli import main

DEEP = ("--depth", "2000")
JOINTS = ["roll", "pitch", "insertion"]


def telemetry(graph, n: int = 60):
    """A slow roll-pitch sweep in the telemetry's format: position deg (the insertion field carries
    a value the node must not read), velocity a PWM, effort a setpoint."""
    t = np.linspace(0, 1, n)
    roll, pitch = 25 * np.sin(2 * np.pi * t), -20 + 40 * t
    return [graph.message(JOINTS, [r, p, 333.4], [-12.0, 40.0, 0.0], [r, p, 0.0], k=k)
            for k, (r, p) in enumerate(zip(roll, pitch))], np.column_stack([roll, pitch])


def offline_gravity(capsys, roll: float, pitch: float, insertion: float) -> dict:
    pose = [repr(float(x)) for x in (roll, pitch, insertion)]
    assert main(["gravity", "psm", *pose, "--deg", "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_gravity_answers_each_pose_with_the_holding_pwm_of_rcm_kin_gravity(graph, node_process, capsys):
    node = node_process("gravity", "--json", *DEEP, "--insertion", "0.1")
    source = graph.publisher("/psm_joint_telemetry")
    answers = graph.collect("psm_holding_effort")
    graph.wait_matched([source], ["psm_holding_effort"])
    graph.handshake(source, graph.message(JOINTS, [0, 0, 0], [0, 0, 0], [0, 0, 0], probe=True), answers)
    messages, poses = telemetry(graph)
    graph.play(source, messages, rate=400.0)
    assert graph.spin_until(lambda: len(played(messages, answers)) >= len(messages), 10.0), node.output()
    graph.spin_until(lambda: False, 0.2)
    status, seconds = node.stop()
    assert status == 0 and seconds < 2.0
    answers = played(messages, answers)
    assert len(answers) == len(messages)
    assert all(list(a.name) == JOINTS and a.header.frame_id == "psm_drive.toml" for a in answers)
    expected = [offline_gravity(capsys, r, p, 0.1) for r, p in poses]
    np.testing.assert_allclose(as_array(answers, "velocity"), [e["pwm"] for e in expected], rtol=0, atol=1e-9)
    np.testing.assert_allclose(as_array(answers, "effort"), [e["tau"][:3] for e in expected], rtol=0, atol=1e-9)
    np.testing.assert_allclose(as_array(answers), [e["q"][:3] for e in expected], rtol=0, atol=1e-12)


def test_gravity_crtk_reads_the_insertion_in_si(graph, node_process, capsys):
    node = node_process("gravity", "--json", *DEEP, "--convention", "crtk")
    source = graph.publisher("/PSM1/measured_js")
    answers = graph.collect("/PSM1/servo_jf")
    graph.wait_matched([source], ["/PSM1/servo_jf"])
    graph.handshake(source, graph.message(JOINTS, [0, 0, 0.08], probe=True), answers)
    q = [(0.2, -0.3, 0.05), (-0.4, 0.1, 0.12)]
    messages = [graph.message(JOINTS, row, k=k) for k, row in enumerate(q)]
    graph.play(source, messages, rate=50.0)
    assert graph.spin_until(lambda: len(played(messages, answers)) >= len(messages), 10.0)
    assert node.stop()[0] == 0
    expected = [offline_gravity(capsys, *np.degrees(row[:2]), row[2]) for row in q]
    np.testing.assert_allclose(as_array(played(messages, answers), "velocity"), [e["pwm"] for e in expected],
                               rtol=0, atol=1e-9)

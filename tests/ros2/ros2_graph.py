"""The ROS 2 tests' side of the graph: a test-process rclpy node (publishers, collecting
subscriptions, paced playback, a handshake), the node processes under test, and small helpers.
(A module of its own, not conftest.py: ``from conftest import`` would find another folder's.)"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

START_TIMEOUT = 60.0     # s: a node process up and matched (imports, models, a first C compile, discovery)
STOP_TIMEOUT = 2.0       # s: SIGTERM to exit, the bound


class Graph:
    """A test-side rclpy node: publishers, collecting subscriptions, paced playback."""

    def __init__(self):
        import rclpy
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        self.rclpy, self.JointState = rclpy, JointState
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(f"rcm_kin_test_{os.getpid()}", context=self.context)
        from rclpy.executors import SingleThreadedExecutor

        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.qos = QoSProfile(depth=2000, reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)
        self.received: dict[str, list] = {}

    def publisher(self, topic: str):
        return self.node.create_publisher(self.JointState, topic, self.qos)

    def collect(self, topic: str) -> list:
        got = self.received.setdefault(topic, [])
        self.node.create_subscription(self.JointState, topic, got.append, self.qos)
        return got

    def spin_until(self, done, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if done():
                return True
            self.executor.spin_once(timeout_sec=0.005)
        return bool(done())

    def wait_matched(self, publishers, subscribed_topics, timeout: float = START_TIMEOUT) -> None:
        """Every publisher has a subscriber and every topic collected has a publisher."""
        ok = self.spin_until(lambda: all(p.get_subscription_count() > 0 for p in publishers)
                             and all(self.node.count_publishers(t) > 0 for t in subscribed_topics), timeout)
        assert ok, "the node process did not join the graph in time"

    def handshake(self, publisher, probe, answers: list, timeout: float = START_TIMEOUT) -> None:
        """Publish ``probe`` every 50 ms until the node has answered one: discovery is then complete in
        both directions (a reader that has not yet matched the writer drops what it sends). The
        probe's answers carry its stamp (second 1), which the tests leave out."""
        end = time.monotonic() + timeout
        while not answers and time.monotonic() < end:
            publisher.publish(probe)
            self.spin_until(lambda: bool(answers), 0.05)
        assert answers, "the node process did not answer in time"
        self.spin_until(lambda: False, 0.2)      # the probes still in flight

    def message(self, names, position=(), velocity=(), effort=(), k: int = 0, probe: bool = False):
        msg = self.JointState()
        msg.header.stamp.sec, msg.header.stamp.nanosec = (1, 0) if probe else (1000 + k // 1000, (k % 1000) * 1_000_000)
        msg.name = list(names)
        msg.position, msg.velocity, msg.effort = ([float(x) for x in v] for v in (position, velocity, effort))
        return msg

    def play(self, publisher, messages, rate: float = 200.0) -> None:
        period, start = 1.0 / rate, time.monotonic()
        for k, msg in enumerate(messages):
            publisher.publish(msg)
            self.spin_until(lambda: time.monotonic() >= start + (k + 1) * period, 1.0)

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)


def stamp_key(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def played(messages, answers) -> list:
    """The answers to ``messages`` (by stamp), in arrival order: the probes' left out."""
    keys = {stamp_key(m) for m in messages}
    return [a for a in answers if stamp_key(a) in keys]


class NodeProcess:
    """``rcm-kin ros2 <args>`` as a subprocess; stopped by SIGTERM, killed at teardown if it hangs."""

    def __init__(self, args: list[str], tmp_path: Path):
        self.out, self.err = tmp_path / "node.out", tmp_path / "node.err"
        with self.out.open("w") as out, self.err.open("w") as err:
            self.process = subprocess.Popen([sys.executable, "-m", "rcm_kin.cli", "ros2", *args], stdout=out,
                                            stderr=err, env=os.environ.copy())

    def stop(self, timeout: float = STOP_TIMEOUT) -> tuple[int, float]:
        """SIGTERM; (exit status, seconds it took)."""
        start = time.monotonic()
        self.process.send_signal(signal.SIGTERM)
        status = self.process.wait(timeout=timeout)
        return status, time.monotonic() - start

    def output(self) -> tuple[str, str]:
        return self.out.read_text(), self.err.read_text()

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(timeout=10)


def as_array(messages, field: str = "position") -> np.ndarray:
    return np.array([list(getattr(m, field)) for m in messages])

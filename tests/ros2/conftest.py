"""The ROS 2 tests' graph: loopback only, a domain of their own, real node processes.

The session writes a FastDDS profile (:data:`rcm_kin.ros2.nodes.LOOPBACK_PROFILE`: one UDPv4
transport allowed on 127.0.0.1 alone, the builtin transports off; its content is checked in
test_ros2_nodes.py) and points ``FASTDDS_DEFAULT_PROFILES_FILE`` at it, with
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a random ``ROS_DOMAIN_ID``: no test traffic leaves
127.0.0.1 and two sessions on one machine do not hear each other. The node processes are
``python -m rcm_kin.cli ros2 ...`` subprocesses, so signals reach them as they would on the robot.
Every wait has a timeout.
"""

from __future__ import annotations

import os
import random

import pytest
from ros2_graph import Graph, NodeProcess


@pytest.fixture(scope="session")
def ros_env(tmp_path_factory, compiled_cache):
    """rclpy (else skip with the reason), and the loopback-only environment for this process and
    the node processes it starts."""
    pytest.importorskip("rclpy", reason="the ros2 extra is not installed (pip install 'rcm-kin[ros2]')")
    pytest.importorskip("sensor_msgs.msg", reason="the ros2 extra is not installed (pip install 'rcm-kin[ros2]')")
    from rcm_kin.ros2.nodes import loopback_environment

    env = loopback_environment(tmp_path_factory.mktemp("ros2"), random.SystemRandom().randint(1, 100))
    os.environ.pop("FASTRTPS_DEFAULT_PROFILES_FILE", None)
    os.environ.update(env)
    return env


@pytest.fixture
def graph(ros_env):
    g = Graph()
    yield g
    g.close()


@pytest.fixture
def node_process(ros_env, tmp_path):
    started = []

    def start(*args: str) -> NodeProcess:
        folder = tmp_path / f"node{len(started)}"
        folder.mkdir()
        node = NodeProcess(list(args), folder)
        started.append(node)
        return node

    yield start
    for node in started:
        node.kill()



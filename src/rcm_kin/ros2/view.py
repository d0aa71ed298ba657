"""``ros2 view``: a live meshcat view of the MTM and the PSM, each placed by its joint-state topic.

The latest pose of each robot is kept by its subscription and drawn by a timer at most ``rate`` times
a second (a meshcat update costs about a millisecond a body: drawing every message at 400-1000 Hz
would fall behind). The MTM joints present in a message move (the others stay where they were); the
PSM is placed by roll and pitch (and, in the CRTK convention, insertion; the firmware convention
holds the insertion at ``insertion``, as the gravity node does). The robots stand ``spacing`` m apart.
"""

from __future__ import annotations

import time

import numpy as np

from rcm_kin.kinematics.psm_ik import ARM
from rcm_kin.model import load_robot
from rcm_kin.ros2.messages import MalformedMessage, joint_values, units_of
from rcm_kin.ros2.nodes import NodeOptions, RosNode
from rcm_kin.visualization.views import robot_view, show


class _Robot:
    """One robot's view and its latest pose (rad, m), and which joints a message may move."""

    def __init__(self, name: str, window, convention: str, offset: float):
        self.robot = load_robot(name)
        self.view = robot_view(self.robot, window=window)
        self.view.viewer[self.robot.name].set_transform(_translation(offset))
        self.q = np.zeros(self.robot.nq)
        self.factors = units_of(convention).factors([self.robot.joint_kind(j) for j in self.robot.actuated])
        self.changed = True

    def take(self, names, values, wanted=None) -> None:
        wanted = wanted or tuple(j for j in self.robot.actuated if j in names)
        if not wanted:
            raise MalformedMessage(f"no joint of the {self.robot.name} named (names: {', '.join(names[:8]) or 'none'})")
        index = [self.robot.actuated.index(j) for j in wanted]
        q = self.q.copy()
        q[index] = joint_values(names, values, wanted) * self.factors[index]
        self.q = np.clip(q, self.robot.lower, self.robot.upper)
        self.changed = True

    def draw(self) -> bool:
        if self.changed:
            show(self.view, self.robot, self.q)
            self.changed = False
            return True
        return False


def _translation(y: float) -> np.ndarray:
    transform = np.eye(4)
    transform[1, 3] = y
    return transform


def run_view(window, options: NodeOptions = NodeOptions(), ros_args: list[str] | None = None,
             psm_topic: str = "", rate: float = 30.0, spacing: float = 0.6) -> dict:
    """Both robots in meshcat ``window`` (e.g. ``meshcat.Visualizer().window``), the MTM placed by
    ``input_topic`` (default the convention's MTM joint states) and the PSM by ``psm_topic`` (default
    its telemetry or ``measured_js``), redrawn at most ``rate`` Hz. Runs until stopped; the tally
    (``published``: redraws)."""
    with RosNode("view", options, ros_args) as ros:
        return _view(ros, window, psm_topic, rate, spacing)


def _view(ros: RosNode, window, psm_topic: str, rate: float, spacing: float) -> dict:
    opt = ros.options
    mtm = _Robot("mtm", window, opt.convention, -spacing / 2)
    psm = _Robot("psm", window, opt.convention, spacing / 2)
    psm.q[psm.robot.actuated.index("insertion")] = opt.insertion
    crtk = opt.convention == "crtk"
    psm_joints = ARM if crtk else ARM[:2]

    def take_mtm(msg) -> bool:
        mtm.take(list(msg.name), msg.position)
        return False

    def take_psm(msg) -> bool:
        psm.take(list(msg.name), msg.position, psm_joints)
        return False

    def redraw() -> None:
        start = time.perf_counter()
        drawn = mtm.draw() | psm.draw()
        if drawn:
            ros.tally.published += 1
            ros.tally.latency(time.perf_counter() - start)

    ros.node.create_subscription(ros.JointState, opt.topic(opt.input_topic, "mtm"), ros.guarded(take_mtm), ros.qos)
    ros.node.create_subscription(ros.JointState, opt.topic(psm_topic, "telemetry"), ros.guarded(take_psm), ros.qos)
    ros.node.create_timer(1.0 / rate, redraw)
    return ros.spin()

"""The rclpy plumbing of the nodes: QoS, topics, ROS parameters, the spin loop and a clean stop.

Each node builds its models first (:class:`~rcm_kin.ros2.teleop.TeleopStep`,
:class:`~rcm_kin.ros2.gravity.GravityStep`), then subscribes; a callback converts the message
(:mod:`rcm_kin.ros2.messages`), calls the step and publishes, or counts the message as malformed
(a warning at most every ``warn_period`` s) and publishes nothing. No exception leaves a callback.
SIGINT and SIGTERM end the spin loop within one ``SPIN_PERIOD``; the node is destroyed and the
context shut down before the function returns its :class:`~rcm_kin.ros2.messages.Tally` summary.

rclpy is imported when a node starts: the ``ros2`` extra (``pip install 'rcm-kin[ros2]'``).
Every option is also a ROS parameter of the node (``--ros-args -p depth:=15``), which wins.
"""

from __future__ import annotations

import importlib.util
import os
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from pathlib import Path

import numpy as np

from rcm_kin.atomic import write_text
from rcm_kin.errors import RcmKinError, warn
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.identification.rosbag import FIELDS, message_columns
from rcm_kin.identification.telemetry import JOINTS, MAX_LOG_ROWS, TelemetryLog, telemetry_log
from rcm_kin.kinematics.psm_ik import ARM
from rcm_kin.kinematics.teleop import TeleopMap, default_teleop_map
from rcm_kin.model import load_robot
from rcm_kin.ros2.gravity import GravityStep
from rcm_kin.ros2.messages import MalformedMessage, Tally, joint_values, units_of
from rcm_kin.ros2.teleop import TeleopStep

EXTRA = "pip install 'rcm-kin[ros2]'"
SPIN_PERIOD = 0.05          # s: the longest a stop signal waits for the spin loop
# the robot's topics (firmware convention) and the dVRK's (CRTK), per node role
TOPICS = {
    "firmware": {"mtm": "mtm_joint_states", "target": "target_pose", "joints": "psm_joint_targets",
                 "telemetry": "/psm_joint_telemetry", "effort": "psm_holding_effort"},
    "crtk": {"mtm": "/MTMR/measured_js", "target": "target_pose", "joints": "/PSM1/servo_jp",
             "telemetry": "/PSM1/measured_js", "effort": "/PSM1/servo_jf"},
}


# a FastDDS profile keeping every participant of the processes that name it on 127.0.0.1: one UDPv4
# transport allowed on the loopback interface alone, the builtin transports (UDP on every interface,
# shared memory) off; with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST discovery stays on the host too
LOOPBACK_PROFILE = """<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>loopback_udp</transport_id>
        <type>UDPv4</type>
        <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="rcm_kin_loopback" is_default_profile="true">
      <rtps>
        <userTransports><transport_id>loopback_udp</transport_id></userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def loopback_environment(folder: str | Path, domain: int) -> dict[str, str]:
    """Write :data:`LOOPBACK_PROFILE` into ``folder``; the environment variables that make a process's
    ROS 2 traffic stay on 127.0.0.1 in ``domain`` (FastDDS, logs in ``folder``)."""
    folder = Path(folder)
    profile = write_text(folder / "fastdds_loopback.xml", LOOPBACK_PROFILE)
    return {"FASTDDS_DEFAULT_PROFILES_FILE": str(profile), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
            "ROS_DOMAIN_ID": str(int(domain)), "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
            "ROS_LOG_DIR": str(folder / "log")}


@dataclass(frozen=True)
class NodeOptions:
    """A node's settings; each is also its ROS parameter of the same name. Topics left empty take
    the convention's (:data:`TOPICS`). QoS defaults are the robot's: reliable, volatile, depth 20."""

    convention: str = "firmware"     # firmware (deg, mm; PWM counts) or crtk (rad, m)
    depth: int = 20
    reliability: str = "reliable"    # reliable or best_effort
    durability: str = "volatile"     # volatile or transient_local
    input_topic: str = ""
    output_topic: str = ""           # teleop: the joint targets; gravity: the holding effort
    target_topic: str = ""           # teleop: the Cartesian target (firmware target_pose format)
    warn_period: float = 1.0         # s between two warnings of malformed messages
    duration: float = 0.0            # s to run, 0: until SIGINT/SIGTERM
    insertion: float = HOME_INSERTION   # m: gravity's insertion when the message's is not used (firmware)
    scale: tuple[float, float, float] = (0.05, 0.05, 0.25)   # teleop map scale per PSM base axis
    drive: str = ""                  # gravity: drive parameter file (default the PSM's)
    clutch_topic: str = ""           # teleop: std_msgs/Bool, true while the clutch is pressed ("": no clutch)
    name: str = ""                   # node name (default rcm_kin_<role>)

    def topic(self, given: str, role: str) -> str:
        return given or TOPICS[self.convention][role]


def _check_rmw() -> None:
    """The middleware ``RMW_IMPLEMENTATION`` asks for is installed, else a one-line error (rcl would
    end the process with status 102 when it loads). Checked where the middlewares are Python-visible
    folders (the ROS 2 wheels); a ROS distribution's own install is left to rcl."""
    requested = os.environ.get("RMW_IMPLEMENTATION", "")
    if requested and _findable("rmw_fastrtps_cpp") and not _findable(requested):
        raise RcmKinError(f"no DDS transport: RMW_IMPLEMENTATION={requested} is not installed (the ros2 extra "
                          f"brings rmw_fastrtps_cpp: {EXTRA})", parameter="RMW_IMPLEMENTATION")


def _findable(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def _ros():
    """rclpy and the JointState type, or a one-line error naming the extra / the middleware."""
    _check_rmw()
    try:
        import rclpy
        from sensor_msgs.msg import JointState
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] in ("rclpy", "sensor_msgs"):
            raise RcmKinError(f"the ROS 2 nodes need the ros2 extra: {EXTRA}") from None
        raise RcmKinError(f"ROS 2 is installed but does not load ({exc}): reinstall with {EXTRA}") from None
    except ImportError as exc:
        raise RcmKinError(f"ROS 2 is installed but does not load ({str(exc).splitlines()[0]}): no DDS "
                          f"transport (the ros-rmw-fastrtps-cpp wheel); reinstall with {EXTRA}") from None
    return rclpy, JointState


def _qos(options: NodeOptions):
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    if options.reliability not in ("reliable", "best_effort") or options.durability not in ("volatile",
                                                                                           "transient_local"):
        raise RcmKinError("QoS: reliability is reliable or best_effort, durability volatile or transient_local",
                          parameter="reliability")
    if options.depth < 1:
        raise RcmKinError(f"QoS depth is at least 1 message, got {options.depth}", parameter="depth")
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=int(options.depth),
                      reliability=getattr(ReliabilityPolicy, options.reliability.upper()),
                      durability=getattr(DurabilityPolicy, options.durability.upper()))


def _with_parameters(node, options: NodeOptions) -> NodeOptions:
    """Declare every option as a ROS parameter (the option its default) and read them back."""
    values = {}
    for f in fields(NodeOptions):
        default = getattr(options, f.name)
        value = node.declare_parameter(f.name, list(default) if isinstance(default, tuple) else default).value
        values[f.name] = tuple(float(v) for v in value) if isinstance(default, tuple) else value
    return replace(options, **values)


def make_executor(context):
    """rclpy's events executor (its loop in C++: a third of the per-message cost of the Python
    executor) where this rclpy has it, else the single-threaded executor."""
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:
        from rclpy.executors import SingleThreadedExecutor

        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


class RosNode:
    """One rclpy context and node, stopped cleanly by SIGINT/SIGTERM or after ``duration``."""

    def __init__(self, role: str, options: NodeOptions, ros_args: list[str] | None = None):
        self.rclpy, self.JointState = _ros()
        from rclpy.signals import SignalHandlerOptions

        self.context, self.node = self.rclpy.Context(), None
        try:
            self.rclpy.init(args=["rcm_kin", *(ros_args or [])], context=self.context,
                            signal_handler_options=SignalHandlerOptions.NO)
            self.node = self.rclpy.create_node(options.name or f"rcm_kin_{role}", context=self.context)
        except Exception as exc:   # the middleware's own error types: no DDS transport, bad --ros-args
            self.close()
            first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
            if "ROSArgs" in type(exc).__name__:
                raise RcmKinError(f"ROS did not take the arguments `ros_args`: {first} (ROS reads -p NAME:=VALUE "
                                  "and -r FROM:=TO)", parameter="ros_args") from None
            raise RcmKinError(f"ROS 2 could not start a node (no DDS transport?): {first}") from None
        try:
            self.options = _with_parameters(self.node, options)
            units_of(self.options.convention)
            self.qos = _qos(self.options)
        except Exception:
            self.close()
            raise
        self.tally = Tally()
        self.log = self.node.get_logger()
        self.stop = threading.Event()

    def malformed(self, exc: Exception) -> None:
        self.tally.bad(str(exc))
        count = sum(self.tally.malformed.values())
        self.log.warning(f"message {self.tally.received} left out ({count} so far): {exc}",
                         throttle_duration_sec=self.options.warn_period)

    def guarded(self, work: Callable) -> Callable:
        """``work(msg)`` counted, timed, and never raising into the executor."""
        def callback(msg) -> None:
            start = time.perf_counter()
            self.tally.received += 1
            try:
                if work(msg):
                    self.tally.published += 1
                    self.tally.latency(time.perf_counter() - start)
            except (MalformedMessage, ValueError, TypeError, AttributeError) as exc:
                self.malformed(exc)
            except Exception as exc:     # no exception reaches the executor: the node goes on
                self.malformed(RuntimeError(f"not answered: {type(exc).__name__}: {exc}"))
        return callback

    def __enter__(self) -> RosNode:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Destroy the node and shut its context down (once; also after an error before spinning)."""
        if getattr(self, "node", None) is not None:
            self.node.destroy_node()
            self.node = None
        self._shutdown()

    def spin(self) -> dict:
        stop = self.stop
        previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
        executor = make_executor(self.context)
        executor.add_node(self.node)
        end = time.monotonic() + self.options.duration if self.options.duration > 0 else np.inf
        try:
            self.log.info("ready")
            while not stop.is_set() and time.monotonic() < end:
                executor.spin_once(timeout_sec=SPIN_PERIOD)
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)
            executor.shutdown(timeout_sec=1.0)
            self.close()
        return self.tally.summary()

    def _shutdown(self) -> None:
        if self.context.ok():
            self.rclpy.shutdown(context=self.context)

    def answer(self, names, frame: str) -> Callable:
        """``fill(stamp, position, velocity=None, effort=None)``: one JointState of joints ``names``
        in ``frame``, built once and refilled per answer (publishing serialises it at once)."""
        msg = self.JointState()
        msg.header.frame_id = frame
        msg.name = list(names)

        def fill(stamp, position, velocity=None, effort=None):
            msg.header.stamp = stamp
            msg.position = np.asarray(position, dtype=float).tolist()
            if velocity is not None:
                msg.velocity = np.asarray(velocity, dtype=float).tolist()
            if effort is not None:
                msg.effort = np.asarray(effort, dtype=float).tolist()
            return msg
        return fill


def run_teleop(options: NodeOptions = NodeOptions(), ros_args: list[str] | None = None,
               mtm_joints: tuple[str, ...] = ("j1", "j2", "j3")) -> dict:
    """The teleoperation node: MTM joint states in; the PSM shaft-tip target (``target_pose``:
    ``x, y, z`` m from the RCM, PSM base axes) and the PSM joint targets (roll, pitch, insertion in
    the convention's units) out, the input's stamp on both. With ``clutch_topic``, a ``std_msgs/Bool``
    true holds the PSM target while the MTM moves (:meth:`TeleopStep.clutch`). Runs until stopped;
    the tally."""
    with RosNode("teleop", options, ros_args) as ros:
        return _teleop(ros, mtm_joints)


def _teleop(ros: RosNode, mtm_joints):
    opt = ros.options
    psm = load_robot("psm")
    home = default_teleop_map(psm).home
    step = TeleopStep(load_robot("mtm"), psm, TeleopMap(home=home, scale=np.array(opt.scale)), mtm_joints)
    units = units_of(opt.convention)
    to_mtm = units.factors(["revolute"] * len(mtm_joints))
    to_psm = 1.0 / units.factors([psm.joint_kind(j) for j in ARM])
    targets = ros.node.create_publisher(ros.JointState, opt.topic(opt.target_topic, "target"), ros.qos)
    joints = ros.node.create_publisher(ros.JointState, opt.topic(opt.output_topic, "joints"), ros.qos)

    target_msg, joints_msg = ros.answer(("x", "y", "z"), "psm_rcm"), ros.answer(ARM, "psm_base")

    def work(msg) -> bool:
        out = step(joint_values(msg.name, msg.position, step.mtm_joints) * to_mtm)
        ros.tally.clamped += out.clamped
        targets.publish(target_msg(msg.header.stamp, out.reached - step.rcm))
        joints.publish(joints_msg(msg.header.stamp, out.joints * to_psm))
        return True

    ros.node.create_subscription(ros.JointState, opt.topic(opt.input_topic, "mtm"), ros.guarded(work), ros.qos)
    if opt.clutch_topic:
        from std_msgs.msg import Bool

        ros.node.create_subscription(Bool, opt.clutch_topic, lambda msg: step.clutch(bool(msg.data)), ros.qos)
    return ros.spin()


def run_gravity(options: NodeOptions = NodeOptions(), ros_args: list[str] | None = None) -> dict:
    """The gravity-feedforward node: PSM telemetry in; the holding effort out as a JointState of
    roll, pitch, insertion: ``position`` the pose used (rad, rad, m), ``effort`` the holding torque
    (N m, N m, N), ``velocity`` the holding PWM (counts, hardware sign; the telemetry's PWM field),
    ``header.frame_id`` the drive file's name; the input's stamp. The firmware convention reads
    roll and pitch (deg) and holds the insertion at ``insertion`` (m); CRTK reads all three (SI)."""
    with RosNode("gravity", options, ros_args) as ros:
        return _gravity(ros)


def _gravity(ros: RosNode):
    opt = ros.options
    step = GravityStep(load_robot("psm"), opt.drive or None)
    crtk = opt.convention == "crtk"
    wanted = ARM if crtk else ARM[:2]
    to_si = units_of(opt.convention).factors(["revolute"] * 2 + ["prismatic"] * crtk)
    publisher = ros.node.create_publisher(ros.JointState, opt.topic(opt.output_topic, "effort"), ros.qos)
    answer = ros.answer(ARM, step.source)

    def work(msg) -> bool:
        q = joint_values(msg.name, msg.position, wanted) * to_si
        out = step(q if crtk else np.r_[q, opt.insertion])
        publisher.publish(answer(msg.header.stamp, out.q, out.pwm, out.tau))
        return True

    ros.node.create_subscription(ros.JointState, opt.topic(opt.input_topic, "telemetry"), ros.guarded(work), ros.qos)
    return ros.spin()


def run_record(options: NodeOptions = NodeOptions(), ros_args: list[str] | None = None,
               messages: int = 0) -> tuple[TelemetryLog, dict]:
    """A live telemetry topic read into a :class:`TelemetryLog` (the CSV and bag readers' type, the
    same checks) until ``messages`` are in (0: the bound of one log, ``MAX_LOG_ROWS``), ``duration``
    s pass or a stop signal."""
    if options.convention != "firmware":
        raise RcmKinError("a telemetry log is the firmware's telemetry (deg, the PWM in `velocity`); the CRTK "
                          "convention's measured_js carries no PWM: set `convention` to firmware",
                          parameter="convention")
    with RosNode("record", options, ros_args) as ros:
        return _record(ros, messages)


def _record(ros: RosNode, messages: int):
    opt = ros.options
    topic = opt.topic(opt.input_topic, "telemetry")
    rows, stamps, received = [], [], []
    limit = min(messages or MAX_LOG_ROWS, MAX_LOG_ROWS)     # a log's bound (the CSV reader's) holds here too

    def work(msg) -> bool:
        rows.append({(name, f): float(values[i]) for f in FIELDS if len(values := getattr(msg, f)) == len(msg.name)
                     for i, name in enumerate(msg.name) if name in JOINTS})
        stamps.append(f"{msg.header.stamp.sec}.{msg.header.stamp.nanosec:09d}")
        received.append(time.time_ns())
        if len(rows) >= limit:
            ros.stop.set()
        return False

    ros.node.create_subscription(ros.JointState, topic, ros.guarded(work), ros.qos)
    summary = ros.spin()
    if len(rows) >= MAX_LOG_ROWS and messages != MAX_LOG_ROWS:
        warn(f"live:{topic}: the capture stopped at {MAX_LOG_ROWS:,} messages, the bound of one log")
    t, data = message_columns(f"live:{topic}", rows, stamps, received)
    return telemetry_log(f"live:{topic}", t, data), summary

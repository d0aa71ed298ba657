"""``ros2 teleop``, ``ros2 gravity``, ``ros2 record-check``, ``ros2 view``: rcm-kin as ROS 2 nodes (rclpy imported
when a node starts; the ``ros2`` extra)."""

from __future__ import annotations

import argparse

from rcm_kin.cli.common import RAW, Parser, add_json, count, emit, finite, path_text
from rcm_kin.cli.outputs import add_force, new_output
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.identification.telemetry import MAX_LOG_ROWS

EXTRA = "pip install 'rcm-kin[ros2]'"
EPILOG = ("examples: rcm-kin ros2 teleop                      (mtm_joint_states -> target_pose, psm_joint_targets)\n"
          "          rcm-kin ros2 gravity --insertion 0.1     (/psm_joint_telemetry -> psm_holding_effort)\n"
          "          rcm-kin ros2 record-check --messages 2000 --out capture.csv; rcm-kin sysid capture.csv\n"
          "          rcm-kin ros2 view                        (meshcat: open the URL it prints)\n"
          "          rcm-kin ros2 teleop --convention crtk    (a dVRK arm: /MTMR/measured_js -> /PSM1/servo_jp, SI)\n"
          "          rcm-kin ros2 gravity --ros-args -p depth:=15   (every option is also a ROS parameter)\n"
          "units at the message boundary: firmware convention deg and mm (the PSM's PWM in counts), crtk rad and m;\n"
          f"the nodes stop on Ctrl-C or SIGTERM and print their tally; needs the ros2 extra: {EXTRA}\n"
          "topics and QoS: docs/guide.md, 'On the robot's ROS 2 graph'")


def _common(p) -> None:
    p.add_argument("--convention", choices=("firmware", "crtk"), default="firmware",
                   help="firmware: the robot's topics, deg/mm at the boundary (default); crtk: the dVRK's, rad/m")
    p.add_argument("--input-topic", default="", help="topic read (default: the convention's, see the guide)")
    p.add_argument("--depth", type=count(1, 10_000, "messages"), default=20,
                   help="QoS history depth in messages (default 20: the robot's 15-20)")
    p.add_argument("--reliability", choices=("reliable", "best_effort"), default="reliable",
                   help="QoS reliability (default reliable, the robot's)")
    p.add_argument("--durability", choices=("volatile", "transient_local"), default="volatile",
                   help="QoS durability (default volatile, the robot's)")
    p.add_argument("--duration", type=finite(0, 1e6, "s"), default=0.0,
                   help="stop after this many seconds (default 0: run until Ctrl-C or SIGTERM)")
    p.add_argument("--warn-period", type=finite(0, 3600, "s"), default=1.0,
                   help="at most one warning about malformed messages per this many seconds (default 1)")
    p.add_argument("--name", default="", help="node name (default rcm_kin_<command>)")
    add_json(p, '{"received", "published", "clamped", "malformed", "malformed_reasons", "latency_median_s", '
                '"latency_p99_s"} when the node stops (latency: message in to answer published, s)')
    p.add_argument("--ros-args", nargs=argparse.REMAINDER, default=[],
                   help="the rest goes to ROS (-p name:=value parameters, -r remappings); last on the line")


def add_ros2(sub) -> None:
    p = sub.add_parser("ros2", help="ROS 2 nodes: teleoperation, gravity feedforward, live capture",
                       epilog=EPILOG, formatter_class=RAW)
    ros2 = p.add_subparsers(dest="ros2_command", required=True, parser_class=Parser)
    s = ros2.add_parser("teleop", help="MTM joint states -> PSM Cartesian target and joint targets",
                        epilog=EPILOG, formatter_class=RAW)
    _common(s)
    s.add_argument("--target-topic", default="", help="Cartesian target out (default target_pose: JointState x y z "
                                                      "in m from the PSM's RCM, PSM base axes)")
    s.add_argument("--output-topic", default="", help="joint targets out (default psm_joint_targets: roll, pitch deg, "
                                                      "insertion mm; crtk /PSM1/servo_jp: rad, m)")
    s.add_argument("--scale", nargs=3, type=finite(-10, 10), default=[0.05, 0.05, 0.25], metavar=("SX", "SY", "SZ"),
                   help="teleoperation scale per PSM base axis (default 0.05 0.05 0.25, the firmware's)")
    s.add_argument("--clutch-topic", default="", help="std_msgs/Bool topic, true while the clutch is pressed: the "
                                                      "PSM target holds while the MTM moves (default: no clutch)")
    s.add_argument("--mtm-joints", nargs=3, default=["j1", "j2", "j3"], metavar="NAME",
                   help="names of the MTM joints that place its wrist centre, as in the messages (default j1 j2 j3)")
    s.set_defaults(func=cmd_teleop)
    s = ros2.add_parser("gravity", help="PSM telemetry -> holding torque and PWM at the measured pose",
                        epilog=EPILOG, formatter_class=RAW)
    _common(s)
    s.add_argument("--output-topic", default="", help="holding effort out (default psm_holding_effort; crtk "
                                                      "/PSM1/servo_jf): effort N m, N; velocity PWM counts")
    s.add_argument("--insertion", type=finite(0, 0.16, "m"), default=HOME_INSERTION,
                   help=f"firmware convention: the insertion in m (default {HOME_INSERTION:g}; the telemetry's "
                        "insertion field is not read); crtk reads it from the message")
    s.add_argument("--params", type=path_text, default=None, help="drive parameter TOML (default the PSM's)")
    s.set_defaults(func=cmd_gravity)
    s = ros2.add_parser("record-check", help="a live telemetry topic read into a telemetry log (CSV for sysid, "
                                             "predict)", epilog=EPILOG, formatter_class=RAW)
    _common(s)
    s.add_argument("--messages", type=count(0, MAX_LOG_ROWS, "messages"), default=0,
                   help=f"stop after this many messages (default 0: --duration, Ctrl-C or {MAX_LOG_ROWS:,}, a log's "
                        "bound)")
    s.add_argument("--out", type=path_text, help="write the log as a telemetry CSV here (deg, PWM counts, deg; a new "
                                                 ".csv file unless --force)")
    add_force(s)
    s.set_defaults(func=cmd_record)
    s = ros2.add_parser("view", help="live meshcat view of the MTM and the PSM driven by their joint-state topics",
                        epilog=EPILOG, formatter_class=RAW)
    _common(s)
    s.add_argument("--psm-topic", default="", help="PSM joint states (default /psm_joint_telemetry: roll, pitch "
                                                   "deg; crtk /PSM1/measured_js: rad, m); --input-topic: the MTM's")
    s.add_argument("--rate", type=finite(0.1, 120, "Hz"), default=30.0,
                   help="redraws per second at most (default 30)")
    s.add_argument("--insertion", type=finite(0, 0.16, "m"), default=HOME_INSERTION,
                   help=f"firmware convention: the PSM's insertion in m (default {HOME_INSERTION:g})")
    s.set_defaults(func=cmd_view)


def _options(args, **extra):
    from rcm_kin.ros2.nodes import NodeOptions

    return NodeOptions(convention=args.convention, depth=args.depth, reliability=args.reliability,
                       durability=args.durability, input_topic=args.input_topic, duration=args.duration,
                       warn_period=args.warn_period, name=args.name, **extra)


def _ros_args(args) -> list[str]:
    return ["--ros-args", *args.ros_args] if args.ros_args else []


def _report(args, summary: dict, what: str) -> None:
    lines = [f"{what}: {summary['received']} messages in, {summary['published']} answered, "
             f"{summary['malformed']} malformed, {summary['clamped']} clamped"]
    if summary["malformed_reasons"]:
        lines += [f"  malformed: {n} x {reason}" for reason, n in summary["malformed_reasons"].items()]
    if summary["latency_median_s"] is not None:
        lines.append(f"latency message in -> answer out: median {summary['latency_median_s'] * 1e6:.0f} us, "
                     f"99th percentile {summary['latency_p99_s'] * 1e6:.0f} us")
    emit(args, summary, "\n".join(lines))


def cmd_teleop(args) -> None:
    from rcm_kin.ros2.nodes import run_teleop

    options = _options(args, target_topic=args.target_topic, output_topic=args.output_topic, scale=tuple(args.scale),
                       clutch_topic=args.clutch_topic)
    _report(args, run_teleop(options, _ros_args(args), tuple(args.mtm_joints)), "teleop")


def cmd_gravity(args) -> None:
    from rcm_kin.ros2.nodes import run_gravity

    options = _options(args, output_topic=args.output_topic, insertion=args.insertion, drive=args.params or "")
    _report(args, run_gravity(options, _ros_args(args)), "gravity")


def cmd_view(args) -> None:
    import contextlib
    import sys

    import meshcat

    from rcm_kin.ros2.view import run_view

    with contextlib.redirect_stdout(sys.stderr):     # its URL on stderr: stdout is the tally (--json)
        live = meshcat.Visualizer()                  # starts the meshcat server
    try:
        summary = run_view(live.window, _options(args, insertion=args.insertion), _ros_args(args), args.psm_topic,
                           args.rate)
    finally:
        if live.window.server_proc is not None:
            live.window.server_proc.kill()
            live.window.server_proc.wait()
    _report(args, summary, "view (answered = redraws)")


def cmd_record(args) -> None:
    from rcm_kin.identification.telemetry import write_telemetry
    from rcm_kin.ros2.nodes import run_record

    out = new_output(args.out, args.force, (".csv",)) if args.out else None      # refused before listening
    log, summary = run_record(_options(args), _ros_args(args), args.messages)
    steps = log.time[1:] - log.time[:-1]
    summary.update(samples=len(log.time), seconds=float(log.time[-1]), joints=sorted(log.position),
                   rate_hz=float(1 / steps.mean()), widest_step_s=float(steps.max()))
    if out is not None:
        summary["file"] = str(write_telemetry(log, out))
    text = (f"{summary['samples']} samples over {summary['seconds']:.3f} s ({summary['rate_hz']:.1f} Hz, widest step "
            f"{summary['widest_step_s'] * 1e3:.2f} ms) of {', '.join(summary['joints'])}"
            + (f"; written to {summary['file']}" if args.out else ""))
    emit(args, summary, text)

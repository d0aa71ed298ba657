"""``info``, ``fk``, ``ik``: a robot's joints and frames, forward and inverse kinematics."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import RAW, add_json, any_robot, emit, floats, joint_values
from rcm_kin.model import joint_table, load_robot

EPILOG_FK = "example: rcm-kin fk psm 10 -5 0.08 --deg --json   (roll 10 deg, pitch -5 deg, insertion 0.08 m)"
EPILOG_IK = ("examples: rcm-kin ik psm 0.01 0.02 -0.06 --json   (shaft tip at x y z in m, base frame)\n"
             "          rcm-kin ik psm -0.009 0 -0.073 --rpy 0 61 -180 --deg   (tool_tip pose, numeric)\n"
             "          rcm-kin ik mtm 0.26 0.02 -0.2 --json   (MTM wrist centre)\n"
             "          rcm-kin ik path/to/arm.toml 0.4 0.1 0.3 --frame tool0   (any robot, any frame)")


def add_info(sub) -> None:
    p = sub.add_parser("info", help="joints, limits, axes and frames of a robot", parents=[any_robot()],
                       epilog="example: rcm-kin info psm --json")
    add_json(p)
    p.set_defaults(func=cmd_info)


def add_fk(sub) -> None:
    p = sub.add_parser("fk", help="forward kinematics of the frames of interest", parents=[any_robot()],
                       epilog=EPILOG_FK, formatter_class=RAW)
    p.add_argument("q", nargs="*", metavar="Q",
                   help="actuated joint values in 'info' order (rad, m); missing trailing values are 0")
    p.add_argument("--deg", action="store_true", help="revolute values in degrees (prismatic stay in m)")
    add_json(p, "machine-readable output (SI)")
    p.set_defaults(func=cmd_fk)


def add_ik(sub) -> None:
    p = sub.add_parser("ik", help="inverse kinematics of any robot: closed form about the RCM where the description "
                                  "has [rcm], damped least squares otherwise", parents=[any_robot()],
                       epilog=EPILOG_IK, formatter_class=RAW)
    for axis in "xyz":
        p.add_argument(axis, metavar=axis.upper(), help=f"target {axis} in m, base frame")
    p.add_argument("--frame", metavar="F",
                   help="the frame to place (default: the [rcm] shaft frame, else the last frame of interest "
                        "that three joints place, or the last one with --rpy)")
    p.add_argument("--rpy", nargs=3, metavar=("R", "P", "Y"),
                   help="also the frame's orientation as roll pitch yaw (rad, or deg with --deg)")
    p.add_argument("--deg", action="store_true", help="--rpy in degrees")
    add_json(p, "machine-readable output (SI)")
    p.set_defaults(func=cmd_ik)


def cmd_info(args) -> None:
    """Joint table, loops, frames of interest and, where declared, the measured remote centre."""
    robot = load_robot(args.robot)
    joints = [{"name": j.name, "type": j.kind, "lower": j.lower, "upper": j.upper,
               "axis_world": j.axis.round(12).tolist(), "role": j.role} for j in joint_table(robot)]
    payload = {"robot": robot.name, "joints": joints, "actuated": list(robot.actuated),
               "gravity": robot.gravity.tolist(), "frames": list(robot.description.frames),
               "loops": [c.loop.name for c in robot.constraints]}
    lines = [f"{robot.name}: {len(robot.actuated)} actuated joints, {len(robot.constraints)} loop closures, "
             f"gravity {robot.gravity.tolist()} m/s^2 (base frame)",
             f"{'joint':18} {'type':9} {'role':8} {'lower':>9} {'upper':>9}  axis (base frame, q = 0)"]
    for j in joints:
        scale, unit = (1e3, "mm") if j["type"] == "prismatic" else (180 / np.pi, "deg")
        lines.append(f"{j['name']:18} {j['type']:9} {j['role']:8} {j['lower'] * scale:9.2f} {j['upper'] * scale:9.2f}"
                     f" {unit:3} {np.round(j['axis_world'], 4).tolist()}")
    lines.append(f"frames of interest: {', '.join(robot.description.frames)}")
    if robot.description.rcm is not None:
        lines.append(_rcm_line(robot, payload))
    emit(args, payload, "\n".join(lines))


def _rcm_line(robot, payload: dict) -> str:
    """Adds the measured remote centre to ``payload``; returns its line of text."""
    from rcm_kin.kinematics.rcm_scatter import rcm_scatter

    rcm = robot.description.rcm
    scatter = rcm_scatter(robot, rcm.shaft_frame, rcm.joints, rcm.base_frame)
    payload["rcm"] = {"point": scatter.point.tolist(), "frame": rcm.base_frame or "base",
                      "max_distance": scatter.max_distance, "rms_distance": scatter.rms_distance}
    return (f"remote centre of motion: {np.round(scatter.point, 6).tolist()} m in {rcm.base_frame or 'the base'};"
            f" shaft lines over {rcm.joints[0]} x {rcm.joints[1]} pass within "
            f"{scatter.max_distance * 1e3:.3g} mm (RMS {scatter.rms_distance * 1e3:.3g} mm)")


def cmd_fk(args) -> None:
    from rcm_kin.kinematics.fk import forward_kinematics

    robot = load_robot(args.robot)
    result = forward_kinematics(robot, joint_values(robot, args))
    frames = {name: {"position": M.translation.tolist(), "rotation": M.rotation.tolist()}
              for name, M in result.frames.items()}
    payload = {"q": result.q.tolist(), "frames": frames, "closure_residual": result.closure_residual}
    lines = [f"q = {np.round(result.q, 6).tolist()} (rad, m)"]
    lines += [f"{name:14} position {np.round(M.translation, 6).tolist()} m" for name, M in result.frames.items()]
    lines.append(f"loop closure residual {result.closure_residual:.1e} m")
    emit(args, payload, "\n".join(lines))


def cmd_ik(args) -> None:
    from rcm_kin.kinematics.ik import inverse_kinematics

    robot = load_robot(args.robot)
    target = floats([args.x, args.y, args.z], "the target x y z")
    rpy = None if args.rpy is None else floats(args.rpy, "--rpy")
    solution = inverse_kinematics(robot, target, np.radians(rpy) if args.deg and rpy is not None else rpy,
                                  frame=args.frame)
    payload = {"q": solution.q.tolist(), "position_error": solution.position_error, "frame": solution.frame,
               "joints": list(solution.joints), "method": solution.method}
    if solution.orientation_error is not None:
        payload["orientation_error"] = solution.orientation_error
    shown = [f"{n} {np.degrees(v):.4f} deg" if robot.joint_kind(n) == "revolute" else f"{n} {v * 1e3:.4f} mm"
             for n, v in zip(solution.joints, solution.q)]
    emit(args, payload, f"{solution.frame}: " + ", ".join(shown)
         + f"  (position error {solution.position_error:.1e} m)")

"""``export``: a bundled robot in another tool's format. Each format is one option and one writer
call; the handler only dispatches."""

from __future__ import annotations

from rcm_kin.cli.common import RAW, add_params, any_robot
from rcm_kin.errors import RcmKinError
from rcm_kin.robot import load_robot

EPILOG = ("examples: rcm-kin export psm --mjcf psm.xml   (MuJoCo: python -m mujoco.viewer --mjcf psm.xml)\n"
          "          rcm-kin export davinci --mjcf davinci.xml")


def add_export(sub) -> None:
    p = sub.add_parser("export", help="write a robot model for another tool (MuJoCo MJCF)",
                       parents=[any_robot()], epilog=EPILOG, formatter_class=RAW)
    p.add_argument("--mjcf", metavar="FILE", help="MuJoCo MJCF file: loops closed by equality/connect, a motor "
                                                  "per actuated joint (N m, N), keyframes (home, thesis grid)")
    add_params(p, "drive parameter TOML for the PSM's joint armature, damping and friction "
                  "(default: the shipped calibrated set)")
    p.set_defaults(func=cmd_export)


def cmd_export(args) -> None:
    if not args.mjcf:
        raise RcmKinError("choose what to write: --mjcf FILE")
    robot = load_robot(args.robot)
    if args.params and robot.name != "psm":
        raise RcmKinError(f"--params sets the PSM's drives; {robot.name} has none")
    if args.mjcf:
        from rcm_kin.dynamics.drive import load_drive_parameters
        from rcm_kin.export.mjcf import write_mjcf

        params = load_drive_parameters(args.params) if robot.name == "psm" else None
        print(f"wrote {write_mjcf(robot, args.mjcf, params)}")

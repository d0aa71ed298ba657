"""The ``rcm-kin`` command line. Units: SI (rad, m) unless ``--deg``; ``--json`` for scripts.

User errors print one line ``error: ...`` on stderr and exit with status 2. One module per
command group registers its sub-commands (``add_*``) and runs them (``cmd_*``): parse, call the
library, format.
"""

from __future__ import annotations

import sys

from rcm_kin.cli import (control, drive_train, export, identification, kinematics, robustness, safety, simulation,
                         statics, views)
from rcm_kin.cli.common import RAW, Parser
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.rosbag import DEFAULT_TOPIC, telemetry_topic

# in the order of ``rcm-kin --help``
COMMANDS = (kinematics.add_info, kinematics.add_fk, kinematics.add_ik,
            statics.add_gravity, statics.add_torque_map, statics.add_calibrate,
            control.add_dynamics, control.add_linearize, control.add_schedule,
            simulation.add_simulate, robustness.add_robustness, robustness.add_sweep,
            identification.add_sysid, identification.add_greybox,
            drive_train.add_identify, drive_train.add_predict, drive_train.add_excite,
            views.add_view, safety.add_safety, views.add_report, export.add_export)
# the commands that read telemetry logs: CSV, or ROS 2 bags whose JointState topic --topic names
LOG_COMMANDS = ("calibrate", "sysid", "greybox", "identify", "predict", "report")


def build_parser() -> Parser:
    parser = Parser(prog="rcm-kin", description=(
        "Models of the low-cost RCM surgical robot (PSM and MTM): kinematics, dynamics, control. "
        "Units: rad, m, N m, V unless --deg; PWM in counts with the hardware sign."),
        epilog=("examples: rcm-kin fk psm 10 -5 0.08 --deg --json\n"
                "          rcm-kin simulate psm --experiment sine --controller scheduled\n"
                "          rcm-kin report --out report\n"
                "every command: rcm-kin COMMAND --help (units and an example); --json for scripts"),
        formatter_class=RAW)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for add in COMMANDS:
        add(sub)
    for name in LOG_COMMANDS:
        sub.choices[name].add_argument("--topic", default=DEFAULT_TOPIC,
                                       help=f"telemetry topic of ROS 2 bag logs (.mcap, .db3; default {DEFAULT_TOPIC})")
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one command; 0 on success, 2 on a user error, 130 on Ctrl-C."""
    args = build_parser().parse_args(argv)
    try:
        with telemetry_topic(getattr(args, "topic", None)):
            args.func(args)
    except RcmKinError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    return 0

"""The ``rcm-kin`` command line. Units: SI (rad, m) unless ``--deg``; ``--json`` for scripts.

User errors print one line ``error: ...`` on stderr and exit with status 2. One module per
command group registers its sub-commands (``add_*``) and runs them (``cmd_*``): parse, call the
library, format.
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import warnings
from importlib.metadata import PackageNotFoundError, version

from rcm_kin.atomic import stop_writes
from rcm_kin.cli import (
    calibration,
    control,
    counterweights,
    drive_train,
    export,
    identification,
    kinematics,
    prediction,
    robustness,
    ros2,
    safety,
    schedule,
    simulation,
    statics,
    views,
)
from rcm_kin.cli.common import RAW, Parser, command_options, with_flags
from rcm_kin.cli.outputs import owned_outputs
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.rosbag import DEFAULT_TOPIC, telemetry_topic
from rcm_kin.identification.telemetry import MAX_GAP, MAX_LOG_BYTES, MAX_LOG_ROWS, TIME_TOLERANCE

TERMINATED = "terminated (SIGTERM): nothing written under a final name after the signal"
# in the order of ``rcm-kin --help``
COMMANDS = (kinematics.add_info, kinematics.add_fk, kinematics.add_ik,
            statics.add_gravity, statics.add_torque_map, counterweights.add_counterweights, calibration.add_calibrate,
            control.add_dynamics, control.add_linearize, schedule.add_schedule,
            simulation.add_simulate, robustness.add_robustness, robustness.add_sweep,
            identification.add_sysid, identification.add_greybox,
            drive_train.add_identify, prediction.add_predict, drive_train.add_excite,
            views.add_view, safety.add_safety, views.add_report, export.add_export, ros2.add_ros2)
# the commands that read telemetry logs: CSV, or ROS 2 bags whose JointState topic --topic names
LOG_COMMANDS = ("calibrate", "sysid", "greybox", "identify", "predict", "report")
LOG_BOUNDS = (f"logs: a CSV of at most {MAX_LOG_ROWS:,} rows and {MAX_LOG_BYTES // 2**20} MiB; time stamps in order\n"
              f"      (none more than {TIME_TOLERANCE:g} s before the one above), no gap over {MAX_GAP:g} s: else the "
              "log is refused naming the row")


def build_parser() -> Parser:
    parser = Parser(prog="rcm-kin", description=(
        "Models of RCM surgical robots (the bundled PSM and MTM, or any robot by the path of its URDF or sidecar): "
        "kinematics, dynamics, control. "
        "Units: rad, m, N m, V unless --deg; PWM in counts with the hardware sign."),
        epilog=("examples: rcm-kin fk psm 10 -5 0.08 --deg --json\n"
                "          rcm-kin simulate psm --experiment sine --controller scheduled\n"
                "          rcm-kin torque-map mtm --grid j1=-60:60:61 j3=-30:80:56 --out maps\n"
                "          rcm-kin report --out report\n"
                "every command: rcm-kin COMMAND --help (units and an example); --json for scripts"),
        formatter_class=RAW)
    parser.add_argument("--version", action="version", version=f"rcm-kin {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for add in COMMANDS:
        add(sub)
    for name in LOG_COMMANDS:
        command = sub.choices[name]
        lines = [command.epilog, LOG_BOUNDS] if command.epilog else [LOG_BOUNDS]
        command.epilog = ("\n" if command.formatter_class is RAW else "; ").join(lines)
        command.add_argument("--topic", default=DEFAULT_TOPIC,
                             help=f"telemetry topic of ROS 2 bag logs (.mcap, .db3; default {DEFAULT_TOPIC})")
    return parser


def _version() -> str:
    try:
        return version("rcm-kin")
    except PackageNotFoundError:
        return "unknown (not installed)"


def main(argv: list[str] | None = None) -> int:
    """Run one command; 0 on success, 2 on a user error, 130 on Ctrl-C, 143 on SIGTERM.

    The one place where errors become output: an :class:`RcmKinError` (and an operating-system
    error on a file) is the single line ``error: ...`` on stderr, after any progress bar is cleared;
    the library parameter it names (``exc.parameter``) is named by the command's flag.
    Warnings raised while the command runs are held back: on success each is one line
    ``warning: ...`` on stderr; on an error only the error line is printed.
    """
    parser, args = build_parser(), None
    with warnings.catch_warnings(record=True) as caught, _terminated_as_interrupt():
        try:
            args = parser.parse_args(argv)    # a usage error exits here (status 2), as argparse does
            with telemetry_topic(getattr(args, "topic", None)), owned_outputs():
                args.func(args)
        except (RcmKinError, OSError) as exc:
            if _TERMINATED:             # a write refused after SIGTERM
                return _fail(TERMINATED, 143)
            return _fail(_message(exc, command_options(parser, getattr(args, "command", None))), 2)
        except Terminated:
            return _fail(TERMINATED, 143)
        except KeyboardInterrupt:
            return _fail("interrupted", 130)
        if _TERMINATED:                 # the signal landed where Python swallows exceptions
            return _fail(TERMINATED, 143)
    for message in dict.fromkeys(" ".join(str(w.message).split()) for w in caught):
        print(f"warning: {message}", file=sys.stderr)
    return 0


_TERMINATED: list[int] = []


class Terminated(KeyboardInterrupt):
    """SIGTERM received: unwinds like Ctrl-C (temporaries removed, clusters and pools closed)."""


@contextlib.contextmanager
def _terminated_as_interrupt():
    """While a command runs in the main thread, SIGTERM raises :class:`Terminated` (a second one
    while cleaning up is ignored: the clean-up finishes); the previous handler is restored after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(signum, frame):
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        _TERMINATED.append(signum)
        stop_writes("the run was terminated (SIGTERM)")
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _message(exc: Exception, options: set[str]) -> str:
    """One line: an RcmKinError's message (the parameters it names named by their flags among the
    command's ``options``), or an OSError's file and reason."""
    if isinstance(exc, RcmKinError):
        text = with_flags(str(exc), exc.parameters, options)
    else:
        text = f"cannot use {exc.filename}: {exc.strerror}" if exc.filename else f"{exc.strerror or exc}"
    return " ".join(text.split())


def _fail(message: str, status: int) -> int:
    """Clear the progress bars still on screen, then print ``message`` as one line."""
    from tqdm import tqdm

    for bar in list(getattr(tqdm, "_instances", ())):
        bar.leave = False
        bar.close()
    print(f"error: {message}", file=sys.stderr)
    return status

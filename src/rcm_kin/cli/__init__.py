"""The ``rcm-kin`` command line. Units: SI (rad, m) unless ``--deg``; ``--json`` for scripts.

User errors print one line ``error: ...`` on stderr and exit with status 2. One module per
command group registers its sub-commands (``add_*``) and runs them (``cmd_*``): parse, call the
library, format.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import signal
import sys
import threading
import warnings
from typing import NoReturn

from rcm_kin.atomic import stop_writes
from rcm_kin.cli.common import RAW, Parser, command_options, with_flags
from rcm_kin.cli.outputs import owned_outputs
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.rosbag import DEFAULT_TOPIC, telemetry_topic
from rcm_kin.identification.telemetry import MAX_GAP, MAX_LOG_BYTES, MAX_LOG_ROWS, TIME_TOLERANCE

TERMINATED = "terminated (SIGTERM): nothing written under a final name after the signal"
# in the order of ``rcm-kin --help``: (command, its module in rcm_kin.cli, the function that adds it),
# the module imported when the command is built: a command pays for its own module's imports only
COMMANDS = (("info", "kinematics", "add_info"), ("fk", "kinematics", "add_fk"), ("ik", "kinematics", "add_ik"),
            ("gravity", "statics", "add_gravity"), ("torque-map", "statics", "add_torque_map"),
            ("counterweights", "counterweights", "add_counterweights"), ("calibrate", "calibration", "add_calibrate"),
            ("dynamics", "control", "add_dynamics"), ("linearize", "control", "add_linearize"),
            ("schedule", "schedule", "add_schedule"), ("simulate", "simulation", "add_simulate"),
            ("robustness", "robustness", "add_robustness"), ("sweep", "robustness", "add_sweep"),
            ("sysid", "identification", "add_sysid"), ("greybox", "identification", "add_greybox"),
            ("identify", "drive_train", "add_identify"), ("predict", "prediction", "add_predict"),
            ("excite", "drive_train", "add_excite"), ("view", "views", "add_view"), ("safety", "safety", "add_safety"),
            ("report", "views", "add_report"), ("export", "export", "add_export"), ("ros2", "ros2", "add_ros2"))
# the commands that read telemetry logs: CSV, or ROS 2 bags whose JointState topic --topic names
LOG_COMMANDS = ("calibrate", "sysid", "greybox", "identify", "predict", "report")
LOG_BOUNDS = (f"logs: a CSV of at most {MAX_LOG_ROWS:,} rows and {MAX_LOG_BYTES // 2**20} MiB; time stamps in order\n"
              f"      (none more than {TIME_TOLERANCE:g} s before the one above), no gap over {MAX_GAP:g} s: else the "
              "log is refused naming the row")


def build_parser(command: str | None = None) -> Parser:
    """The ``rcm-kin`` parser with every command, or with ``command`` alone (one of
    :data:`COMMANDS`: its module is the only one imported)."""
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
    parser.add_argument("--version", action=Version, help="show program's version number and exit")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name, module, add in COMMANDS:
        if command in (None, name):
            getattr(importlib.import_module(f"rcm_kin.cli.{module}"), add)(sub)
    for name in LOG_COMMANDS:
        if name not in sub.choices:
            continue
        reader = sub.choices[name]
        lines = [reader.epilog, LOG_BOUNDS] if reader.epilog else [LOG_BOUNDS]
        reader.epilog = ("\n" if reader.formatter_class is RAW else "; ").join(lines)
        reader.add_argument("--topic", default=DEFAULT_TOPIC,
                             help=f"telemetry topic of ROS 2 bag logs (.mcap, .db3; default {DEFAULT_TOPIC})")
    return parser


class Version(argparse.Action):
    """``--version`` as argparse's ``version`` action prints it (stdout, then exit 0), the version
    read from the installed package when asked: importlib.metadata, imported to read it, costs
    20-40 ms of every command's start otherwise."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS, help=None):
        super().__init__(option_strings=option_strings, dest=dest, default=default, nargs=0, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"rcm-kin {_version()}")
        parser.exit()


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("rcm-kin")
    except PackageNotFoundError:
        return "unknown (not installed)"


def run() -> NoReturn:
    """The ``rcm-kin`` console command (and ``python -m rcm_kin.cli``): :func:`main`, then the
    process exits with its status. What the command left in memory is frozen first
    (``gc.freeze``): the interpreter's shutdown would otherwise scan every object again in its
    collections before freeing them, 0.1-0.25 s of a short command's wall time once Pinocchio and
    matplotlib are loaded (docs/performance.md). What is still alive at the exit is then not
    finalised by a collection: the commands close their files, pools, clusters and ROS 2 context
    inside ``main`` (stdout and stderr are flushed and atexit handlers run either way). A process
    that calls :func:`main` and goes on keeps its collector as it was."""
    status = main()
    gc.freeze()
    sys.exit(status)


def main(argv: list[str] | None = None) -> int:
    """Run one command; 0 on success, 2 on a user error, 130 on Ctrl-C, 143 on SIGTERM.

    The one place where errors become output: an :class:`RcmKinError` (and an operating-system
    error on a file) is the single line ``error: ...`` on stderr, after any progress bar is cleared;
    the library parameter it names (``exc.parameter``) is named by the command's flag.
    Warnings raised while the command runs are held back: on success each is one line
    ``warning: ...`` on stderr; on an error only the error line is printed.
    """
    argv = sys.argv[1:] if argv is None else argv
    parser, args = build_parser(argv[0] if argv and argv[0] in {c[0] for c in COMMANDS} else None), None
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

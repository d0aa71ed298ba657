"""What the command modules share: the parser class, the ``robot`` parent parsers and their run-time
check, the repeated options, the validated argument types (finite numbers in a range, counts, paths),
number parsing and strict output."""

from __future__ import annotations

import argparse
import json
import math
import re
import sys

import numpy as np

from rcm_kin.errors import NonFiniteResultError, RcmKinError
from rcm_kin.model import load_robot, robot_names

RAW = argparse.RawDescriptionHelpFormatter      # keeps the epilogs' example lines
PARAMS_HELP = "drive parameter TOML (default: the shipped calibrated set)"
# the library's parameter names (as its messages write them, in backticks: `harmonics`) -> the
# flag that sets them; a name not listed is its flag (``--`` and dashes) when the command has it
PARAMETER_FLAGS = {"params": "--params", "harmonics": "--harmonics", "duration": "--duration", "points": "--points",
                   "delta": "--delta", "error_bound": "--error-bound", "r_max": "--r-max", "renderer": "--renderer",
                   "rpy": "--rpy", "segment": "--segment", "topic": "--topic", "grid": "--grid",
                   "pwm_limit": "--pwm-limit", "package_dirs": "--package-dir", "drive": "--params"}


class Parser(argparse.ArgumentParser):
    """argparse with the project's one-line error format, reading ``-1e-06`` as a number."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str):  # noqa: D102 - argparse API
        self.exit(2, f"error: {message} (see: {self.prog} --help)\n")

    def _get_value(self, action, arg_string):
        """argparse's (private, stable) conversion, with a value refused by one of our types (:class:`BadValue`)
        turned into an :class:`ArgumentValueError` naming the argument (the command's user error,
        status 2 from :func:`rcm_kin.cli.main`, like any other bad value)."""
        try:
            return super()._get_value(action, arg_string)
        except BadValue as exc:
            name = "/".join(action.option_strings) or action.metavar or action.dest
            raise ArgumentValueError(f"{name}: {exc}") from None


def with_flags(message: str, parameters: tuple[str, ...], options: set[str]) -> str:
    """``message`` with each of ``parameters``, written in it in backticks (`` `name` ``), named by its
    flag: :data:`PARAMETER_FLAGS`'s, else ``--name`` when the command's ``options`` hold it."""
    for name in parameters:
        flag = PARAMETER_FLAGS.get(name)
        if flag is None and (derived := "--" + name.replace("_", "-")) in options:
            flag = derived
        if flag is not None:
            message = message.replace(f"`{name}`", flag)
    return message


def command_options(parser: argparse.ArgumentParser, command: str | None) -> set[str]:
    """The option strings of the sub-command ``command`` of ``parser`` (empty when not known)."""
    sub = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
    chosen = None if sub is None else sub.choices.get(command)
    return set() if chosen is None else {o for a in chosen._actions for o in a.option_strings}


class BadValue(Exception):
    """Raised by the argument types below: not a ValueError, so that argparse passes it on."""


class ArgumentValueError(RcmKinError):
    """A command-line value outside what its argument accepts (the argument is named)."""


def robot_parent(help_text: str) -> argparse.ArgumentParser:
    """Parent parser of a command whose first argument is a robot name."""
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("robot", help=help_text)
    return parent


def any_robot() -> argparse.ArgumentParser:
    """``robot``: a bundled robot or a user's description by path (checked by ``load_robot``)."""
    return robot_parent(f"a bundled robot ({', '.join(robot_names())}) or the path of a robot's sidecar .toml "
                        "or URDF")


def psm_robot() -> argparse.ArgumentParser:
    """``robot`` of the PSM-only commands; they call :func:`require_psm` when run."""
    return robot_parent("psm: this command is the bundled PSM's (its thesis experiments, firmware and logs); "
                        "other robots are refused")


def is_bundled_psm(robot: str) -> bool:
    """Whether the robot argument names the bundled PSM: ``psm``, or a path to its own sidecar."""
    return robot == "psm" or (str(robot).endswith(".toml") and load_robot(robot) is load_robot("psm"))


def require_psm(args, message: str) -> None:
    """User error ``message`` (``{robot}`` filled in) unless the robot argument is the bundled PSM
    (by name, or by the path of its own files)."""
    if not is_bundled_psm(args.robot):
        raise RcmKinError(message.format(robot=args.robot))


def add_json(parser: argparse.ArgumentParser, help_text: str = "machine-readable output") -> None:
    parser.add_argument("--json", action="store_true", help=help_text)


def add_params(parser: argparse.ArgumentParser, help_text: str = PARAMS_HELP) -> None:
    parser.add_argument("--params", type=path_text, help=help_text)


def _shown(word: str) -> str:
    """A typed word as quoted in a message: at most 40 characters."""
    return repr(word if len(word) <= 40 else word[:37] + "...")


def finite(lo: float = -math.inf, hi: float = math.inf, unit: str = "", open_lo: bool = False):
    """argparse ``type``: a finite number within [lo, hi] (``open_lo``: above ``lo``), in ``unit``."""
    bounded = math.isfinite(lo) or math.isfinite(hi)
    span = (f" in {'(' if open_lo else '['}{lo:g}, {hi:g}]" if bounded else "") + (f" {unit}" if unit else "")

    def parse(word: str) -> float:
        try:
            value = float(word)
        except ValueError:
            raise BadValue(f"needs a number{span}, got {_shown(word)}") from None
        if not math.isfinite(value):
            raise BadValue(f"needs a finite number{span}, got {_shown(word)}")
        if value < lo or value > hi or (open_lo and value == lo):
            raise BadValue(f"needs a number{span}, got {_shown(word)}")
        return value
    return parse


def count(lo: int, hi: int, what: str = ""):
    """argparse ``type``: a whole number of ``what`` within [lo, hi] (a bound on the work it asks for)."""
    def parse(word: str) -> int:
        try:
            value = int(word)
        except ValueError:
            raise BadValue(f"needs a whole number{' of ' + what if what else ''}, got {_shown(word)}") from None
        if not lo <= value <= hi:
            raise BadValue(f"needs at least {lo} and at most {hi:,}{' ' + what if what else ''}, got {_shown(word)}")
        return value
    return parse


def path_text(word: str) -> str:
    """argparse ``type``: a non-empty path."""
    if not word.strip():
        raise BadValue("an empty path")
    return word


def floats(values: list[str], what: str) -> np.ndarray:
    """Command-line words as finite numbers, or a user error naming ``what``."""
    try:
        numbers = np.array([float(v) for v in values])
    except ValueError:
        raise RcmKinError(f"{what} must be numbers, got {' '.join(_shown(v) for v in values)}") from None
    if not np.all(np.isfinite(numbers)):
        raise RcmKinError(f"{what} must be finite numbers, got {' '.join(_shown(v) for v in values)}")
    return numbers


def joint_values(robot, args) -> np.ndarray:
    """The actuated q typed on the command line (``args.q``, ``--deg``), padded with zeros."""
    q = floats(args.q, "joint values")
    if args.deg:                      # revolute deg -> rad; prismatic stay in m
        for i, name in enumerate(robot.actuated[:q.size]):
            if robot.joint_kind(name) == "revolute":
                q[i] = np.radians(q[i])
    return robot.check_limits(robot.check_q(q, allow_short=True))


def driven_model(params: str | None, coulomb: bool, robot: str = "psm", joints=None):
    """The driven-joint dynamics of ``robot`` (a name or a sidecar path; default the bundled PSM)
    with the drive parameter TOML ``params`` (None: the robot's own drive, else its URDF inertias
    with torque input over ``joints``, default all actuated)."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.state_space import driven_dynamics

    drive = load_drive_parameters(params) if params is not None else None
    return driven_dynamics(load_robot(robot), drive, coulomb=coulomb, joints=joints)


def check_finite(payload: dict) -> None:
    """A user error naming the first non-finite number in ``payload`` (call it before writing files
    from a result, so that a refused result leaves nothing behind)."""
    where = _non_finite(payload)
    if where:
        raise NonFiniteResultError(f"the result is not finite ({where}): the inputs are outside what the model "
                                   "can compute; check the parameter file and the numbers given", where=where)


def emit(args, payload: dict, text: str) -> None:
    """Print ``payload`` as strict JSON with ``--json``, else ``text``. Either way a non-finite number
    in ``payload`` is a user error naming where it is: a result is finite or it is not printed."""
    check_finite(payload)
    print(json.dumps(payload, allow_nan=False) if getattr(args, "json", False) else text)


def _non_finite(value, where: str = "") -> str:
    """The path of the first non-finite float in ``value`` ('' when all are finite)."""
    if isinstance(value, (float, np.floating)):
        return "" if math.isfinite(value) else (where.lstrip(".") or "value")
    if isinstance(value, dict):
        return next((w for k, v in value.items() if (w := _non_finite(v, f"{where}.{k}"))), "")
    if isinstance(value, (list, tuple)):
        return next((w for i, v in enumerate(value) if (w := _non_finite(v, f"{where}[{i}]"))), "")
    return ""


def progress_wanted(args) -> bool:
    """Progress bars on stderr when it is a terminal, unless ``--json`` (scripts): a log file or a
    pipe gets the ``error:``/``warning:`` lines alone, each on its own line. A user error is
    printed after the bars are cleared (:func:`rcm_kin.cli.main`)."""
    return not getattr(args, "json", False) and sys.stderr.isatty()


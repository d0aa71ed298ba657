"""What the command modules share: the parser class, the ``robot`` parent parsers and their run-time
check, the repeated options, number parsing and output."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np

from rcm_kin.errors import RcmKinError
from rcm_kin.robot import load_robot, robot_names

RAW = argparse.RawDescriptionHelpFormatter      # keeps the epilogs' example lines
PARAMS_HELP = "drive parameter TOML (default: the shipped calibrated set)"


class Parser(argparse.ArgumentParser):
    """argparse with the project's one-line error format, reading ``-1e-06`` as a number."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str):  # noqa: D102 - argparse API
        self.exit(2, f"error: {message} (see: {self.prog} --help)\n")


def robot_parent(help_text: str) -> argparse.ArgumentParser:
    """Parent parser of a command whose first argument is a robot name."""
    parent = argparse.ArgumentParser(add_help=False)
    parent.add_argument("robot", help=help_text)
    return parent


def any_robot() -> argparse.ArgumentParser:
    """``robot``: any bundled robot (checked by ``load_robot``)."""
    return robot_parent(f"robot name ({', '.join(robot_names())})")


def psm_robot() -> argparse.ArgumentParser:
    """``robot`` of the PSM-only commands; they call :func:`require_psm` when run."""
    return robot_parent("psm")


def require_psm(args, message: str) -> None:
    """User error ``message`` (``{robot}`` filled in) unless the robot argument is the PSM."""
    if args.robot != "psm":
        raise RcmKinError(message.format(robot=args.robot))


def add_json(parser: argparse.ArgumentParser, help_text: str = "machine-readable output") -> None:
    parser.add_argument("--json", action="store_true", help=help_text)


def add_params(parser: argparse.ArgumentParser, help_text: str = PARAMS_HELP) -> None:
    parser.add_argument("--params", help=help_text)


def floats(values: list[str], what: str) -> np.ndarray:
    """Command-line words as numbers, or a user error naming ``what``."""
    try:
        return np.array([float(v) for v in values])
    except ValueError:
        raise RcmKinError(f"{what} must be numbers, got {' '.join(values)}") from None


def joint_values(robot, args) -> np.ndarray:
    """The actuated q typed on the command line (``args.q``, ``--deg``), padded with zeros."""
    q = floats(args.q, "joint values")
    if args.deg:                      # revolute deg -> rad; prismatic stay in m
        for i, name in enumerate(robot.actuated[:q.size]):
            if robot.joint_kind(name) == "revolute":
                q[i] = np.radians(q[i])
    return robot.check_q(q, allow_short=True)


def driven_model(params: str | None, coulomb: bool):
    """The PSM's driven-joint dynamics with the drive parameter TOML ``params`` (None: shipped)."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.state_space import driven_dynamics

    return driven_dynamics(load_robot("psm"), load_drive_parameters(params), coulomb=coulomb)


def emit(args, payload: dict, text: str) -> None:
    """Print ``payload`` as strict JSON with ``--json`` (NaN and infinities as null), else ``text``."""
    print(json.dumps(_strict(payload), allow_nan=False) if args.json else text)


def _strict(value):
    """``value`` with every non-finite float replaced by None (JSON null)."""
    if isinstance(value, float):
        return value if np.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_strict(v) for v in value]
    return value


def new_output(path: str, force: bool) -> Path:
    """``path`` as a file the command may write: a clear error if it exists and ``force`` is off,
    or if its folder does not exist."""
    out = Path(path)
    if out.exists() and not force:
        raise RcmKinError(f"{out} exists: choose another --out or add --force")
    if not out.parent.is_dir():
        raise RcmKinError(f"no folder {out.parent} for {out.name}")
    return out

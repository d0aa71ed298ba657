"""``--package-dir NAME=DIR``: where a URDF's ``package://NAME/...`` meshes are (``view``, ``export``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rcm_kin.cli.common import BadValue
from rcm_kin.errors import RcmKinError


def package_dir(text: str) -> tuple[str, str]:
    """argparse ``type`` of ``--package-dir NAME=DIR``: (NAME, DIR), ``~`` expanded."""
    name, sep, folder = text.partition("=")
    if not (sep and name.strip() and folder.strip()):
        raise BadValue(f"'{text[:60]}' is not NAME=DIR (a ROS package's name and its folder)")
    return name.strip(), str(Path(folder.strip()).expanduser())


def add_package_dirs(parser: argparse.ArgumentParser) -> None:
    """``--package-dir NAME=DIR`` (repeatable): where the URDF's ``package://NAME/...`` meshes are."""
    parser.add_argument("--package-dir", action="append", default=[], type=package_dir, metavar="NAME=DIR",
                        help="the folder of ROS package NAME, for the URDF's package://NAME/... meshes (repeatable; "
                             "ROS_PACKAGE_PATH is searched too)")


def package_dirs(args) -> dict[str, str] | None:
    """The ``--package-dir`` pairs as {NAME: DIR} (None when none is given); a folder that is not
    one, or a name given twice, is an error."""
    found: dict[str, str] = {}
    for name, folder in args.package_dir:
        if not Path(folder).is_dir():
            raise RcmKinError(f"--package-dir {name}={folder}: {folder} is not a folder")
        if found.setdefault(name, folder) != folder:
            raise RcmKinError(f"--package-dir: package '{name}' given twice ({found[name]}, {folder})")
    return found or None

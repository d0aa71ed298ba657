"""A robot's visual geometry with its meshes found: the one place a URDF's mesh files are resolved.

A URDF names a mesh by a path relative to the URDF, an absolute path, ``file://`` or
``package://NAME/rest``. A package is found through ``package_dirs`` (NAME -> the package's own
folder; the CLI's ``--package-dir NAME=DIR``), then ``ROS_PACKAGE_PATH`` (folders that are packages
or hold packages: a ``package.xml`` names each). Every problem (a package not given, a mesh file
that does not exist, a mesh Pinocchio cannot read) is one :class:`~rcm_kin.errors.RcmKinError` line.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path

import pinocchio as pin

from rcm_kin.errors import RcmKinError, read_text

PACKAGE = re.compile(r"^package://([^/]+)/(.*)$")


def _package_name(folder: Path) -> str:
    """The ``<name>`` of a ROS package folder's package.xml (the folder's name when it has none)."""
    try:
        name = ET.parse(folder / "package.xml").getroot().findtext("name")
    except (ET.ParseError, OSError):
        name = None
    return (name or folder.name).strip()


def package_folders(package_dirs: Mapping[str, str | Path] | None = None) -> dict[str, Path]:
    """Package name -> folder: ``package_dirs`` first, then the packages on ``ROS_PACKAGE_PATH``."""
    found: dict[str, Path] = {}
    for entry in filter(None, os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)):
        root = Path(entry)
        candidates = [root] if (root / "package.xml").is_file() else sorted(root.glob("*/package.xml"))
        for folder in (c if c.is_dir() else c.parent for c in candidates):
            found.setdefault(_package_name(folder), folder)
    for name, folder in (package_dirs or {}).items():
        folder = Path(folder)
        if not folder.is_dir():
            raise RcmKinError(f"package folder {folder} of '{name}' is not a folder", parameter="package_dirs")
        found[str(name)] = folder
    return found


def mesh_path(uri: str, urdf: Path, packages: Mapping[str, Path]) -> Path:
    """The file of one mesh ``uri`` of the URDF at ``urdf``, checked to exist."""
    if match := PACKAGE.match(uri):
        name, rest = match.groups()
        if name not in packages:
            raise RcmKinError(f"{urdf}: mesh {uri} is in package '{name}', which neither `package_dirs` "
                              f"({name}=DIR) nor ROS_PACKAGE_PATH gives", parameter="package_dirs")
        path = packages[name] / rest
    elif uri.startswith("file://"):
        path = Path(uri[len("file://"):])
    elif "://" in uri:
        raise RcmKinError(f"{urdf}: mesh {uri}: only relative paths, file:// and package:// are read")
    else:
        path = urdf.parent / uri
    if not path.is_file():
        raise RcmKinError(f"{urdf}: mesh file {path} (from {uri}) does not exist")
    return path.resolve()


def resolved_urdf(text: str, urdf: Path, package_dirs: Mapping[str, str | Path] | None = None) -> str:
    """The URDF ``text`` (of the file ``urdf``) with every mesh filename an absolute, existing path."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise RcmKinError(f"{urdf}: not valid XML ({exc})") from None
    meshes = list(root.iter("mesh"))
    if not meshes:
        return text
    packages = package_folders(package_dirs)
    for mesh in meshes:
        uri = mesh.get("filename")
        if not uri:
            raise RcmKinError(f"{urdf}: a <mesh> without a filename")
        mesh.set("filename", str(mesh_path(uri, urdf, packages)))
    return ET.tostring(root, encoding="unicode")


def visual_geometry(robot, package_dirs: Mapping[str, str | Path] | None = None) -> pin.GeometryModel:
    """The robot's visual geometry (Pinocchio ``GeometryModel``), its meshes resolved as the module
    says; a fresh model for the caller."""
    urdf = Path(robot.description.urdf)
    try:
        text = read_text(urdf, "URDF")
    except (OSError, UnicodeDecodeError) as exc:
        raise RcmKinError(f"cannot read the URDF {urdf}: {exc}") from None
    text = resolved_urdf(text, urdf, package_dirs)
    try:
        return pin.buildGeomFromUrdfString(robot.tree, text, pin.GeometryType.VISUAL)
    except (RuntimeError, ValueError, IndexError) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise RcmKinError(f"{urdf}: cannot read its visual geometry ({first[:200]})") from None

"""Links without inertial data: what needs masses refuses a robot that has none, and says loudly
when it assumes zero mass for some links (never a silent zero).

A link counts as massless when it is moved by a non-fixed joint (directly or through fixed
joints) and neither it nor any link fixed to it has an ``<inertial>`` element
(:attr:`Robot.massless_links`, found by the loader). Frame links on fixed joints of a massive
body are therefore not massless.
"""

from __future__ import annotations

import threading
import weakref

from rcm_kin.errors import RcmKinError, RcmKinWarning, warn
from rcm_kin.model.robot import Robot

SHOWN = 6   # links named in a message; the rest are counted

_WARNED: weakref.WeakSet = weakref.WeakSet()   # robots already warned about (once per robot)
_LOCK = threading.Lock()


def _listed(links: tuple[str, ...]) -> str:
    shown = ", ".join(links[:SHOWN])
    return shown if len(links) <= SHOWN else f"{shown}, ... ({len(links)} links)"


def has_masses(robot: Robot) -> bool:
    """True if at least one moving body of ``robot`` has inertial data."""
    bodies = {robot.tree.frames[robot.tree.getFrameId(link)].parentJoint for link in robot.massless_links}
    return len(bodies) < robot.tree.njoints - 1


def require_masses(robot: Robot, what: str) -> None:
    """Refuse ``what`` (e.g. ``"gravity"``) on a robot whose moving links all lack ``<inertial>``
    data (an :class:`~rcm_kin.errors.RcmKinError` listing them); warn once per robot
    (:class:`~rcm_kin.errors.RcmKinWarning`) when only some do: their mass is taken as zero."""
    links = robot.massless_links
    if not links:
        return
    where = robot.description.urdf
    if not has_masses(robot):
        raise RcmKinError(f"{what} needs masses: links {_listed(links)} of {where} have no <inertial>")
    with _LOCK:
        if robot in _WARNED:
            return
        _WARNED.add(robot)
    warn(f"{what} assumes zero mass for links {_listed(links)} of {where} (no <inertial>)", RcmKinWarning)

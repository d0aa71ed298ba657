"""What the nodes read from and write to ``sensor_msgs/JointState``, as plain arrays (no rclpy).

The robot's conventions (osMDV firmware, the thesis): angles in degrees and the insertion in
millimetres at the message boundary, the PSM telemetry's ``velocity`` field carrying the
commanded PWM (counts) and ``effort`` the setpoint. The CRTK convention of the dVRK
(``measured_js``, ``servo_jp``) is SI: rad and m. Inside, every number is SI (rad, m, N m).

A message the nodes cannot use (a joint missing or named twice, a field shorter than ``name``, a
non-finite value) raises :class:`MalformedMessage`; the node counts it, warns at a bounded rate and
publishes nothing for it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rcm_kin.errors import RcmKinError

CONVENTIONS = ("firmware", "crtk")
DEG = np.pi / 180.0
MM = 1e-3


class MalformedMessage(RcmKinError):
    """A JointState the node cannot use; the message says why (one line)."""


@dataclass(frozen=True)
class Units:
    """SI value = message value * factor, per joint kind: the convention's units at the boundary."""

    revolute: float
    prismatic: float
    text: str

    def factors(self, kinds) -> np.ndarray:
        return np.array([self.prismatic if k == "prismatic" else self.revolute for k in kinds])


FIRMWARE_UNITS = Units(DEG, MM, "deg, mm")
CRTK_UNITS = Units(1.0, 1.0, "rad, m")


def units_of(convention: str) -> Units:
    if convention not in CONVENTIONS:
        raise RcmKinError(f"the message convention is one of {', '.join(CONVENTIONS)}, got {convention!r}",
                          parameter="convention")
    return FIRMWARE_UNITS if convention == "firmware" else CRTK_UNITS


def joint_values(names, values, wanted: tuple[str, ...], what: str = "position") -> np.ndarray:
    """The values of the joints ``wanted`` (in that order) from a message's ``names`` and one of its
    fields ``values``; :class:`MalformedMessage` when the message cannot give them."""
    names = list(names)
    values = np.asarray(values, dtype=float)
    if values.ndim != 1 or len(values) != len(names):
        raise MalformedMessage(f"{what} has {values.size} values for {len(names)} joint names")
    index = []
    for joint in wanted:
        count = names.count(joint)
        if count != 1:
            raise MalformedMessage(f"joint '{joint}' {'missing' if count == 0 else 'named twice'} "
                                   f"(names: {', '.join(map(str, names[:8])) or 'none'})")
        index.append(names.index(joint))
    picked = values[index]
    if not np.all(np.isfinite(picked)):
        bad = [w for w, v in zip(wanted, picked) if not np.isfinite(v)]
        raise MalformedMessage(f"a non-finite {what} of {', '.join(bad)}")
    return picked


@dataclass
class Tally:
    """What a node did with its messages: used, malformed (by reason), clamped; the latency from a
    message's arrival to its answer's publication (s), kept for the last ``keep`` messages."""

    keep: int = 100_000
    received: int = 0
    published: int = 0
    clamped: int = 0
    malformed: dict[str, int] = field(default_factory=dict)
    latencies: list[float] = field(default_factory=list)

    def bad(self, reason: str) -> None:
        key = reason.split(" (")[0]
        self.malformed[key] = self.malformed.get(key, 0) + 1

    def latency(self, seconds: float) -> None:
        if len(self.latencies) < self.keep:
            self.latencies.append(seconds)

    def summary(self) -> dict:
        lat = np.array(self.latencies)
        return {"received": self.received, "published": self.published, "clamped": self.clamped,
                "malformed": sum(self.malformed.values()), "malformed_reasons": dict(self.malformed),
                "latency_median_s": float(np.median(lat)) if lat.size else None,
                "latency_p99_s": float(np.percentile(lat, 99)) if lat.size else None}

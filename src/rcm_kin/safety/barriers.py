"""Barrier functions ``B(x)`` with gradients: ``B <= 0`` is safe, ``B > 0`` unsafe (the
convention of the safety thesis). Positions in metres, in the frame of the state they are
evaluated on (the scenario's base frame). The interface is :class:`Barrier` (a ``typing.Protocol``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from rcm_kin.errors import RcmKinError


@runtime_checkable
class Barrier(Protocol):
    """What a safety filter needs of a barrier: ``value(x)`` = ``B(x)`` (safe where <= 0) and
    ``gradient(x)`` = ``dB/dx`` (same length as the state ``x``), at a state ``x`` (m)."""

    def value(self, x: np.ndarray) -> float:
        ...

    def gradient(self, x: np.ndarray) -> np.ndarray:
        ...


@dataclass(frozen=True)
class Ellipsoid:
    """A no-go ellipsoid: ``B = 1 - sum(((x - c) / r)^2)``, positive inside (thesis eq. 6.2)."""

    center: np.ndarray      # (3,) m
    radii: np.ndarray       # (3,) m

    def __post_init__(self):
        if np.shape(self.center) != (3,) or np.shape(self.radii) != (3,) or np.any(np.asarray(self.radii) <= 0):
            raise RcmKinError("an ellipsoid needs a centre and three positive radii (m)")

    def value(self, x: np.ndarray) -> float:
        return float(1.0 - np.sum(((x - self.center) / self.radii) ** 2))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        return -2.0 * (x - self.center) / self.radii**2


@dataclass(frozen=True)
class Slab:
    """Keep coordinate ``axis`` of the state inside ``[lower, upper]``: the thesis's parabola
    ``B = k (x - lower)(x - upper)`` with ``k = 16/9`` (1/m), positive outside (eq. 4.4)."""

    axis: int
    lower: float
    upper: float
    k: float = 16.0 / 9.0

    def __post_init__(self):
        if not self.lower < self.upper or self.k <= 0:
            raise RcmKinError(f"a slab needs lower < upper and k > 0, got [{self.lower}, {self.upper}], k {self.k}")

    def value(self, x: np.ndarray) -> float:
        return float(self.k * (x[self.axis] - self.lower) * (x[self.axis] - self.upper))

    def gradient(self, x: np.ndarray) -> np.ndarray:
        g = np.zeros(len(x))
        g[self.axis] = self.k * (2 * x[self.axis] - self.lower - self.upper)
        return g


@dataclass(frozen=True)
class MovingPlane:
    """The beating-heart fixture: the tool coordinate ``tool`` must stay above the surface
    coordinate ``surface`` (both state entries): ``B = x[surface] - x[tool]`` (eq. 5.9)."""

    tool: int
    surface: int

    def value(self, x: np.ndarray) -> float:
        return float(x[self.surface] - x[self.tool])

    def gradient(self, x: np.ndarray) -> np.ndarray:
        g = np.zeros(len(x))
        g[self.surface], g[self.tool] = 1.0, -1.0
        return g


def band_width(barrier: Barrier, x_edge: np.ndarray) -> float:
    """``eps = |B|`` at a point chosen on the edge of the transition band (thesis: 1 cm outside
    the unsafe set along one axis)."""
    return abs(barrier.value(np.asarray(x_edge, dtype=float)))

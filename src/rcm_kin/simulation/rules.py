"""The firmware's rules, each stated once in plain Python and NumPy.

The readable loop (:func:`rcm_kin.simulation.loop.simulate`, :mod:`rcm_kin.simulation.firmware`
and the controllers of :mod:`rcm_kin.simulation.controllers`) calls these functions; the compiled
kernel (:mod:`rcm_kin.simulation.kernel`) has one numba twin of each, written in the same order
of operations so that both engines compute the same numbers, and ``tests/simulation/test_rules.py``
holds every twin to its statement here on random inputs.

- :func:`bilinear`: the gain tables' clamped bilinear interpolation (``gain_schedule.h``), stated
  in :mod:`rcm_kin.control.gain_schedule` with the schedule it reads and named here;
- :func:`conditional_integral`: the anti-windup of every error integral;
- :func:`quantise`: the encoder's whole counts;
- :func:`velocity_estimate`: the backward difference, an EMA on the roll only;
- :func:`saturate`: the PWM limits, then whole counts.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rcm_kin.control.gain_schedule import bilinear

__all__ = ["bilinear", "conditional_integral", "quantise", "saturate", "velocity_estimate"]


def conditional_integral(integral: float, error: float, period: float, law: Callable[[float], float],
                         limit: float) -> tuple[float, float]:
    """Anti-windup by conditional integration of the error integral ``E`` (deg s) of the law
    ``u = law(E)``: keep the new integral ``E + e T`` unless the command is then beyond ``limit``
    (counts) and integrating pushed it further out. Returns ``(u, integral)``."""
    candidate = integral + error * period
    u = law(candidate)
    if abs(u) > limit and np.sign(u) == np.sign(law(candidate) - law(integral)):
        return law(integral), integral
    return u, candidate


def quantise(position: np.ndarray, count: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """What the encoders read of ``position`` (3,) (deg, deg, m): whole counts of ``count`` (3,)
    (the resolution; 0: read exactly) plus ``noise`` (3,) whole counts (zeros without noise)."""
    exact = count == 0
    counts = np.round(position / np.where(exact, 1.0, count)) + noise
    return np.where(exact, position, counts * count)


def velocity_estimate(measured: np.ndarray, previous: np.ndarray, filtered: np.ndarray, period: float,
                      roll_filter: float) -> np.ndarray:
    """The firmware's velocities (deg/s, deg/s, m/s): the backward difference of the readings
    over ``period`` s; the roll's smoothed by the EMA ``a vf + (1 - a) v_raw`` (``a = roll_filter``,
    ``vf`` the previous estimate ``filtered[0]``), the pitch's and insertion's raw."""
    raw = (measured - previous) / period
    a = roll_filter
    return np.array([a * filtered[0] + (1 - a) * raw[0], raw[1], raw[2]])


def saturate(command: np.ndarray, limit: np.ndarray, whole_counts: bool) -> np.ndarray:
    """The PWM the drivers receive of ``command`` (3,): saturated at ``+-limit`` (3,) counts, then
    truncated toward zero (a C ``int`` cast) when ``whole_counts``."""
    u = np.clip(command, -limit, limit)
    return np.trunc(u) if whole_counts else u

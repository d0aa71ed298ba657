"""The firmware's rules, each stated once in plain Python and NumPy: the one home of what the
PSM's microcontroller does with its readings and its commands.

Every model of the firmware calls these functions: the gain schedule
(:mod:`rcm_kin.control.gain_schedule`), the readable closed loop (:mod:`rcm_kin.simulation`), the
drive-train axis under its recorded law (:func:`rcm_kin.dynamics.stick_slip.simulate_axis_closed`,
which compiles :func:`quantise` and :func:`saturate` themselves with numba) and the excitation's
replay (:mod:`rcm_kin.identification.replay`). The compiled closed loop
(:mod:`rcm_kin.simulation.kernel`) has one C twin of each, written in the same order of
operations, and ``tests/simulation/test_rules.py`` holds every twin to its statement here.

- :func:`bilinear`: the gain tables' clamped bilinear interpolation (``gain_schedule.h``);
- :func:`conditional_integral`: the anti-windup of every error integral;
- :func:`quantise`: the encoder's whole counts (from zero, or from a starting angle);
- :func:`velocity_estimate`: the backward difference, an EMA on the roll only;
- :func:`saturate`: the PWM limits, then whole counts;
- :func:`p_command`, :func:`insertion_command`: the P loops (roll and pitch with the hardware
  sign, and the insertion's, which runs under every controller).

:func:`quantise`, :func:`saturate`, :func:`p_command` and :func:`insertion_command` take scalars
(and :func:`saturate` and the P laws NumPy arrays too) and use only what numba compiles.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["bilinear", "conditional_integral", "insertion_command", "interpolate", "p_command", "quantise",
           "quantise_axes", "saturate", "velocity_estimate"]


def interpolate(x: float, x0: float, x1: float, y0, y1):
    """The firmware's ``interpolate``: ``y0 + (y1 - y0) * ((x - x0) / (x1 - x0))``."""
    return y0 + (y1 - y0) * ((x - x0) / (x1 - x0))


def _cell(grid: np.ndarray, x: float) -> tuple[int, float]:
    """Cell index and the clamped coordinate: never extrapolate beyond the grid."""
    x = min(max(x, grid[0]), grid[-1])
    i = int(np.searchsorted(grid, x, side="right")) - 1
    return min(max(i, 0), len(grid) - 2), x


def bilinear(roll_grid: np.ndarray, pitch_grid: np.ndarray, table: np.ndarray, roll_deg: float, pitch_deg: float):
    """Bilinear interpolation of ``table[pitch][roll]`` (trailing dims are values), clamped to
    the grid: along roll on the two pitch rows, then along pitch, as ``gain_schedule.h`` does."""
    i, r = _cell(roll_grid, float(roll_deg))
    j, p = _cell(pitch_grid, float(pitch_deg))
    low = interpolate(r, roll_grid[i], roll_grid[i + 1], table[j, i], table[j, i + 1])
    high = interpolate(r, roll_grid[i], roll_grid[i + 1], table[j + 1, i], table[j + 1, i + 1])
    return interpolate(p, pitch_grid[j], pitch_grid[j + 1], low, high)


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


def quantise(position: float, count: float, noise: float = 0.0, origin: float = 0.0) -> float:
    """What an encoder reads of ``position``: whole counts of ``count`` (the resolution; 0: read
    exactly) from ``origin`` (where the counter was zeroed: 0, or the angle an axis started
    from), plus ``noise`` whole counts."""
    if count == 0.0:
        return position
    return origin + (np.round((position - origin) / count) + noise) * count


def quantise_axes(position: np.ndarray, count: np.ndarray, noise: np.ndarray) -> np.ndarray:
    """:func:`quantise` of each axis: ``position``, ``count`` and ``noise`` (3,) (deg, deg, m;
    noise in whole counts, zeros without noise), counted from zero."""
    return np.array([quantise(p, c, n) for p, c, n in zip(position, count, noise)])


def velocity_estimate(measured: np.ndarray, previous: np.ndarray, filtered: np.ndarray, period: float,
                      roll_filter: float) -> np.ndarray:
    """The firmware's velocities (deg/s, deg/s, m/s): the backward difference of the readings
    over ``period`` s; the roll's smoothed by the EMA ``a vf + (1 - a) v_raw`` (``a = roll_filter``,
    ``vf`` the previous estimate ``filtered[0]``), the pitch's and insertion's raw."""
    raw = (measured - previous) / period
    a = roll_filter
    return np.array([a * filtered[0] + (1 - a) * raw[0], raw[1], raw[2]])


def saturate(command, limit, whole_counts: bool = False):
    """The PWM the drivers receive of ``command`` (a number or an array): saturated at ``+-limit``
    counts (of the same shape), then truncated toward zero (a C ``int`` cast) when ``whole_counts``."""
    u = np.minimum(np.maximum(command, -limit), limit)
    return np.trunc(u) if whole_counts else u


def p_command(kp, error):
    """The P loop of the roll and pitch, hardware sign: ``u = -Kp e`` (counts) of the error ``e = r - y``."""
    return -kp * error


def insertion_command(reference: float, measured: float, kp: float) -> float:
    """The insertion's P loop under every controller: ``Kp (r - y)`` counts (``kp`` counts/m, the
    firmware's :data:`rcm_kin.hardware.INSERTION_KP`, 30 PWM/mm; a positive PWM extends the insertion)."""
    return kp * (reference - measured)

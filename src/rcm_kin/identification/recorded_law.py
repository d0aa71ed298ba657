"""The controller that ran during a closed-loop log, read back from the log itself.

The pitch PRBS experiments ran a light feedback law plus a pseudo-random binary excitation of
fixed amplitude (data README: "light LQR plus a +-15 PWM PRBS"). Where that law is linear in
the measured angle and its backward difference, the logged PWM is exactly

    u_k = offset + position_gain y_k + velocity_gain (y_k - y_k-1) / T_k + a s_k,   s_k = +-1,

so the law and the excitation's signs can be recovered from ``(y, u)`` alone: alternate a
least-squares fit of the three gains to ``u - a s`` with ``s = sign(u - law)``. A log whose
law this explains (``|u - law| = a`` to half a count on most samples) is simulated with that
law in the loop and its own excitation (:func:`rcm_kin.dynamics.stick_slip.simulate_axis_closed`):
the axis's unstable open loop is never simulated open loop, and nothing measured after the
start enters the prediction. Logs run under another law (an integrator, changing targets) are
not explained and are left out, with the fraction said.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rcm_kin.identification.records import tick_period
from rcm_kin.identification.telemetry import TelemetryLog

EXPLAINED = 0.95       # least fraction of samples the law must reproduce to EXACT counts
EXCITED = 1.0          # PWM counts: least excitation amplitude (a plain holding loop identifies nothing)
EXACT = 0.5            # PWM counts
SWEEPS = 30            # sign / least-squares alternations (they settle in a handful)
BALANCE = 0.05         # least share of samples at each level of a binary excitation


@dataclass(frozen=True)
class RecordedLaw:
    """``u = offset + position_gain y + velocity_gain dy/dt + amplitude s`` (PWM counts; y in rad,
    dy/dt the backward difference in rad/s), saturated at ``limit``."""

    offset: float            # counts
    position_gain: float     # counts/rad
    velocity_gain: float     # counts/(rad/s)
    amplitude: float         # counts: the binary excitation's
    limit: float             # counts: the firmware's saturation on this axis
    explained: float         # fraction of the log's samples reproduced to EXACT counts

    def problem(self) -> str:
        """Why this law cannot be simulated in the loop ("" when it can)."""
        if self.amplitude < EXCITED:
            return f"its controller ran without an excitation ({self.amplitude:.2f} PWM)"
        if self.explained < EXPLAINED:
            return (f"the controller that ran is not a linear law plus a binary excitation (it explains "
                    f"{100 * self.explained:.0f} % of the samples, {100 * EXPLAINED:.0f} % needed)")
        return ""

    def vector(self) -> np.ndarray:
        """``[offset, position_gain, velocity_gain, limit]``, as the closed-loop kernel takes it."""
        return np.array([self.offset, self.position_gain, self.velocity_gain, self.limit])

    def excitation(self, angle: np.ndarray, pwm: np.ndarray, period: float) -> np.ndarray:
        """The excitation (counts) on a uniform record: ``amplitude`` times the sign of what the law
        leaves of the logged PWM (``angle`` in rad, the first difference taken from rest)."""
        rate = np.r_[0.0, np.diff(angle)] / period
        law = self.offset + self.position_gain * angle + self.velocity_gain * rate
        return self.amplitude * np.where(pwm >= law, 1.0, -1.0)


def recover_law(log: TelemetryLog, joint: str, limit: float) -> RecordedLaw:
    """The best linear law with a binary excitation for ``joint`` in ``log`` (see the module
    text), each logged sample one controller tick, the difference taken over the mean logged
    interval (the firmware's period: its stamps are whole milliseconds, 2 or 3 ms around a 2.4 ms
    loop, and the law is exact only with a constant period); check :attr:`RecordedLaw.explained`
    before using it."""
    y, u = np.radians(log.position[joint]), log.pwm[joint]
    rate = np.r_[0.0, np.diff(y)] / tick_period(log)
    inside = np.abs(u) < limit - 1.0              # saturated samples tell nothing about the law
    A = np.column_stack([np.ones(inside.sum()), y[inside], rate[inside]])
    sign = np.sign(u[inside] - np.median(u[inside]))
    amplitude = 0.0
    for _ in range(SWEEPS):
        B = np.column_stack([A, sign])
        gains, *_ = np.linalg.lstsq(B, u[inside], rcond=None)
        amplitude = abs(gains[3])
        sign = np.where(u[inside] >= A @ gains[:3], 1.0, -1.0)
    if min(np.mean(sign > 0), np.mean(sign < 0)) < BALANCE:   # one level only: no excitation, the law alone
        gains, *_ = np.linalg.lstsq(A, u[inside], rcond=None)
        amplitude = 0.0
    residual = u[inside] - A @ gains[:3]
    explained = float(np.mean(np.abs(np.abs(residual) - amplitude) < EXACT)) * inside.mean()
    return RecordedLaw(float(gains[0]), float(gains[1]), float(gains[2]), float(amplitude), float(limit), explained)

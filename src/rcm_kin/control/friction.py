"""Friction-compensation feedforward: the PWM that cancels each axis's sliding Coulomb friction.

The smooth model the gains are designed on (:mod:`rcm_kin.dynamics.state_space`,
``coulomb=False``) leaves Coulomb friction out; stiction is treated separately, here, as a
feedforward on the reference. Sliding at joint velocity ``v`` the axis feels ``F_c sign(v)``
(N m; for the roll the identified link and motor Coulomb plus the presliding slip force,
``JointDrive.coulomb``), so the steady PWM that cancels it is the ``u`` with ``k_u u = F_c
sign(v)``. In the hardware sign convention ``k_u`` (N m per count,
``DriveConstants.input_gain``) is negative (a positive PWM lowers the angle), so

    u_fc = F_c sign(v) / k_u = -sign(v) F_c / |k_u|       (counts)

i.e. moving the angle up takes a NEGATIVE PWM, as the holding PWM ``g(q) / k_u`` does. The
firmware does not know the sliding direction before the axis slides, so it uses the REFERENCE
velocity ``rdot`` (deg/s), with a smooth ramp ``tanh(rdot / v_ramp)`` in place of ``sign``: no
chatter at reversals, about nothing while the reference stands still (``|rdot| << v_ramp``),
the full amplitude once it moves (``tanh(2) = 0.96`` at ``rdot = 2 v_ramp``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.dynamics.state_space import drive_constants
from rcm_kin.errors import RcmKinError

if TYPE_CHECKING:
    from rcm_kin.dynamics.state_space import DriveConstants

DEFAULT_RAMP_DEG_S = 2.0    # deg/s: v_ramp of tanh(rdot / v_ramp)


@dataclass(frozen=True)
class FrictionCompensation:
    """Sliding-friction feedforward of the roll and pitch: ``u_fc = -pwm tanh(rdot / ramp_deg_s)``.

    ``pwm``: amplitude per axis (roll, pitch), counts, >= 0: ``F_c / |k_u|``, the PWM that
    balances the sliding Coulomb friction. ``ramp_deg_s``: ``v_ramp`` (deg/s, > 0)."""

    pwm: tuple[float, float]
    ramp_deg_s: float = DEFAULT_RAMP_DEG_S

    def __post_init__(self):
        pwm = tuple(float(p) for p in self.pwm)
        if len(pwm) != 2 or not all(np.isfinite(p) and p >= 0 for p in pwm):
            raise RcmKinError(f"the friction-compensation PWM is 2 finite counts >= 0 (roll, pitch), got {self.pwm}")
        if not (np.isfinite(self.ramp_deg_s) and self.ramp_deg_s > 0):
            raise RcmKinError(f"the friction-compensation ramp is a velocity > 0 in deg/s, got {self.ramp_deg_s}")
        object.__setattr__(self, "pwm", pwm)
        object.__setattr__(self, "ramp_deg_s", float(self.ramp_deg_s))

    def feedforward(self, rdot_deg_s) -> np.ndarray:
        """PWM (2,) (roll, pitch; counts, hardware sign) for the reference velocities ``rdot_deg_s``
        (2,) in deg/s: negative for a rising reference. ``gain_schedule.h``'s
        ``rcm_friction_feedforward`` computes the same."""
        rdot = np.asarray(rdot_deg_s, dtype=float)
        return -np.asarray(self.pwm) * np.tanh(rdot / self.ramp_deg_s)


def friction_compensation(drive: DriveParameters | DriveConstants,
                          ramp_deg_s: float = DEFAULT_RAMP_DEG_S) -> FrictionCompensation:
    """The compensation of the smooth model's sliding Coulomb friction: per axis (roll, pitch)
    ``F_c / |k_u|`` counts with ``F_c`` = ``coulomb`` (N m) and ``k_u`` = ``input_gain`` (N m per
    count) of the drive parameters or of a model's :class:`DriveConstants` (DRIVEN order)."""
    constants = drive_constants(drive) if isinstance(drive, DriveParameters) else drive
    if np.any(constants.input_gain[:2] >= 0):
        raise RcmKinError("the friction compensation is written for the PSM's hardware sign (a positive PWM lowers "
                          "roll and pitch, pwm_sign = -1); this drive has another")
    pwm = np.asarray(constants.coulomb[:2], dtype=float) / np.abs(constants.input_gain[:2])
    return FrictionCompensation((float(pwm[0]), float(pwm[1])), ramp_deg_s)

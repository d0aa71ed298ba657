"""The identified drive-train parameters of one axis (the stick-slip model's,
:mod:`rcm_kin.dynamics.stick_slip`), in a module of their own so that reading a drive parameter
file does not load the model's compiled kernels (numba)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np


@dataclass(frozen=True)
class AxisFriction:
    """Identified drive-train parameters of one axis (joint-referred SI; PWM in counts)."""

    extra_inertia: float = 0.0         # kg m^2 the CAD lacks, on the link side
    viscous: float = 0.0               # N m s/rad, link side (back-EMF damping is the drive's)
    coulomb: float = 0.0               # N m, link side, sliding
    static: float = 0.0                # N m, link side, break-away (below coulomb: taken as coulomb)
    stribeck_velocity: float = 0.01    # rad/s
    presliding_stiffness: float = 0.0  # N m/rad at angle 0
    presliding_slope: float = 0.0      # 1/rad: k_p(q) = k_p0 exp(slope q)
    presliding_force: float = 0.0      # N m: where the presliding spring slips
    cable_stiffness: float = 0.0       # N m/rad; 0: rigid drive (one body)
    cable_damping: float = 0.0         # N m s/rad
    motor_coulomb: float = 0.0         # N m (joint-referred)
    motor_viscous: float = 0.0         # N m s/rad (joint-referred), beyond back-EMF

    def vector(self) -> np.ndarray:
        """The parameters in field order, as the integration kernels take them."""
        return np.array([getattr(self, f.name) for f in fields(self)], dtype=float)

    def as_dict(self) -> dict:
        return asdict(self)

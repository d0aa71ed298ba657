"""The identified drive-train parameters of one axis (the stick-slip model's,
:mod:`rcm_kin.dynamics.stick_slip`) and the model's integration constants and state layout, in a
module of their own so that reading a drive parameter file, or running the compiled closed loop
(whose C twin of the model takes these numbers: :mod:`rcm_kin.simulation.kernel`), does not load
the model's numba kernels."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np

from rcm_kin.errors import RcmKinError

MAX_ELEMENTS = 4   # presliding (Maxwell-slip) elements at most: the kernels' state holds this many anchors
STATE_SIZE = 4 + MAX_ELEMENTS   # one axis's state [theta, w, q, v, z_1 .. z_MAX_ELEMENTS]; unused anchors ignored
SUBSTEP = 2.5e-4   # s: integration step
COUPLING_SWEEPS = 4   # block Gauss-Seidel sweeps of the motor-cable-link step: each contracts the coupling
                      # error by h^2 k_c / (J_m + h^2 k_c) x h^2 k_c / M (< 0.03 up to k_c = 1e6 N m/rad)
# (stick_slip's numba kernels freeze MAX_ELEMENTS and COUPLING_SWEEPS when compiled, and numba keys its cache on
# stick_slip.py alone: a change here needs stick_slip.py touched; the C kernel's key includes them)
DISCRETE = ("presliding_elements",)   # model choices (whole numbers): never searched, sampled or differenced


@dataclass(frozen=True)
class AxisFriction:
    """Identified drive-train parameters of one axis (joint-referred SI; PWM in counts).

    The presliding spring is ``presliding_elements`` = N Maxwell-slip (Iwan) elements in
    parallel: each of stiffness ``k_p(q) / N``, element i (1..N) slipping at
    ``F_p 2 i / (N (N + 1))``, so that the total stiffness is ``k_p`` and the forces sum to ``F_p``
    (the whole spring's saturation force); N = 1 is the single elasto-plastic spring, larger N
    softens it gradually instead of at one cliff. N is a model choice, never fitted
    (:data:`DISCRETE`)."""

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
    presliding_elements: float = 1.0   # Maxwell-slip elements of the presliding spring, a whole 1..MAX_ELEMENTS
                                       # (a float so that vector() stays a float array)

    def __post_init__(self) -> None:
        n = self.presliding_elements
        number = isinstance(n, (int, float, np.integer, np.floating))
        if not (number and float(n).is_integer() and 1 <= n <= MAX_ELEMENTS):
            raise RcmKinError(f"presliding_elements must be a whole number 1 to {MAX_ELEMENTS}, got {n!r}",
                              parameter="presliding_elements")

    def vector(self) -> np.ndarray:
        """The parameters in field order, as the integration kernels take them."""
        return np.array([getattr(self, f.name) for f in fields(self)], dtype=float)

    def as_dict(self) -> dict:
        return asdict(self)


def substep_count(period: float) -> int:
    """Integration substeps (each at most :data:`SUBSTEP` s) in one ``period`` s."""
    return max(1, int(np.ceil(period / SUBSTEP - 1e-9)))

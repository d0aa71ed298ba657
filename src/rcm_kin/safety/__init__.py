"""Safety of automated motion: control barrier functions on the tool tip (a safety filter on
top of any nominal controller) and sum-of-squares barrier certificates for linear closed loops,
after the da Vinci safety thesis (AAU 2015; project digest) and Wieland and Allgower."""

import lazy_loader

__all__ = [
    "Barrier", "Ellipsoid", "MovingPlane", "Slab", "blended_control", "cbf_qp", "find_certificate", "run_scenario",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "barriers": ["Barrier", "Ellipsoid", "Slab", "MovingPlane"],
        "cbf": ["blended_control", "cbf_qp"],
        "scenarios": ["run_scenario"],
        "sos": ["find_certificate"],
    },
)

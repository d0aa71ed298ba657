"""CasADi transcription of Pinocchio trees and closed chains, and their compilation to C."""

import lazy_loader

__all__ = ["closed_chain_rnea", "map_points", "rk4_map", "single_call", "tree_functions"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "tree": ["tree_functions"],
        "closed_chain": ["closed_chain_rnea"],
        "integrators": ["rk4_map"],
        "compiled": ["map_points", "single_call"],
    },
)

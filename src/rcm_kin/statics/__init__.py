"""Statics: what it takes to hold a pose (holding-effort maps, counterweight design)."""

import lazy_loader

__all__ = [
    "CounterweightDesign", "GravityMap", "HoldingEffort", "design_counterweights", "gravity_map", "holding_effort",
    "write_gravity_maps",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "maps": ["GravityMap", "HoldingEffort", "gravity_map", "holding_effort", "write_gravity_maps"],
        "counterweights": ["CounterweightDesign", "design_counterweights"],
    },
)

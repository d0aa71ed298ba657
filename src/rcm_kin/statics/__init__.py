"""Statics: what it takes to hold a pose (holding effort, torque maps of any robot, counterweight design)."""

import lazy_loader

__all__ = [
    "CounterweightDesign", "CounterweightPlacement", "GravityMap", "HoldingEffort", "TorqueMap",
    "design_counterweights", "gravity_map", "holding_effort", "place_counterweight", "torque_map",
    "write_gravity_maps", "write_torque_map",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "maps": ["GravityMap", "HoldingEffort", "gravity_map", "holding_effort", "write_gravity_maps"],
        "holding": ["TorqueMap", "torque_map", "write_torque_map"],
        "counterweights": ["CounterweightDesign", "CounterweightPlacement", "design_counterweights",
                           "place_counterweight"],
    },
)

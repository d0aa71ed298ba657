"""Closed-loop simulation of the PSM firmware on the nonlinear driven-joint model."""

import lazy_loader

__all__ = [
    "Controller", "FirmwareSettings", "Hold", "LoopLaw", "SimulationResult", "closed_loop", "experiment_reference",
    "make_controller", "run_experiment", "simulate", "tracking_metrics",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "loop": ["SimulationResult", "simulate", "tracking_metrics"],
        "controllers": ["Controller", "make_controller", "Hold"],
        "experiments": ["run_experiment", "closed_loop", "experiment_reference"],
        "firmware": ["FirmwareSettings"],
        "kernel_forms": ["LoopLaw"],
    },
)

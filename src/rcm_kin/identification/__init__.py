"""System identification of the PSM from telemetry logs: black-box transfer functions and the
grey-box fit of the physics model"s drive parameters."""

import lazy_loader

__all__ = ["TelemetryLog", "calibrate", "design_excitation", "fit_greybox", "fit_transfer_function", "load_telemetry"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "telemetry": ["TelemetryLog", "load_telemetry"],
        "calibration": ["calibrate"],
        "transfer_function": ["fit_transfer_function"],
        "greybox": ["fit_greybox"],
        "excitation": ["design_excitation"],
    },
)

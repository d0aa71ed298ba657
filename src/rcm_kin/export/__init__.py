"""Writers of the robot models in other tools" formats."""

import lazy_loader

__all__ = ["OWN_DRIVE", "calibrated_robot", "export_drive", "write_mjcf"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "calibrated": ["OWN_DRIVE", "calibrated_robot", "export_drive"],
        "mjcf": ["write_mjcf"],
    },
)

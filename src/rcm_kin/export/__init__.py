"""Writers of the robot models in other tools" formats."""

import lazy_loader

__all__ = ["calibrated_robot", "write_mjcf"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "calibrated": ["calibrated_robot"],
        "mjcf": ["write_mjcf"],
    },
)

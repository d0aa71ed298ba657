"""Model code for other targets: plain C99 for the firmware (:mod:`rcm_kin.codegen.c99`,
:mod:`rcm_kin.codegen.psm_model`)."""

import lazy_loader

__all__ = ["c_function", "export_c", "write_gain_schedule"]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "c99": ["c_function"],
        "psm_model": ["export_c"],
        "firmware_export": ["write_gain_schedule"],
    },
)

"""Model code for other targets: plain C99 for the firmware (:mod:`rcm_kin.codegen.c99`,
:mod:`rcm_kin.codegen.psm_model`)."""

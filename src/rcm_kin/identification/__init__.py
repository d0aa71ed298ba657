"""System identification of the PSM from telemetry logs: black-box transfer functions and the
grey-box fit of the physics model's drive parameters."""

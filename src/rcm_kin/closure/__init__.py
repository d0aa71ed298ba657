"""Where the loops are closed: the sidecar format, the constrained model and the reduced model.

- :mod:`description`: reading ``urdf/<robot>.toml`` (actuated joints, frames, loops, passive relations)
- :mod:`constrained`: the open tree plus Pinocchio constraint models joining each cut bar
- :mod:`reduced`: the model in actuated coordinates (passive joints as Pinocchio mimic joints)
"""

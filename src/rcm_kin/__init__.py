"""rcm-kin: models of da Vinci-style RCM surgical robots in Pinocchio and CasADi, turned into
controllers.

The public API is this module's names (``import rcm_kin as rk``); they are imported lazily
(PEP 562), so ``import rcm_kin`` and ``rcm-kin --help`` stay light. Each subpackage's
``__all__`` lists its own public names; every other module path is internal and may change.

>>> import rcm_kin as rk
>>> psm = rk.load_robot("psm")
>>> tmap = rk.gravity_map(psm, roll_deg=[-10, 0, 10], pitch_deg=[0, 5], insertion=0.08)
>>> tmap.sel(roll=10, pitch=5).pwm.shape
(3,)
"""

from __future__ import annotations

import lazy_loader

__version__ = "0.1.0"

# the public API, by the subpackage that defines each name
_API = {
    "errors": ["RcmKinError", "JointLimitError", "ParameterFileError", "WorkLimitError", "LogDataError",
               "NonFiniteResultError", "RcmKinWarning", "CompilerFallbackWarning", "EngineFallbackWarning",
               "LogDataWarning"],
    "model": ["Robot", "RobotData", "load_robot", "robot_names", "joint_table", "gravity_torque"],
    "kinematics": ["forward_kinematics", "inverse_kinematics"],
    "dynamics": ["load_drive_parameters", "driven_dynamics", "holding_pwm"],
    "statics": ["GravityMap", "gravity_map", "holding_effort", "TorqueMap", "torque_map", "place_counterweight"],
    "control": ["linearize", "linearize_grid", "schedule_gains"],
    "simulation": ["simulate", "run_experiment", "tracking_metrics"],
    "visualization": ["robot_view", "show", "write_html"],
    "report": ["write_report"],
}

__all__ = sorted(name for names in _API.values() for name in names)

SUBPACKAGES = ["codegen", "control", "dynamics", "export", "identification", "kinematics", "model", "robustness",
               "safety", "simulation", "statics", "symbolic", "visualization"]

__getattr__, __dir__, _ = lazy_loader.attach(__name__, submodules=SUBPACKAGES, submod_attrs=_API)

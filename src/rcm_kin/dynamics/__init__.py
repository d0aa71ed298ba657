"""Dynamics of the actuated joints: the drive from joint torque to PWM (a robot's drive file), and the
model of any robot's joints, PWM input through its drive or torque input on its URDF inertias."""

import lazy_loader

__all__ = [
    "AxisFriction", "DriveEffort", "DriveParameters", "DrivenDynamics", "drive_effort", "driven_dynamics",
    "holding_pwm", "load_drive_parameters", "model_label", "robot_drive", "simulate_axis", "write_parameters",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submodules=["stick_slip"],      # ``dynamics.stick_slip``: the numba model, loaded on first use
    submod_attrs={
        "drive": ["DriveParameters", "DriveEffort", "load_drive_parameters", "write_parameters", "drive_effort",
                  "robot_drive", "model_label"],
        "state_space": ["DrivenDynamics", "driven_dynamics", "holding_pwm"],
        "stick_slip": ["simulate_axis"],
        "axis_friction": ["AxisFriction"],
    },
)

"""Dynamics of the actuated joints: gravity (here), and the drive from joint torque to PWM."""

import lazy_loader

__all__ = [
    "AxisFriction", "DriveEffort", "DriveParameters", "DrivenDynamics", "drive_effort", "driven_dynamics",
    "holding_pwm", "load_drive_parameters", "simulate_axis", "write_parameters",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "drive": ["DriveParameters", "DriveEffort", "load_drive_parameters", "write_parameters", "drive_effort"],
        "state_space": ["DrivenDynamics", "driven_dynamics", "holding_pwm"],
        "stick_slip": ["simulate_axis"],
        "axis_friction": ["AxisFriction"],
    },
)

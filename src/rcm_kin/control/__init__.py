"""Linear models and controller design: linearisation, LQR/LQI gain schedules, stability of the firmware loop."""

import lazy_loader

__all__ = [
    "GainSchedule", "Linearization", "LinearizationGrid", "Weights", "friction_compensation",
    "linearize", "linearize_grid", "schedule_gains", "schedule_joints", "scheduled_gains", "stability_survey",
    "zero_order_hold",
]

__getattr__, __dir__, _ = lazy_loader.attach(
    __name__,
    submod_attrs={
        "linearization": ["Linearization", "LinearizationGrid", "linearize", "linearize_grid", "zero_order_hold"],
        "gain_schedule": ["GainSchedule", "schedule_gains", "scheduled_gains"],
        "joint_schedule": ["schedule_joints"],
        "weights": ["Weights"],
        "stability": ["stability_survey"],
        "friction": ["friction_compensation"],
    },
)

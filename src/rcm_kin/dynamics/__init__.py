"""Dynamics of the actuated joints: gravity (here), and the drive from joint torque to PWM."""

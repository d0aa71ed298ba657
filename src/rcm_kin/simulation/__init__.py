"""Closed-loop simulation of the PSM firmware on the nonlinear driven-joint model."""

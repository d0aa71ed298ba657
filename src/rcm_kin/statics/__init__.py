"""Statics: what it takes to hold a pose (gravity maps, counterweight design, calibration of the drive on measured holds)."""

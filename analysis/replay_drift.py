"""Why the excitation's replay closes a P loop around its feedforward: the roll's designed
excitation (60 s, the shipped drive train) on the stick-slip model, the feedforward alone against
the feedforward plus the thesis's P loop (:func:`rcm_kin.identification.replay.closed_loop_record`).

    python analysis/replay_drift.py

Prints the RMS of the angle off the setpoint (deg) both ways: the smooth feedforward does not know
the presliding spring and the cable, and the open-loop angle drifts away (docs/findings.md,
"Excitation design").
"""

import numpy as np

from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.dynamics.stick_slip import axis_plant, simulate_axis
from rcm_kin.hardware import FIRMWARE_PERIOD
from rcm_kin.identification.drive_train import at_rest
from rcm_kin.identification.excitation import base_model, design_excitation
from rcm_kin.identification.replay import HOLD_POSE

params = load_drive_parameters()
excitation = design_excitation(60.0, ["roll"])
setpoint, feedforward = excitation.setpoint[:-1, 0], excitation.pwm[:-1, 0]
friction = params.drive_train["roll"]
plant, state = at_rest(friction, axis_plant(base_model(params), "roll", HOLD_POSE), setpoint[0], feedforward[0])
angle = np.r_[setpoint[0], simulate_axis(friction, plant, feedforward[:-1], FIRMWARE_PERIOD, state)]
open_loop = np.degrees(np.sqrt(np.mean((angle - setpoint) ** 2)))
closed_loop = np.degrees(excitation.joints["roll"].tracking_rms)
print(f"roll, feedforward alone: {open_loop:.2f} deg RMS off the setpoint; with the P loop: {closed_loop:.2f} deg RMS")

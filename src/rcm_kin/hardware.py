"""The one home of the PSM hardware and firmware numbers that are not robot geometry.

Geometry, masses and joint limits live in the URDF (``urdf/generate.py`` writes it); drive
constants that a user calibrates live in ``urdf/psm_drive.toml``. What is left, the
fixed numbers of the electronics and the flashed firmware, is here, each with its source.
Arrays are ordered (roll, pitch, insertion).
"""

from __future__ import annotations

import numpy as np

# --- driver and firmware (thesis ch. 4, firmware listings 4.15; robot-parameters.md "drive") ---
DRIVER_PWM_RANGE = 255.0                         # counts: 8-bit sign-magnitude driver, |u| <= 255
PWM_LIMIT = np.array([100.0, 150.0, 100.0])      # counts: firmware saturation per axis
FIRMWARE_PERIOD = 1.0 / 400.0                    # s: control loop (about 400 Hz, 2.4 ms measured)
ROLL_FILTER = 0.9                                # EMA coefficient of the roll velocity estimate
INSERTION_KP = 30.0e3                            # counts/m: insertion P loop, 30 PWM per mm
P_GAINS = (35.0, 60.0)                           # counts/deg: the thesis's baseline P (roll, pitch)

# --- encoders (HEDS-5540 on the motors, behind the capstans) ---
ENCODER_COUNT = np.array([0.009, 0.0135, 0.030e-3])   # deg, deg, m per count

# --- the working pose ---
HOME_INSERTION = 0.080                           # m: insertion of the thesis experiments and holds
PITCH_REST_DEG = -35.0675                        # deg: the pitch resting on its lower stop, as the single-axis roll
                                                 # experiments rest it (psm-sysid/single-axis/roll_step.csv logs
                                                 # -35.0675 throughout; data README: "pitch resting on its lower stop")

# --- osMDV counterweight design (brass), as built ---
MAIN_COUNTERWEIGHT = (2.63, 0.20028)             # kg, m below the main (roll) axis on the roll body
DPM_COUNTERWEIGHT = (1.65, 0.15010, np.radians(7.95))   # kg, m from the pitch pivot, rad offset

"""The numbers quoted from the thesis, in one place, each with its source.

The thesis: L. Nolan, *Implementing Adaptive Control in ROS 2 for a Laparoscopic Surgical
Robotic Test Platform*, MSc thesis, MCI Innsbruck. Section and page numbers follow its table
of contents; the values were read from the thesis and its firmware (collected in the
reference sheet ``robot-parameters.md``). Every value used by the library or the report
comes from here; :data:`SOURCES` names where each constant is printed.

The robot's own hardware numbers (counterweights as built, firmware limits, the home
insertion) live in :mod:`rcm_kin.hardware`; this module only says where the thesis and the
osMDV design quote them.

Gain tables: the thesis labels its rows pitch -20/0/+20 and its columns roll -15/0/+15, but
identified them on the grid pitch {-15, 0, 15} x roll {-20, 0, 20}; the arrays here are indexed
``[pitch, roll]`` on that grid (``rcm_kin.control.gain_schedule.THESIS_PITCH_DEG`` x
``THESIS_ROLL_DEG``). Units and signs are the firmware's: PWM/deg, PWM/(deg/s), PWM/(deg s),
``u = -(Kp e + Kd v [+ Ki int e])`` with ``e = r - y``.
"""

from __future__ import annotations

import numpy as np

from rcm_kin.hardware import DPM_COUNTERWEIGHT, MAIN_COUNTERWEIGHT

# --- gain schedule, thesis Tables 4.4-4.8 (Sec. 4.3.3 gain scheduling, Sec. 4.3.4 LQR and LQI) ---
KP_ROLL = np.array([[135.41, 135.41, 137.91], [136.23, 132.23, 130.12], [137.36, 135.77, 131.78]])
KD_ROLL = np.array([[0.6527, 1.0829, 0.43766], [0.6854, 0.7588, 0.4810], [0.6579, 1.0788, 0.42543]])
KP_PITCH = np.array([[188.07, 195.37, 191.11], [161.41, 166.32, 167.01], [153.37, 155.56, 151.23]])
KD_PITCH = np.array([[0.3124, 0.3256, 0.3154], [0.3671, 0.3671, 0.3272], [0.3643, 0.3374, 0.3576]])
KI_PITCH = np.array([[0.143744, 0.185649, 0.164665], [0.135649, 0.153566, 0.155123],
                     [0.124432, 0.155649, 0.134566]])
K_ROLL = np.stack([KP_ROLL, KD_ROLL], axis=-1)                # (pitch, roll, [Kp, Kd])
K_PITCH = np.stack([KP_PITCH, KD_PITCH, KI_PITCH], axis=-1)   # (pitch, roll, [Kp, Kd, Ki])

# --- identified roll model at roll = pitch = 0, PWM -> deg (Sec. 4.2.1 step response; the
# model the LQR of Sec. 4.3.4 was designed on): G(s) = (4.0426 s - 8.3312) / (s^2 + 6.1202 s + 16.288)
ROLL_TF = (np.array([4.0426, -8.3312]), np.array([1.0, 6.1202, 16.288]))

# --- tracking experiments (Sec. 5.1 overview, Sec. 5.2.1 sinusoid, Sec. 5.2.2 target following) ---
SINE_AMPLITUDE_DEG = (20.0, 15.0)    # roll, pitch amplitude (deg), together
SINE_CYCLE_S = 3.0                   # s, period of both sinusoids
# measured on the robot, sinusoid: (max, mean) absolute tracking error (deg) per controller and axis
SINE_TRACKING_ERROR_DEG = {("p", "roll"): (1.17, 0.62), ("p", "pitch"): (2.31, 1.52),
                           ("scheduled", "roll"): (0.41, 0.21), ("scheduled", "pitch"): (0.35, 0.12)}

# --- figures of the thesis the report draws again from the model ---
FIGURES = {"roll_holding": "Fig 4.6", "pitch_holding": "Fig 4.7",
           "tracking": "Figs 5.2-5.5 and 5.8-5.9", "error_comparison": "Figs 5.6/5.7 and 5.10/5.11"}

# --- osMDV counterweights as built, quoted beside the designs (values: rcm_kin.hardware) ---
OSMDV_COUNTERWEIGHTS = {"main": MAIN_COUNTERWEIGHT, "dpm": DPM_COUNTERWEIGHT}

SOURCES = {
    "K_ROLL": "thesis Tables 4.4-4.8 (roll Kp, Kd), Sec. 4.3.3-4.3.4",
    "K_PITCH": "thesis Tables 4.4-4.8 (pitch Kp, Kd, Ki), Sec. 4.3.3-4.3.4",
    "ROLL_TF": "thesis Sec. 4.2.1 (roll open-loop step response), used in Sec. 4.3.4",
    "SINE_AMPLITUDE_DEG": "thesis Sec. 5.1 and 5.2.1",
    "SINE_CYCLE_S": "thesis Sec. 5.1 and 5.2.1",
    "SINE_TRACKING_ERROR_DEG": "thesis Sec. 5.2.1 (sinusoidal path following, measured)",
    "FIGURES": "thesis List of Figures (Ch. 4 gravity, Ch. 5 experiments)",
    "OSMDV_COUNTERWEIGHTS": "osMDV design repository, counterweight fits (robot-parameters.md, Counterweights)",
}

"""The excitation's replay: what a log of it would show (the CSV the firmware plays back is
written by :func:`rcm_kin.identification.excitation.write_excitation`).

The stick-slip model's predicted standard errors come from the log a replay would record,
simulated on the shipped model: the firmware's PWM, the feedforward plus the thesis's P loop on
the setpoint (the model alone on the feedforward drifts off the setpoint: the smooth feedforward
does not know the presliding spring and the cable; measured: docs/findings.md, "Excitation
design"), and the angle it gives; Gauss-Newton standard errors of the model's free parameters at the shipped values
(:func:`rcm_kin.identification.drive_train.predicted_standard_errors`), with the encoder's
quantisation (one count / sqrt(12) RMS per sample) as the only noise: lower bounds, for
comparing designs; on real logs the model's own error dominates.
"""

from __future__ import annotations

import numpy as np

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters
from rcm_kin.dynamics.stick_slip import axis_plant, simulate_axis
from rcm_kin.firmware_rules import p_command, saturate
from rcm_kin.hardware import ENCODER_COUNT, FIRMWARE_PERIOD, HOME_INSERTION, P_GAINS, PWM_LIMIT
from rcm_kin.identification.drive_train import AxisLog, at_rest, predicted_standard_errors

JOINTS = ("roll", "pitch")
HOLD_POSE = np.array([0.0, 0.0, HOME_INSERTION])


def closed_loop_record(friction, plant, joint: str, setpoint: np.ndarray, feedforward: np.ndarray,
                       period: float = FIRMWARE_PERIOD) -> tuple[np.ndarray, np.ndarray]:
    """What a log of the replay would record on the stick-slip model (rad, counts): from rest at
    ``setpoint[0]``, each period the firmware reads the angle and sends ``feedforward - Kp
    (setpoint - angle)`` (the thesis's P gain, :data:`rcm_kin.hardware.P_GAINS`, the firmware's
    :func:`~rcm_kin.firmware_rules.p_command`), saturated at :data:`PWM_LIMIT`
    (:func:`~rcm_kin.firmware_rules.saturate`). In :func:`predict_log`'s sample convention, so that it reproduces the
    record from the recorded PWM."""
    i = DRIVEN.index(joint)
    plant, state = at_rest(friction, plant, setpoint[0], feedforward[0])
    angle, pwm = np.empty(setpoint.size), np.empty(setpoint.size)
    angle[0], pwm[0] = setpoint[0], feedforward[0]
    for k in range(1, setpoint.size):
        angle[k] = simulate_axis(friction, plant, pwm[k - 1:k], period, state)[0]
        error = np.degrees(setpoint[k] - angle[k])
        pwm[k] = saturate(feedforward[k] + p_command(P_GAINS[i], error), PWM_LIMIT[i])
    return angle, pwm


def stick_slip_errors(model, params: DriveParameters, joint: str, setpoint: np.ndarray,
                       feedforward: np.ndarray) -> tuple[dict, np.ndarray]:
    """The shipped drive train's predicted standard errors from the log of the replay of
    ``setpoint`` (rad) with ``feedforward`` (counts) (:func:`closed_loop_record`), its angle
    measured with the encoder's quantisation noise; and the recorded angle (rad)."""
    friction = params.drive_train[joint]
    plant = axis_plant(model, joint, HOLD_POSE)
    angle, pwm = closed_loop_record(friction, plant, joint, setpoint, feedforward)
    log = AxisLog(f"excitation ({joint})", joint, FIRMWARE_PERIOD, pwm, angle, HOLD_POSE.copy())
    noise = np.radians(ENCODER_COUNT[DRIVEN.index(joint)]) / np.sqrt(12)
    return predicted_standard_errors(friction, [plant], [log], noise), angle

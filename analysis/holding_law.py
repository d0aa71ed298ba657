"""How the robot's firmware held the pitch while the roll stepped: its law, read back from the
pitch columns of the roll-step logs, and how much of the holding PWM its integral carried.

    python analysis/holding_law.py ../shared/data/psm-sysid/roll-step

During each roll step the pitch is held at its nominal angle (the file name's ``pitch_P``) by the
firmware's LQI ``u = -(Kp e + Kd v + Ki E)``, ``e = r - y``, ``v`` the backward difference of the
angle over the mean logged interval, ``E`` the error integral. The logged PWM is the controller's
float output, so a least-squares fit of ``u`` on ``[1, y, v, int y dt, t]`` reads the law back
(``Kp`` the ``y`` coefficient, ``Kd`` minus the ``v`` one, ``Ki`` the ``int y dt`` one; the
constant and the time slope hold the unknown setpoint and the integral's start). Taking the
setpoint ``r`` as the file name's nominal angle (an assumption: the logs do not record it, and the
fit's own time slope pins it poorly), the proportional share of the holding PWM is
``-Kp (r - mean y)`` and the rest is the integral's. At (0, 0), where the robot rests between
experiments and the sinusoid starts, the integral carries the whole holding PWM with the pitch
0.03 deg from its setpoint (the steady hold the simulated experiments start from,
:class:`rcm_kin.simulation.controllers.Hold`); at the poses visited only for a step the pitch
sits 0.26-0.54 deg from its nominal angle and the split there is not settled.
"""

from __future__ import annotations

import argparse
import os
import re

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from rcm_kin.errors import RcmKinError  # noqa: E402
from rcm_kin.identification.records import tick_period  # noqa: E402
from rcm_kin.identification.telemetry import load_telemetry, telemetry_files  # noqa: E402


def holding_law(path, log=None) -> dict:
    """The pitch law of one roll-step log (``log``: the file at ``path`` already read) and the split
    of its mean PWM (counts)."""
    named = re.search(r"pitch_(-?\d+)", path.name)
    if named is None:
        raise RcmKinError(f"{path.name}: the nominal pitch is read from the name (..._pitch_P.csv); rename the log")
    log = log or load_telemetry(path)
    t, y, u = log.time, log.position["pitch"], log.pwm["pitch"]
    v = np.r_[0.0, np.diff(y)] / tick_period(log)
    integral = np.r_[0.0, np.cumsum(y[1:] * np.diff(t))]
    X = np.column_stack([np.ones_like(t), y, v, integral, t])
    coef, *_ = np.linalg.lstsq(X, u, rcond=None)
    nominal = float(named.group(1))
    proportional = -coef[1] * (nominal - float(np.mean(y)))
    return {"log": path.name, "Kp": coef[1], "Kd": -coef[2], "Ki": coef[3],
            "residual_rms": float(np.sqrt(np.mean((u - X @ coef) ** 2))), "mean_pwm": float(np.mean(u)),
            "offset_deg": float(np.mean(y)) - nominal, "proportional": proportional,
            "integral": float(np.mean(u)) - proportional}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="the roll-step logs (roll_step_response_roll_R_pitch_P.csv)")
    args = parser.parse_args()
    print(f"{'log':<42} {'Kp':>7} {'Kd':>6} {'Ki':>6} {'rms':>6} {'PWM':>7} {'y-r':>6} {'P':>6} {'I':>7}")
    for path in telemetry_files(args.folder, "roll_step_response_*"):
        log = load_telemetry(path)
        if np.ptp(log.position["pitch"]) == 0:
            print(f"{path.name:<42} the pitch never leaves one encoder count: its law cannot be read back")
            continue
        try:
            h = holding_law(path, log)
        except RcmKinError as exc:
            parser.exit(2, f"error: {exc}\n")
        print(f"{h['log']:<42} {h['Kp']:7.1f} {h['Kd']:6.3f} {h['Ki']:6.3f} {h['residual_rms']:6.3f} "
              f"{h['mean_pwm']:7.1f} {h['offset_deg']:6.2f} {h['proportional']:6.1f} {h['integral']:7.1f}")


if __name__ == "__main__":
    main()

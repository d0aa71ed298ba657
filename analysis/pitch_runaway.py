"""The one fast pitch record: an upper bound on the pitch's damping at speed, from the runaway
at the end of the PWM ramp log.

    python analysis/pitch_runaway.py ../shared/data/psm-sysid/single-axis/pitch_speed_ramp_down_response.csv

The log ramps the pitch PWM open loop (0, -1, -2, ... counts, one step per ~0.1 s). Near -115
counts the pitch breaks away and swings through about 70 deg to its far stop, peaking at about
130 deg/s, four times the tracking sinusoid's 31 deg/s and ten times anything in the closed-loop
records. Its position column holds raw encoder counts (data README); a negative PWM raises the
pitch (hardware sign -1), so the angle is ``-counts / (2000 * 13.333 / 360)`` deg.

At the speed peak the acceleration passes through zero, so the drive torque ``|k_u u|`` balances
damping, gravity and friction there. Coulomb friction opposes motion, and gravity is assumed to
oppose the rising pitch at the peak: the model's holding PWM is negative over its whole range
(-30 to +30 deg: about -100 to -37 PWM), but the swing covers 74 deg from an unknown start (the
counts start where the arm was powered on) and the peak comes 55 deg after it. Then
``(b_emf + b) v_peak <= |k_u u|``: an upper bound on the viscous friction ``b`` beyond the
motor's back-EMF. ``k_u`` carries the calibrated volts per PWM, whose +-15 % uncertainty the
bound shares.

The computation is the library's (:func:`rcm_kin.identification.speed_bounds.damping_bound`), where
``rcm-kin identify --joint pitch`` takes it as a constraint when the ramp log is among its logs.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.identification.speed_bounds import damping_bound  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", help="pitch_speed_ramp_down_response.csv")
    b = damping_bound(parser.parse_args().log, load_drive_parameters())
    print(f"speed peak {b['speed_deg_s']:.0f} deg/s at t = {b['time_s']:.2f} s under {b['pwm']:.0f} PWM "
          f"(travel {b['travel_deg']:.1f} deg)")
    print(f"back-EMF damping {b['back_emf']:.3f} N m s/rad; viscous friction beyond it <= "
          f"{b['viscous_bound']:.2f} N m s/rad")


if __name__ == "__main__":
    main()

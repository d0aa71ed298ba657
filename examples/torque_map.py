"""A holding-effort map of the PSM: the torque, motor voltage and PWM that hold each pose of a
roll x pitch grid against gravity, read at one pose and saved as tables.

    python examples/torque_map.py OUT_DIR      (default: a new temporary folder)

Angles of the grid are degrees, the insertion metres; torques N m (insertion N), voltages V,
PWM in driver counts with the hardware sign (a positive PWM lowers roll and pitch).
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import rcm_kin as rk

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="torque_map_"))
out.mkdir(parents=True, exist_ok=True)

# the robot (URDF + sidecar: the closed parallelogram) and its calibrated drive parameters
psm = rk.load_robot("psm")
drive = rk.load_drive_parameters()

# the map: every pose of roll x pitch at one insertion, through the drive model
roll = np.linspace(-30, 30, 61)        # deg
pitch = np.linspace(-30, 30, 61)       # deg
insertion = 0.08                       # m
tmap = rk.gravity_map(psm, drive, roll_deg=roll, pitch_deg=pitch, insertion=insertion)

# the named axes: tmap.dims is (pitch, roll, insertion, joint); read a pose by name, not by position
print(f"axes {tmap.dims}, joints {tmap.coords['joint']}")
at = tmap.sel(roll=10, pitch=-15)
print(f"at roll 10 deg, pitch -15 deg, insertion {insertion} m:")
for j, name in enumerate(tmap.coords["joint"]):
    print(f"  {name:9s} holding torque {at.tau[j]:8.3f}  PWM {at.pwm[j]:8.2f} counts")

# the same pose from the single-pose call (all seven actuated joints) agrees with the map
q = np.zeros(psm.nq)
q[:3] = np.radians(10), np.radians(-15), insertion
assert np.allclose(rk.holding_effort(psm, q).drive.pwm, at.pwm)

# the largest holding PWM of the pitch over the grid, and where
worst = np.unravel_index(np.argmax(np.abs(tmap.effort.pwm[..., 1])), tmap.effort.pwm.shape[:3])
print(f"largest pitch PWM {tmap.effort.pwm[worst][1]:.1f} counts at roll {tmap.roll_deg[worst[1]]:g} deg, "
      f"pitch {tmap.pitch_deg[worst[0]]:g} deg")

# the tables: one row per pose, as CSV and as NumPy arrays (np.load gives the columns)
for name in ("torque_map.csv", "torque_map.npz"):
    print(f"wrote {tmap.write(out / name)}")

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

# the named axes: the effort arrays are indexed [pitch, roll, insertion, joint], joints in the
# driven order roll, pitch, insertion
joints = ("roll", "pitch", "insertion")
i_pitch = int(np.argmin(np.abs(tmap.pitch_deg - (-15))))
i_roll = int(np.argmin(np.abs(tmap.roll_deg - 10)))
pwm = tmap.effort.pwm[i_pitch, i_roll, 0]
tau = tmap.effort.tau[i_pitch, i_roll, 0]
print(f"at roll {tmap.roll_deg[i_roll]:g} deg, pitch {tmap.pitch_deg[i_pitch]:g} deg, insertion {insertion} m:")
for j, name in enumerate(joints):
    print(f"  {name:9s} holding torque {tau[j]:8.3f}  PWM {pwm[j]:8.2f} counts")

# the same pose from the single-pose call agrees with the map
q = np.zeros(psm.nq)
q[:3] = np.radians(tmap.roll_deg[i_roll]), np.radians(tmap.pitch_deg[i_pitch]), insertion
assert np.allclose(rk.holding_effort(psm, q).drive.pwm, pwm)

# the largest holding PWM over the grid, and where
worst = np.unravel_index(np.argmax(np.abs(tmap.effort.pwm[..., 1])), tmap.effort.pwm.shape[:3])
print(f"largest pitch PWM {tmap.effort.pwm[worst][1]:.1f} counts at roll {tmap.roll_deg[worst[1]]:g} deg, "
      f"pitch {tmap.pitch_deg[worst[0]]:g} deg")

# the tables: one row per pose (roll, pitch in deg), as CSV and as NumPy arrays
P, R = np.meshgrid(tmap.pitch_deg, tmap.roll_deg, indexing="ij")
columns = {"roll_deg": R.ravel(), "pitch_deg": P.ravel()}
for quantity in ("tau", "voltage", "pwm"):
    values = getattr(tmap.effort, quantity)[:, :, 0, :]
    for j, name in enumerate(joints):
        columns[f"{quantity}_{name}"] = values[..., j].ravel()
np.savetxt(out / "torque_map.csv", np.column_stack(list(columns.values())), delimiter=",",
           header=",".join(columns), comments="", fmt="%.9g")
np.savez(out / "torque_map.npz", **columns)
print(f"wrote {out / 'torque_map.csv'} and {out / 'torque_map.npz'} ({R.size} poses)")

"""A linear model of the PSM's driven joints at a held pose, as a python-control ``StateSpace``.

    python examples/linear_model.py [OUT_DIR]   (writes linear_model.json there; default: a temporary folder)

The model: state [q; v] of roll, pitch, insertion (rad, rad, m and their rates), input the
three drivers' PWM (counts, hardware sign), output the joint positions. It is the closed
chain's exact rigid-body dynamics plus the drive (reflected rotor inertia, back-EMF, viscous
friction), linearised by CasADi's automatic differentiation about the pose held at rest.
"""

import json
import sys
import tempfile
from pathlib import Path

import control
import numpy as np

import rcm_kin as rk

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="linear_model_"))
out.mkdir(parents=True, exist_ok=True)

# the driven-joint model, without the smoothed Coulomb friction: its slope at rest is set by the
# smoothing width alone, so the gain design (and this linearisation) leaves it out
psm = rk.load_robot("psm")
model = rk.driven_dynamics(psm, coulomb=False)

# the pose: roll 10 deg, pitch -5 deg, insertion 0.08 m; held there by the PWM u0
q0 = [np.radians(10), np.radians(-5), 0.08]
lin = rk.linearize(model, q0)
print("holding PWM u0 (roll, pitch, insertion):", np.round(lin.u0, 2))

# the python-control system, in deviations from (x0, u0), with labelled signals
sys_ = lin.to_ss()
print(f"{sys_.nstates} states {sys_.state_labels}")
print(f"inputs {sys_.input_labels}")
print("poles (1/s):")
for p in sorted(sys_.poles(), key=lambda p: p.real):
    print(f"  {p.real:10.4f} {p.imag:+.4f}j")
unstable = [p for p in sys_.poles() if p.real > 0]
print(f"{len(unstable)} unstable pole(s): the open-loop arm falls without its controller")

# the same model sampled as the firmware runs it: PWM held over each 2.5 ms period (400 Hz)
sampled = control.c2d(sys_, 1 / 400, method="zoh")
print("largest |z| of the 400 Hz model:", f"{max(abs(sampled.poles())):.6f}")

# the matrices for other tools
(out / "linear_model.json").write_text(json.dumps(lin.as_dict(), indent=1))
print(f"wrote {out / 'linear_model.json'}")

"""A meshcat view of the PSM at a pose, written as one self-contained HTML page (no server, no
network: open it in any browser), with its frames of interest shown as axis triads.

    python examples/meshcat_view.py [OUT_DIR]   (writes psm.html there; default: a temporary folder)

This is what ``rcm-kin view psm --q 10 -15 0.1 --deg --frames rcm tool_tip --html psm.html``
does. For a live view served on localhost instead, pass a meshcat window:
``rk.robot_view(psm, window=meshcat.Visualizer().window)``.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import rcm_kin as rk

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="meshcat_view_"))
out.mkdir(parents=True, exist_ok=True)

psm = rk.load_robot("psm")

# an offline view (no window given): the scene is kept in memory and written as a page
viz = rk.robot_view(psm, frames=("rcm", "tool_tip"))

# the pose, in the actuated joints' order (rk.joint_table(psm) lists them): roll 10 deg,
# pitch -15 deg, insertion 0.1 m, the instrument joints at 0; the loop's passive joints follow
q = np.zeros(psm.nq)
q[:3] = np.radians(10), np.radians(-15), 0.10
rk.show(viz, psm, q)

# where the tool tip is at that pose (base frame: origin at the remote centre of motion, z up)
tip = rk.forward_kinematics(psm, q).frames["tool_tip"].translation
print(f"tool tip at {np.round(tip * 1000, 1)} mm from the RCM")

page = rk.write_html(viz, out / "psm.html")
print(f"wrote {page} ({page.stat().st_size / 1e6:.1f} MB): open it in a browser")

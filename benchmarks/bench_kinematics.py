"""FK and IK cost per call on the bundled robots.

python benchmarks/bench_kinematics.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import numpy as np
from common import per_call, report

from rcm_kin import load_robot
from rcm_kin.kinematics.fk import forward_kinematics, frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.psm_ik import shaft_tip_ik, tool_pose_ik, wrist_ik


def main() -> None:
    psm, mtm = load_robot("psm"), load_robot("mtm")
    q = np.array([0.2, -0.3, 0.1, 0.4, 0.3, -0.2, 0.5])
    tip = frame_placement(psm, q, "shaft_tip").translation
    tool = frame_placement(psm, q, "tool_tip")
    q_mtm = np.array([0.3, -0.2, 0.4, 0, 0, 0, 0])
    wrist_center = frame_placement(mtm, q_mtm, "wrist_center").translation
    report([
        ("PSM FK, one frame (reduced model)", per_call(lambda: frame_placement(psm, q, "tool_tip"), 5000)),
        ("PSM FK, 3 frames + closure residual", per_call(lambda: forward_kinematics(psm, q), 2000)),
        ("PSM analytic shaft-tip IK", per_call(lambda: shaft_tip_ik(psm, tip), 2000)),
        ("PSM closed-form wrist IK (+ polish)", per_call(lambda: wrist_ik(psm, q[:3], tool.rotation), 500)),
        ("PSM full tool-pose IK (closed form + DLS)",
         per_call(lambda: tool_pose_ik(psm, tool.translation, tool.rotation, jaw=q[6]), 200)),
        ("MTM numeric wrist-centre IK (DLS)",
         per_call(lambda: solve_ik(mtm, "wrist_center", wrist_center, joints=("j1", "j2", "j3")), 200)),
    ])


if __name__ == "__main__":
    main()

"""FK and IK cost per call on the bundled robots; forward kinematics against the plain Pinocchio
calls for the same frames (``pin.forwardKinematics`` + ``updateFramePlacement`` on the reduced
model), alone and with the loop-closure residual done in plain Pinocchio (``forwardKinematics``
on the open tree + each constraint's ``calc``), same run (issue 30: at most 1.5x).

python benchmarks/bench_kinematics.py
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import numpy as np
import pinocchio as pin
from common import per_call, report

from rcm_kin import load_robot
from rcm_kin.kinematics.fk import forward_kinematics, frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.psm_ik import shaft_tip_ik, tool_pose_ik, wrist_ik


def plain_calls(robot, q):
    """The plain Pinocchio calls of ``forward_kinematics(robot, q)``: (frames only, with the closure)."""
    model, data, tree, tree_data = robot.reduced, robot.reduced.createData(), robot.tree, robot.tree.createData()
    constraints = [(c.model, c.model.createData()) for c in robot.constraints]
    frames = robot.description.frames
    ids = [model.getFrameId(name) for name in frames]
    q_reduced, q_tree = np.zeros(model.nq), np.zeros(tree.nq)
    q_reduced[robot.reduced_q_actuated], q_tree[robot.tree_q_actuated] = q, q

    def frames_only():
        pin.forwardKinematics(model, data, q_reduced)
        return {name: pin.updateFramePlacement(model, data, i).copy() for name, i in zip(frames, ids)}

    def with_closure():
        placements = frames_only()
        pin.forwardKinematics(tree, tree_data, q_tree)
        for c, c_data in constraints:
            c.calc(tree, tree_data, c_data)
        return placements, [c_data.constraint_position_error for _, c_data in constraints]
    return frames_only, with_closure


def fk_ratios(psm, q, rounds: int = 150) -> None:
    """The three timed in interleaved rounds (best of ``rounds`` each), so that the machine's load
    falls on all alike; short rounds (200 calls, about 1 ms), so that the best of them is a round
    the scheduler did not interrupt, as often on a loaded machine (15 rounds of 2000 calls before:
    the same calls in all)."""
    frames_only, with_closure = plain_calls(psm, q)
    cases = {"fk": lambda: forward_kinematics(psm, q), "plain": frames_only, "closure": with_closure}
    best = dict.fromkeys(cases, float("inf"))
    for _ in range(rounds):
        for name, fn in cases.items():
            best[name] = min(best[name], per_call(fn, 200, 1))
    fk, plain, closure = best["fk"], best["plain"], best["closure"]
    print(f"forward_kinematics(psm) {fk * 1e6:.2f} us: {fk / plain:.2f}x the plain FK of its 3 frames "
          f"({plain * 1e6:.2f} us), {fk / closure:.2f}x with the closure residual ({closure * 1e6:.2f} us)")


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
    fk_ratios(psm, q)


if __name__ == "__main__":
    main()

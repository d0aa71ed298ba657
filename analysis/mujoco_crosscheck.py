"""The exported PSM in MuJoCo beside our dynamics: the table of the MJCF cross-check.

    python analysis/mujoco_crosscheck.py [--out mujoco_crosscheck.md]

Per keyframe: the largest joint speed over 0.5 s with the motors holding our gravity torques
(the arm: roll, pitch, insertion and the parallelogram joints; the instrument: its four joints),
and without the motors. Then the 1 s free swing from rest at home (RK4 at 0.5, 0.25 and 0.1 ms,
limits and Coulomb friction off): the largest difference to our closed-chain dynamics per driven
joint, beside the joint's travel.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.gravity import gravity_torque  # noqa: E402
from rcm_kin.export.mjcf import write_mjcf  # noqa: E402
from rcm_kin.export.mujoco_check import (actuated_q, at_keyframe, closed_chain_swing, drive_terms,  # noqa: E402
                                         hold_speeds, mujoco_swing)

INSTRUMENT = ("instrument_roll", "wrist_pitch", "wrist_yaw", "jaw")


def hold_table(model, psm) -> list[str]:
    lines = ["| keyframe | held: arm max speed | held: instrument max speed | motors off: arm max speed |",
             "|---|---|---|---|"]
    for k in range(model.nkey):
        key = model.key(k).name
        q = actuated_q(model, at_keyframe(model, key), psm)
        held = hold_speeds(model, at_keyframe(model, key, gravity_torque(psm, q, method="constrained")), 0.5)
        off = hold_speeds(model, at_keyframe(model, key, np.zeros(psm.nq)), 0.5)
        arm = lambda s: max(v for j, v in s.items() if j not in INSTRUMENT)  # noqa: E731
        lines.append(f"| {key} | {arm(held):.1e} | {max(held[j] for j in INSTRUMENT):.1e} | {arm(off):.2f} |")
    return lines


def swing_table(path: Path, psm, params) -> list[str]:
    times = np.arange(0.0, 1.0 + 1e-9, 0.01)
    lines = ["| step (ms) | " + " | ".join(f"{j} error" for j in ("roll", "pitch", "insertion", "wrist_pitch")) + " |",
             "|---|---|---|---|---|"]
    columns = [psm.actuated.index(j) for j in ("roll", "pitch", "insertion", "wrist_pitch")]
    for step in (5e-4, 2.5e-4, 1e-4):
        model = mujoco.MjModel.from_xml_path(str(path))
        model.opt.timestep, model.opt.integrator = step, mujoco.mjtIntegrator.mjINT_RK4
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_LIMIT
        model.dof_frictionloss[:] = 0.0
        theirs = mujoco_swing(model, at_keyframe(model, "home", np.zeros(psm.nq)), psm, times)
        ours = closed_chain_swing(psm, theirs[0], times, *drive_terms(psm, params))
        error = np.max(np.abs(theirs - ours), axis=0)
        lines.append(f"| {step * 1e3:g} | " + " | ".join(f"{error[i]:.2e}" for i in columns) + " |")
    travel = np.max(np.abs(ours - ours[0]), axis=0)
    lines.append("| travel | " + " | ".join(f"{travel[i]:.3f}" for i in columns) + " |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", help="also write the tables to this Markdown file")
    args = parser.parse_args()
    psm, params = load_robot("psm"), load_drive_parameters()
    with tempfile.TemporaryDirectory() as folder:
        path = write_mjcf(psm, Path(folder) / "psm.xml", params)
        model = mujoco.MjModel.from_xml_path(str(path))
        text = "\n".join(["Holding (speeds in rad/s or m/s, 0.5 s from rest):", "", *hold_table(model, psm), "",
                          "Free swing from rest at home, 1 s (errors in rad or m):", "",
                          *swing_table(path, psm, params)])
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")


if __name__ == "__main__":
    main()

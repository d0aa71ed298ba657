"""The PSM exported to MuJoCo and run there beside our dynamics (only with the ``[mujoco]`` extra).

The exported model is the one ``rcm-kin gravity psm`` uses (the shipped calibration, its gravity
offsets as centre-of-mass shifts: :mod:`rcm_kin.export.calibrated`). Holding: per keyframe, the
largest joint speed over 0.5 s with the motors holding that model's gravity torques (the keyframe's
controls; the arm: roll, pitch, insertion and the parallelogram joints; the instrument: its four
joints), and without the motors. Free swing: 0.2 s from rest at home, no motor torque, joint limits
and Coulomb friction off, MuJoCo's RK4 at three steps beside our closed-chain dynamics of the same
model (Pinocchio on the calibrated inertias). 0.2 s: the calibrated arm falls fast (pitch 0.33 rad,
the insertion at the end of its range); past about 0.35 s, limits off, it reaches poses outside the
joint ranges (pitch -83 deg, insertion 0.67 m) where MuJoCo's soft loops and ours part.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from rcm_kin.model import load_robot
from rcm_kin.report.render import Table, relative

INSTRUMENT = ("instrument_roll", "wrist_pitch", "wrist_yaw", "jaw")
SWING_JOINTS = ("pitch", "insertion", "wrist_pitch")
SWING_STEPS = (5e-4, 2.5e-4, 1e-4)       # s
SWING_TOLERANCE = 1e-4                   # of each joint's travel: MuJoCo's loop regularisation (1 - d)/d
SWING_SECONDS = 0.2                      # s
HOLD_SPEED = 1e-3                        # rad/s (m/s): "at rest"


@dataclass(frozen=True)
class MujocoSection:
    template: ClassVar[str] = "mujoco.html.j2"
    model: str               # the exported MJCF, relative to the report folder
    model_label: str         # the model it holds: "calibration psm_drive.toml"
    holding: Table
    swing: Table
    hold_speed: float
    swing_tolerance: float


def _holding(model, psm) -> Table:
    from rcm_kin.export.mujoco_check import at_keyframe, hold_speeds

    rows = []
    for k in range(model.nkey):
        key = model.key(k).name
        held = hold_speeds(model, at_keyframe(model, key), 0.5)     # the keyframe's controls: `gravity`'s torques
        off = hold_speeds(model, at_keyframe(model, key, np.zeros(psm.nq)), 0.5)
        arm = lambda speeds: max(v for j, v in speeds.items() if j not in INSTRUMENT)  # noqa: E731
        rows.append([key, f"{arm(held):.1e}", f"{max(held[j] for j in INSTRUMENT):.1e}", f"{arm(off):.2f}"])
    return Table.of(rows, ["keyframe", "held: arm", "held: instrument", "motors off: arm"])


def _swing(path: Path, psm) -> Table:
    import mujoco

    from rcm_kin.dynamics.drive import robot_drive
    from rcm_kin.export.calibrated import calibrated_robot
    from rcm_kin.export.mujoco_check import at_keyframe, closed_chain_swing, drive_terms, mujoco_swing

    drive = robot_drive(psm)
    ours_model = calibrated_robot(psm, drive)

    times = np.arange(0.0, SWING_SECONDS + 1e-9, 0.01)
    columns = [psm.actuated.index(j) for j in SWING_JOINTS]
    rows = []
    for step in SWING_STEPS:
        model = mujoco.MjModel.from_xml_path(str(path))
        model.opt.timestep, model.opt.integrator = step, mujoco.mjtIntegrator.mjINT_RK4
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_LIMIT
        model.dof_frictionloss[:] = 0.0
        theirs = mujoco_swing(model, at_keyframe(model, "home", np.zeros(psm.nq)), psm, times)
        ours = closed_chain_swing(ours_model, theirs[0], times, *drive_terms(psm, drive))
        error = np.max(np.abs(theirs - ours), axis=0)
        rows.append([f"difference, RK4 {step * 1e3:g} ms"] + [f"{error[i]:.2e}" for i in columns])
    travel = np.max(np.abs(ours - ours[0]), axis=0)
    rows.append(["travel"] + [f"{travel[i]:.3f}" for i in columns])
    return Table.of(rows, [f"{SWING_SECONDS:g} s from rest at home"] + [f"{j} ({'m' if j == 'insertion' else 'rad'})"
                                                        for j in SWING_JOINTS])


def mujoco_section(out: Path) -> MujocoSection | None:
    """Export the PSM to ``out/psm.xml`` and tabulate its runs in MuJoCo; None without MuJoCo."""
    if importlib.util.find_spec("mujoco") is None:
        return None
    import mujoco

    from rcm_kin.dynamics.drive import model_label, robot_drive
    from rcm_kin.export.mjcf import write_mjcf

    psm = load_robot("psm")
    path = write_mjcf(psm, out / "psm.xml", robot_drive(psm))
    return MujocoSection(relative(path, out), model_label(robot_drive(psm)),
                         _holding(mujoco.MjModel.from_xml_path(str(path)), psm),
                         _swing(path, psm), HOLD_SPEED, SWING_TOLERANCE)

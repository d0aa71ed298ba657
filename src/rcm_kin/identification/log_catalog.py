"""Which telemetry log can identify what: open-loop steps, closed-loop records, or neither.

A log identifies a joint's drive train when its angle is in degrees and the pose of the other
axis is known and inside the model's range (the rigid-body gravity along the joint depends on
it). Per joint (roll, pitch) a log is

- a **step**: the PWM holds one value for at least ``HOLD`` s, changes once, and holds the new
  value to the end (the roll steps, the pitch step): simulated from the sample before the step;
- **closed loop**: any other log with motion (PRBS under a controller) whose controller can be
  read back from it (:mod:`rcm_kin.identification.recorded_law`): simulated with that law in
  the loop (:func:`rcm_kin.identification.drive_train.closed_loop_log`).

Logs are skipped with the reason: an angle column that is not in degrees (the pitch ramp log
stores raw encoder counts), the other axis missing from a step log (its gravity would be a
guess), or outside the joint range (resting on its mechanical stop, a contact the model does
not have), closed-loop logs in which the joint only holds still, and closed-loop logs whose
controller is not a linear law plus a binary excitation (it cannot be put in the loop). A log without the roll
takes it at 0, as the single-axis experiments were run (data README: "at roll about 0").

The roll's dynamics do not care whether the pitch is held by its controller or by its stop: a
roll log with the pitch resting on its stop (outside the model's range) is a roll record all the
same, the pitch held where it rests; a roll log without the pitch takes it at its resting value,
:data:`rcm_kin.hardware.PITCH_REST_DEG` (on its lower stop: the single-axis roll experiments
rest it there, as ``roll_step.csv`` shows). Either assumption is the entry's ``note``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.errors import RcmKinError, WorkLimitError
from rcm_kin.hardware import PITCH_REST_DEG, PWM_LIMIT
from rcm_kin.identification.recorded_law import recover_law
from rcm_kin.identification.rosbag import BAG_SUFFIXES
from rcm_kin.identification.telemetry import TelemetryLog, is_bag, load_telemetry, telemetry_files

HOLD = 0.5            # s a step's PWM must hold before and after its one change
ANGLE_RANGE = 90.0    # deg: an angle column beyond this is not in degrees
LIMIT = 30.0          # deg: the PSM's roll and pitch range (the model's)
MIN_MOTION = 0.5      # deg: a closed-loop log must move at least this much to identify anything


@dataclass(frozen=True)
class CatalogEntry:
    path: Path
    joint: str
    kind: str             # "step", "closed-loop" or "skipped"
    reason: str = ""      # why it was skipped
    note: str = ""        # an assumption the record makes (the pitch's pose)


def classify(log: TelemetryLog, joint: str) -> tuple[str, str]:
    """``(kind, reason)`` of ``log`` for ``joint`` (see the module text)."""
    if joint not in log.position or joint not in log.pwm:
        return "skipped", f"no {joint} columns"
    angle, u = log.position[joint], log.pwm[joint]
    if np.max(np.abs(angle)) > ANGLE_RANGE:
        return "skipped", f"the {joint} angle is not in degrees (|angle| up to {np.max(np.abs(angle)):.0f})"
    if np.ptp(angle) == 0.0:
        return "skipped", f"the {joint} does not move"
    other = "pitch" if joint == "roll" else "roll"
    changes = np.flatnonzero(np.abs(np.diff(u)) > 0.1)
    step = changes.size == 1 and min(log.time[changes[0]], log.time[-1] - log.time[changes[0] + 1]) >= HOLD
    if other in log.position and other == "roll":
        held = float(np.mean(log.position[other]))
        if abs(held) > LIMIT:
            return "skipped", f"the {other} is at {held:.1f} deg, outside the model's range (on its stop)"
    if not step and np.ptp(angle) < MIN_MOTION:
        return "skipped", f"the {joint} only holds still ({np.ptp(angle):.2f} deg of motion)"
    if not step:
        problem = recover_law(log, joint, float(PWM_LIMIT[("roll", "pitch").index(joint)])).problem()
        if problem:
            return "skipped", problem
    return ("step" if step else "closed-loop"), ""


def pose_note(log: TelemetryLog, joint: str) -> str:
    """The assumption a record of ``joint`` from ``log`` makes about the pitch's pose ("" for none)."""
    if joint != "roll":
        return ""
    if "pitch" not in log.position:
        return (f"the pitch is not logged: taken at its resting value {PITCH_REST_DEG:.1f} deg (on its lower stop, "
                "where the single-axis roll experiments rest it, as roll_step.csv shows)")
    held = float(np.mean(log.position["pitch"]))
    if abs(held) > LIMIT:
        return (f"the pitch rests at {held:.1f} deg (on its stop, outside the controlled range): held there, "
                "as the roll's dynamics see it")
    return ""


MAX_LOGS = 1000       # CSV files one search may find
MAX_FOLDERS = 10_000  # folders one search may visit (a log folder, not a whole disk)


def _log_files(folder: Path) -> list[Path]:
    """The logs below ``folder`` (CSV and ROS 2 bags: :func:`telemetry_files`), sorted; a search past
    :data:`MAX_FOLDERS` folders or :data:`MAX_LOGS` logs is refused (unreadable folders are skipped)."""
    logs = 0
    for visited, (root, _, names) in enumerate(os.walk(folder), start=1):
        logs += sum(n.endswith((".csv", *BAG_SUFFIXES)) for n in names)
        if visited > MAX_FOLDERS or logs > MAX_LOGS:
            requested, limit = (visited, MAX_FOLDERS) if visited > MAX_FOLDERS else (logs, MAX_LOGS)
            raise WorkLimitError(f"more than {MAX_FOLDERS} folders or {MAX_LOGS} logs below {folder}: "
                                 "give the folder of the logs", requested=requested, limit=limit)
    return telemetry_files(folder, "**/*")


def catalog(paths, joints=("roll", "pitch")) -> list[CatalogEntry]:
    """Every log in ``paths`` (files or folders searched recursively: CSV and ROS 2 bags) for each joint."""
    files = []
    for path in map(Path, paths):
        if path.is_dir() and not is_bag(path):
            files += _log_files(path)
        elif path.exists():
            files.append(path)
        else:
            raise RcmKinError(f"no log file or folder at {path}")
    if not files:
        raise RcmKinError(f"no telemetry logs (CSV, .mcap, .db3) in {', '.join(map(str, paths))}")
    out = []
    for file in files:
        try:
            log = load_telemetry(file)
        except RcmKinError as exc:
            reason = str(exc).removeprefix(f"{file}: ")
            out += [CatalogEntry(file, joint, "skipped", reason) for joint in joints]
            continue
        for joint in joints:
            kind, reason = classify(log, joint)
            out.append(CatalogEntry(file, joint, kind, reason, pose_note(log, joint) if kind != "skipped" else ""))
    return out

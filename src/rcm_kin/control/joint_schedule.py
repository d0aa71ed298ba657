"""Model-based gain schedules over any two scheduling joints of a robot with a drive.

The same design as the PSM firmware's (:mod:`rcm_kin.control.gain_schedule`), over joints named by
the user: at each point of a ``first x second`` grid (degrees) the robot's PWM-input model is
linearised (Coulomb friction left out) with the other modelled joints held at a pose ``at``, and

- the first joint gets an LQR on its ``[q, v]`` (``[Kp, Kd]``),
- the second an LQI on ``[q, v]`` plus the integral of its error (``[Kp, Kd, Ki]``),

each on its own axis model (the other joints frozen), in the firmware's units and signs (PWM per
degree, per deg/s, per deg s; ``u = -(Kp e + Kd v [+ Ki E])`` with ``e = r - y``), with the Bryson
budgets of :class:`~rcm_kin.control.weights.Weights` (``roll_*`` for the first joint, ``pitch_*``
for the second). The check is the continuous closed loop of the two scheduled joints together
(their 4-state coupled model and the integral) at every grid point; the 400 Hz sampled loop,
the velocity filter and the C header are the PSM firmware's and stay with
:func:`~rcm_kin.control.gain_schedule.schedule_gains`.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rcm_kin.atomic import atomic_open, write_text
from rcm_kin.control.gain_schedule import check_grid, lqr_axis
from rcm_kin.control.linearization import linearize_grid
from rcm_kin.control.weights import Weights
from rcm_kin.dynamics.state_space import DrivenDynamics
from rcm_kin.errors import NonFiniteResultError, RcmKinError, output_folder

MAX_GRID_POINTS = 201     # per scheduling joint


@dataclass(frozen=True)
class JointSchedule:
    """Gain tables indexed ``[second][first]`` (like the firmware's ``table[pitch][roll]``)."""

    joints: tuple[str, str]     # the scheduling joints (first: LQR, second: LQI)
    first_deg: np.ndarray       # (n1,) grid, increasing
    second_deg: np.ndarray      # (n2,)
    at: np.ndarray              # (n,) the model pose the other modelled joints are held at (SI)
    k_first: np.ndarray         # (n2, n1, 2)  [Kp, Kd]
    k_second: np.ndarray        # (n2, n1, 3)  [Kp, Kd, Ki]
    u_hold: np.ndarray          # (n2, n1, n) holding PWM of every modelled joint
    max_real: np.ndarray        # (n2, n1) largest real part of the two joints' closed loop (1/s)
    model: str = ""             # which model the tables were designed on
    weights: Weights = Weights()

    @property
    def stable(self) -> bool:
        """Whether the closed loop is stable at every grid point."""
        return bool(np.all(self.max_real < 0))

    def weakest(self) -> dict:
        """The grid point with the slowest closed-loop mode."""
        j, i = np.unravel_index(np.argmax(self.max_real), self.max_real.shape)
        return {"max_real": float(self.max_real[j, i]), f"{self.joints[0]}_deg": float(self.first_deg[i]),
                f"{self.joints[1]}_deg": float(self.second_deg[j])}


def parse_joint_grid(words: list[str], model: DrivenDynamics) -> dict[str, np.ndarray]:
    """``["j=LO:HI:N", "k=LO:HI:N"]`` (degrees) as ``{j: grid, k: grid}``: two distinct revolute
    joints of ``model``, N from 2 to :data:`MAX_GRID_POINTS`, inside the joints' limits."""
    if len(words) != 2:
        raise RcmKinError(f"`grid` takes two scheduling joints as JOINT=LO:HI:N (degrees), got {len(words)}",
                          parameter="grid")
    grid = {}
    for word in words:
        name, _, span = word.partition("=")
        parts = span.split(":")
        try:
            lo, hi, n = float(parts[0]), float(parts[1]), int(parts[2])
        except (ValueError, IndexError):
            raise RcmKinError(f"`grid` entries are JOINT=LO:HI:N (degrees, N whole), got '{word[:60]}'",
                              parameter="grid") from None
        if len(parts) != 3 or name not in model.joints or name in grid:
            raise RcmKinError(f"`grid` '{word[:60]}': JOINT=LO:HI:N over two distinct joints of the model "
                              f"({', '.join(model.joints)})", parameter="grid")
        k = model.joints.index(name)
        if model.units[k] != "rad":
            raise RcmKinError(f"`grid` joint {name} is prismatic: the schedule is over revolute joints (degrees)",
                              parameter="grid")
        if not 2 <= n <= MAX_GRID_POINTS:
            raise RcmKinError(f"`grid` {name}: N must be 2 to {MAX_GRID_POINTS}, got {n}", parameter="grid")
        grid[name] = check_grid(np.linspace(lo, hi, n), name, model.lower[k], model.upper[k])
    return grid


def axis_gains(A: np.ndarray, B: np.ndarray, axis: int, Q: np.ndarray, R: np.ndarray, integral: bool) -> np.ndarray:
    """Firmware-sign gains of one joint's LQR (``[Kp, Kd]``) or LQI (``[Kp, Kd, Ki]``) at one model."""
    i = [axis, axis + A.shape[0] // 2]
    K = lqr_axis(A[np.ix_(i, i)], np.degrees(B[i][:, [axis]]), Q, R, integral=integral)
    return np.array([-K[0], K[1], -K[2]]) if integral else np.array([-K[0], K[1]])


def pair_closed_loop(A: np.ndarray, B: np.ndarray, axes: tuple[int, int], k_first, k_second) -> np.ndarray:
    """Continuous closed loop (5, 5) of the two scheduled joints' coupled model (the other joints
    frozen) under the laws: state ``[q1, q2, v1, v2]`` (SI) and the second joint's error integral."""
    n = A.shape[0] // 2
    i = [axes[0], axes[1], axes[0] + n, axes[1] + n]
    a, b = A[np.ix_(i, i)], B[np.ix_(i, list(axes))]
    k1, k2 = np.degrees(k_first), np.degrees(k_second)       # per degree -> per radian
    K = np.zeros((2, 5))                                     # u = -K [x; z]
    K[0, [0, 2]] = [-k1[0], k1[1]]
    K[1, [1, 3, 4]] = [-k2[0], k2[1], k2[2]]
    a_aug = np.zeros((5, 5))
    a_aug[:4, :4], a_aug[4, 1] = a, -1.0                     # zdot = e = -(y - r)
    return a_aug - np.vstack([b, np.zeros((1, 2))]) @ K


def schedule_joints(model: DrivenDynamics, grid: dict[str, np.ndarray], at=None,
                   weights: Weights | None = None) -> JointSchedule:
    """Design the gain tables of ``model`` (a PWM-input model without Coulomb friction) over the two
    scheduling joints of ``grid`` ({joint: degrees}, first LQR, second LQI), the other modelled
    joints held at ``at`` (the model's pose, SI; default the middle of each joint's range)."""
    if not model.pwm_input:
        raise RcmKinError(f"a gain schedule needs a drive: {model.robot or 'the robot'} has none (its model has "
                          "torque input); give its drive parameter file", parameter="drive")
    if model.coulomb:
        raise RcmKinError("design on the model without Coulomb friction: driven_dynamics(..., coulomb=False)")
    weights = weights or Weights()
    (first, g1), (second, g2) = grid.items()
    axes = (model.joints.index(first), model.joints.index(second))
    at = (model.lower + model.upper) / 2 if at is None else np.asarray(at, dtype=float)
    S, F = np.meshgrid(g2, g1, indexing="ij")
    Q = np.tile(at, (S.size, 1))
    Q[:, axes[0]], Q[:, axes[1]] = np.radians(F.ravel()), np.radians(S.ravel())
    models = linearize_grid(model, Q, compile=S.size > 64)
    k1 = np.array([axis_gains(a, b, axes[0], *weights.roll(), integral=False) for a, b in zip(models.A, models.B)])
    k2 = np.array([axis_gains(a, b, axes[1], *weights.pitch(), integral=True) for a, b in zip(models.A, models.B)])
    max_real = np.array([np.linalg.eigvals(pair_closed_loop(a, b, axes, x, y)).real.max()
                         for a, b, x, y in zip(models.A, models.B, k1, k2)])
    shape, n = S.shape, len(model.joints)
    return JointSchedule((first, second), g1, g2, at, k1.reshape(*shape, 2), k2.reshape(*shape, 3),
                         models.u0.reshape(*shape, n), max_real.reshape(shape), model.model_label, weights)


def schedule_rows(schedule: JointSchedule, joints: tuple[str, ...]) -> tuple[list[str], list[list[float]]]:
    """The tables as CSV columns and rows, one row per grid point."""
    a, b = schedule.joints
    header = [f"{a}_deg", f"{b}_deg", f"kp_{a}", f"kd_{a}", f"kp_{b}", f"kd_{b}", f"ki_{b}", "max_real"]
    header += [f"u_hold_{j}" for j in joints]
    rows = []
    for j, s in enumerate(schedule.second_deg):
        for i, f in enumerate(schedule.first_deg):
            rows.append([float(f), float(s), *schedule.k_first[j, i].tolist(), *schedule.k_second[j, i].tolist(),
                         float(schedule.max_real[j, i]), *schedule.u_hold[j, i].tolist()])
    return header, rows


def schedule_payload(schedule: JointSchedule, model: DrivenDynamics) -> dict:
    """The schedule as JSON-ready data: its joints, grids, tables, the model it was designed on."""
    a, b = schedule.joints
    return {"robot": model.robot, "joints": [a, b], "model": model.model_label, "input_unit": model.input_unit,
            "modelled_joints": list(model.joints), "at": schedule.at.tolist(), f"{a}_deg": schedule.first_deg.tolist(),
            f"{b}_deg": schedule.second_deg.tolist(), "k_first": schedule.k_first.tolist(),
            "k_second": schedule.k_second.tolist(), "u_hold": schedule.u_hold.tolist(),
            "max_real": schedule.max_real.tolist(), "stable": schedule.stable}


def write_joint_schedule(schedule: JointSchedule, model: DrivenDynamics, folder: str | Path) -> list[Path]:
    """``schedule.json`` (:func:`schedule_payload`) and ``schedule.csv`` (:func:`schedule_rows`) in
    ``folder`` (created); nothing is written, not even the folder, when a value is not finite."""
    payload = schedule_payload(schedule, model)
    header, rows = schedule_rows(schedule, model.joints)
    if not np.all(np.isfinite(np.array(rows, dtype=float))):
        raise NonFiniteResultError(f"the gain schedule of {model.robot} is not finite: check its drive parameters",
                                   where="schedule")
    folder = output_folder(folder)
    files = [folder / "schedule.json", folder / "schedule.csv"]
    try:
        write_text(files[0], json.dumps(payload, allow_nan=False, indent=1) + "\n")
        with atomic_open(files[1], "w", newline="") as fh:
            writer = csv.writer(fh)
            writer.writerow(header)
            writer.writerows([[f"{v:.9g}" for v in row] for row in rows])
    except OSError as exc:
        raise RcmKinError(f"cannot write the gain schedule in {folder}: {exc.strerror}") from None
    return files

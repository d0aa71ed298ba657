"""Excitation design: periodic trajectories that make the drive trains identifiable.

The driven joints take turns (roll, then pitch), each excited for ``duration`` s while the
other holds still at 0 and the insertion at the home insertion: the per-axis model of
:mod:`rcm_kin.dynamics.stick_slip` is identified with the other axes held. Each joint follows a
finite Fourier series of its position (:mod:`rcm_kin.identification.fourier`), period ``T`` (the
duration holds a whole number of periods, each about :data:`PERIOD`), ``N`` harmonics,
periodic by construction. Each starts and ends at rest at 0: ``q0 = sum_k b_k / (w k)`` makes
``q(0) = 0``, and ``sum_k a_k = 0``, ``sum_k k b_k = 0`` make ``qd(0) = qdd(0) = 0`` (so the
file starts from the held pose, and the next joint starts where this one stopped).

**The identification regressor** is the linear-in-parameters part of the axis model: the rigid
body with smooth friction, what the drive train reduces to while the axis slides,

    k_u u = J qdd + D qd + F_c tanh(qd / v_c) + A sin q + B cos q = Y(q, qd, qdd) theta

``theta = (J, D, F_c, A, B)``: the total inertia (link, reflected rotor, extra), the damping
(viscous and back-EMF), the sliding friction, and the rigid-body gravity ``A sin q + B cos q``
(exact for one axis of a rigid body: the tables of :func:`axis_plant` fit it to 1e-14 N m).
The condition number minimised is that of ``Y diag(theta_0)``, ``theta_0`` the shipped values:
each column is one term's torque (N m), so the number does not depend on units, and it is low
only when every term contributes a torque comparable to the others' and no two terms have the
same shape in time. (A single sine cannot tell the inertia from the gravity: ``qdd = -w^2 q``
and ``sin q ~ q``; that is the baseline reported beside each design.)

**Limits**, at every sample: ``|q|`` within the URDF limits less :data:`JOINT_MARGIN`,
``|qd| <=`` :data:`VELOCITY_LIMIT`, and the feedforward PWM within :data:`PWM_FRACTION` of
:data:`rcm_kin.hardware.PWM_LIMIT` (the rest is left to the feedback that tracks the
setpoint). The feedforward is ``u = (J(q) qdd + D qd + F_c tanh(qd / v_c) + g(q)) / k_u`` with
the rigid-body inertia and gravity of :func:`axis_plant` and the shipped smooth friction
(``psm_drive.toml`` ``[roll]``, ``[pitch]``, its Coulomb law smoothed over ``v_c`` =
``coulomb_velocity`` as the smooth model's is); the joint held still gets its holding PWM plus
the coupling torque of the moving one (``M_ij qdd_j + c_i(q, qd_j)``). Coefficients: SLSQP with
analytic gradients from several seeded random feasible starts, on :data:`GRID` samples per
period, all the limits one smooth constraint (the Kreisselmeier-Steinhauser envelope of every
sample's margins, which lies above the worst of them); the result is checked, and shrunk if
needed, on the firmware's grid.

The replay file: :func:`write_excitation`; the stick-slip model's predicted errors:
:mod:`rcm_kin.identification.replay`.

**Predicted standard errors**, two kinds:

- of ``theta``: ``sqrt(diag(s^2 (Y^T Y)^-1))`` with ``Y`` along the whole excitation on the
  firmware's grid, and the equation error ``s`` assumed (:data:`EQUATION_NOISE`) one PWM count
  RMS (``|k_u|`` x 1 count: 0.12 N m on the roll), about what the encoder's count becomes when
  differentiated twice behind a :data:`NOISE_BANDWIDTH` low-pass; samples of filtered noise
  are independent only ``1 / (2 x 10 Hz)`` apart, so the covariance counts that many samples;
- of the stick-slip model: :func:`rcm_kin.identification.replay.stick_slip_errors`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from rcm_kin.atomic import atomic_path
from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, load_drive_parameters
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import ENCODER_COUNT, FIRMWARE_PERIOD, PWM_LIMIT
from rcm_kin.identification.excitation_axis import (
    EQUATION_NOISE,
    JOINT_MARGIN,
    NOISE_BANDWIDTH,
    PARAMETERS,
    PWM_FRACTION,
    STARTS,
    VELOCITY_LIMIT,
    AxisModel,
    axis_model,
    optimise_axis,
)
from rcm_kin.identification.fourier import Fourier
from rcm_kin.identification.identify import base_model
from rcm_kin.identification.replay import HOLD_POSE, JOINTS, stick_slip_errors

UNITS = {"inertia": "kg m^2", "damping": "N m s/rad", "coulomb": "N m", "gravity_sin": "N m",
         "gravity_cos": "N m"}
PERIOD = 10.0                        # s: the period aimed at (a whole number of them per duration)
HARMONICS = 5
MAX_HARMONICS = 20
MIN_DURATION, MAX_DURATION = 1.0, 600.0   # s per joint


def coupling_torques(model, joint: str, q, qd, qdd) -> np.ndarray:
    """(3, n) rigid-body torques of the driven joints (N m, N) while ``joint`` follows ``q``,
    ``qd``, ``qdd`` and the others hold at :data:`HOLD_POSE`: ``g(q) + M[:, j] qdd + c(q, qd e_j)``
    (``c`` is quadratic in the velocity), from tables along the axis. No friction: the moving
    joint's own is :meth:`AxisModel.pwm`'s."""
    j = DRIVEN.index(joint)
    grid = np.linspace(-np.radians(45.0), np.radians(45.0), 181)
    poses = np.repeat(HOLD_POSE[None, :], grid.size, axis=0)
    poses[:, j] = grid
    unit = np.zeros_like(poses)
    unit[:, j] = 1.0
    gravity = np.array(model.gravity.map(grid.size)(poses.T))
    coriolis = np.array(model.bias.map(grid.size)(poses.T, unit.T)) - gravity
    column = np.array([np.array(model.mass_matrix(p))[:, j] for p in poses]).T
    table = lambda values: np.array([np.interp(q, grid, row) for row in values])  # noqa: E731
    return table(gravity) + table(column) * qdd + table(coriolis) * qd**2


@dataclass(frozen=True)
class JointExcitation:
    """One joint's excitation, its regressor's conditioning and the standard errors it predicts."""

    joint: str
    trajectory: Fourier
    start: float                           # s: when its excitation starts in the file
    theta: dict[str, float]                # the shipped values of PARAMETERS (SI)
    condition_number: float                # of Y diag(theta) along the excitation
    baseline_condition_number: float       # a single sine of the same amplitude and period
    standard_errors: dict[str, float]      # of theta (SI), the assumed equation error
    baseline_standard_errors: dict[str, float]
    stick_slip_errors: dict[str, float] | None            # the drive train's free parameters (their units)
    baseline_stick_slip_errors: dict[str, float] | None
    tracking_rms: float | None             # rad: the stick-slip model replaying it (P loop), off the setpoint
    peak_position: float                   # rad
    peak_velocity: float                   # rad/s
    peak_pwm: float                        # counts, the joint's own feedforward


@dataclass(frozen=True)
class Excitation:
    """The joints' excitations in turn, on the firmware's grid."""

    period: float                          # s: of each Fourier series
    duration: float                        # s: each joint's excitation (a whole number of periods)
    harmonics: int
    joints: dict[str, JointExcitation]
    time: np.ndarray                       # (n,) s
    setpoint: np.ndarray                   # (n, 2) rad: roll, pitch
    pwm: np.ndarray                        # (n, 2) counts: roll, pitch feedforward

    def as_dict(self) -> dict:
        def errors(r: JointExcitation, baseline: bool) -> dict:   # NaN (not determined): null
            found = {"regressor": r.baseline_standard_errors if baseline else r.standard_errors,
                     "stick_slip": r.baseline_stick_slip_errors if baseline else r.stick_slip_errors}
            return {k: None if v is None else {n: x if np.isfinite(x) else None for n, x in v.items()}
                    for k, v in found.items()}
        return {
            "condition_number": {j: r.condition_number for j, r in self.joints.items()},
            "baseline_condition_number": {j: r.baseline_condition_number for j, r in self.joints.items()},
            "standard_errors": {j: errors(r, False) for j, r in self.joints.items()},
            "baseline_standard_errors": {j: errors(r, True) for j, r in self.joints.items()},
            "parameters": {j: r.theta for j, r in self.joints.items()},
            "period_s": self.period, "duration_s": self.duration, "harmonics": self.harmonics,
            "start_s": {j: r.start for j, r in self.joints.items()},
            "coefficients": {j: {"a": r.trajectory.a.tolist(), "b": r.trajectory.b.tolist(),
                                 "offset": r.trajectory.offset} for j, r in self.joints.items()},
            "peaks": {j: {"position_deg": float(np.degrees(r.peak_position)),
                          "velocity_deg_s": float(np.degrees(r.peak_velocity)), "pwm": r.peak_pwm}
                      for j, r in self.joints.items()},
            "tracking_rms_deg": {j: None if r.tracking_rms is None else float(np.degrees(r.tracking_rms))
                                  for j, r in self.joints.items()},
            "limits": {"margin_deg": float(np.degrees(JOINT_MARGIN)),
                       "velocity_deg_s": float(np.degrees(VELOCITY_LIMIT)),
                       "pwm": {j: float(PWM_FRACTION * PWM_LIMIT[DRIVEN.index(j)]) for j in JOINTS}},
            "assumed_noise": {"equation_pwm": EQUATION_NOISE, "bandwidth_hz": NOISE_BANDWIDTH,
                              "encoder_deg": {j: float(ENCODER_COUNT[DRIVEN.index(j)] / np.sqrt(12)) for j in JOINTS}},
        }


def check_request(duration: float, joints, harmonics: int) -> tuple[str, ...]:
    """The joints asked for (in the order given, once each), or a user error."""
    if not np.isfinite(duration) or not MIN_DURATION <= duration <= MAX_DURATION:
        raise RcmKinError(f"the duration must be between {MIN_DURATION:g} and {MAX_DURATION:g} s per joint, "
                          f"got {duration:g}")
    if not 2 <= harmonics <= MAX_HARMONICS:
        raise RcmKinError(f"`harmonics` must be between 2 and {MAX_HARMONICS} (the start at rest takes two "
                          f"coefficients), got {harmonics}", parameter="harmonics")
    joints = tuple(dict.fromkeys(joints))
    unknown = [j for j in joints if j not in JOINTS]
    if unknown or not joints:
        raise RcmKinError(f"no excitation for {', '.join(unknown) or 'no joint'}: the joints are {', '.join(JOINTS)} "
                          "(the insertion is held by its own loop)")
    return joints


def design_excitation(duration: float, joints=JOINTS, harmonics: int = HARMONICS, seed: int = 0,
                      params: DriveParameters | None = None, starts: int = STARTS,
                      progress: bool = False) -> Excitation:
    """Excitations of ``joints`` in turn, ``duration`` s each (rounded to the firmware period;
    periods of about :data:`PERIOD` s), ``harmonics`` harmonics, optimised from ``starts``
    random starts drawn with ``seed`` (see the module notes); a progress bar when ``progress``
    and the design takes more than 2 s."""
    joints = check_request(duration, joints, harmonics)
    params = params or load_drive_parameters()
    model = base_model(params)
    h = FIRMWARE_PERIOD
    n = int(round(duration / h))
    duration = n * h
    period = duration / max(1, int(round(duration / PERIOD)))
    t = np.arange(n) * h
    rng = np.random.default_rng(seed)
    results, setpoint, pwm = {}, [], []
    with tqdm(total=len(joints) * (starts + 1), desc="excite", unit="step", delay=2.0,
              disable=not progress) as bar:
        for k, joint in enumerate(joints):
            axis = axis_model(model, params, joint)
            fourier = fitted_to_limits(axis, optimise_axis(axis, period, harmonics, rng, starts, bar.update), t)
            motion = fourier.evaluate(t)
            torques = coupling_torques(model, joint, *motion)
            u = torques / model.drive.input_gain[:, None]
            u[DRIVEN.index(joint)] = axis.pwm(*motion)
            results[joint] = _joint_result(axis, model, params, fourier, k * duration, duration, motion, u[:2], t)
            position = np.zeros((n, 2))
            position[:, JOINTS.index(joint)] = motion[0]
            setpoint.append(position)
            pwm.append(u[:2].T)
            bar.update()
    rest = np.array(model.gravity(HOLD_POSE)).ravel()[:2] / model.drive.input_gain[:2]
    worst = np.max(np.abs(np.concatenate(pwm)), axis=0) / PWM_LIMIT[:2]
    if np.any(worst > 1):   # a held joint's coupling torque (not seen by the optimisation) too large
        raise RcmKinError(f"the feedforward of the held {JOINTS[int(np.argmax(worst))]} exceeds its PWM limit; "
                          "try fewer `harmonics`", parameter="harmonics")
    time = np.arange(len(joints) * n + 1) * h
    return Excitation(period, duration, harmonics, results, time, np.r_[np.concatenate(setpoint), np.zeros((1, 2))],
                      np.r_[np.concatenate(pwm), rest[None]])


def fitted_to_limits(axis: AxisModel, fourier: Fourier, t: np.ndarray) -> Fourier:
    """``fourier`` shrunk (rarely: its limits were met between the optimisation's samples) until
    every sample at the times ``t`` is within the limits."""
    for _ in range(200):
        q, qd, qdd = fourier.evaluate(t)
        excess = axis.violation(q, qd, axis.pwm(q, qd, qdd))
        if excess <= 0:
            return fourier
        scale = 1.0 - max(excess, 1e-4) - 1e-4
        fourier = replace(fourier, a=fourier.a * scale, b=fourier.b * scale)
    raise RcmKinError(f"the {axis.joint}'s excitation does not fit its limits; try fewer `harmonics`",
                      parameter="harmonics")


def _joint_result(axis: AxisModel, model, params: DriveParameters, fourier: Fourier, start: float, duration: float,
                  motion, u: np.ndarray, t: np.ndarray) -> JointExcitation:
    """Conditioning and standard errors of one joint's excitation, and of its single-sine baseline."""
    q, qd, qdd = motion
    i = JOINTS.index(axis.joint)
    amplitude, w = np.max(np.abs(q)), 2 * np.pi / fourier.period
    sine = (amplitude * np.sin(w * t), amplitude * w * np.cos(w * t), -amplitude * w**2 * np.sin(w * t))
    stick_slip = baseline_stick_slip = rms = None
    if axis.joint in params.drive_train:
        stick_slip, measured = stick_slip_errors(model, params, axis.joint, q, u[i])
        baseline_stick_slip, _ = stick_slip_errors(model, params, axis.joint, sine[0], axis.pwm(*sine))
        rms = float(np.sqrt(np.mean((measured - q) ** 2)))
    return JointExcitation(
        axis.joint, fourier, start, dict(zip(PARAMETERS, map(float, axis.theta))), axis.condition_number(*motion),
        axis.condition_number(*sine), axis.standard_errors(*motion, duration), axis.standard_errors(*sine, duration),
        stick_slip, baseline_stick_slip, rms, float(np.max(np.abs(q))), float(np.max(np.abs(qd))),
        float(np.max(np.abs(u[i]))))


def write_excitation(excitation: Excitation, path: str | Path) -> Path:
    """The replay CSV of ``excitation`` at ``path``: one header line and no comments, a row every
    firmware period (:data:`rcm_kin.hardware.FIRMWARE_PERIOD`, 2.5 ms), in the telemetry format
    (:func:`rcm_kin.identification.telemetry.load_telemetry` reads it back)::

        __time                                    s, from 0
        /psm_joint_telemetry/roll/position        deg, the setpoint (what perfect tracking would measure)
        /psm_joint_telemetry/roll/velocity        counts, the feedforward PWM (hardware sign)
        /psm_joint_telemetry/roll/effort          deg, the position setpoint
        /psm_joint_telemetry/pitch/position       the same three for the pitch
        /psm_joint_telemetry/pitch/velocity
        /psm_joint_telemetry/pitch/effort

    Both joints are always written; a joint not excited holds at 0. A last row closes the file at
    rest. The insertion is not in the file: its firmware loop holds it."""
    path = Path(path)
    header = ["__time"] + [f"/psm_joint_telemetry/{j}/{c}" for j in JOINTS for c in ("position", "velocity", "effort")]
    degrees = np.degrees(excitation.setpoint)
    columns = [excitation.time]
    for k in range(len(JOINTS)):
        columns += [degrees[:, k], excitation.pwm[:, k], degrees[:, k]]
    try:
        with atomic_path(path) as temporary:
            np.savetxt(temporary, np.column_stack(columns), delimiter=",", header=",".join(header), comments="",
                       fmt=["%.4f"] + ["%.6f", "%.3f", "%.6f"] * len(JOINTS))
    except OSError as exc:
        raise RcmKinError(f"cannot write {path}: {exc.strerror}") from None
    return path


"""One Dask task: a batch of samples, each a drawn parameter set simulated with every controller.

The controllers are the ones flashed once: their gain schedule is designed on the nominal
parameter set (:func:`rcm_kin.simulation.experiments.psm_schedule`), and only the plant
(the robot the schedule meets) takes the drawn parameters. Per sample and controller:

- the closed-loop experiment (400 Hz firmware; :func:`rcm_kin.simulation.experiments.closed_loop`,
  in the compiled kernel, equal to :func:`rcm_kin.simulation.loop.simulate` tick for tick) and its
  tracking metrics; a run is *unstable* (:func:`closed_loop_run`) when its state leaves the
  finite numbers (diverged) or its joints leave their range
  (:func:`rcm_kin.simulation.experiments.check_in_limits`, where the model means nothing);
- the linear stability of the roll and pitch about every pose of a ``survey_points`` x
  ``survey_points`` grid over the schedule's span (:func:`loop_margins`, on the drawn set's smooth
  model, Coulomb friction left out as the design does; the insertion's own modes left out):
  the largest real part of the continuous closed loop
  (:func:`rcm_kin.control.gain_schedule.closed_loop_matrix`), the largest spectral radius of
  the 400 Hz firmware loop (:func:`rcm_kin.control.stability.firmware_loop_matrix`) and the
  smallest damping ratio of its poles (as ``stability_survey`` takes it). The PID's
  law (roll integral, derivative of the error) is not the firmware loop those model, so it has
  no margin (NaN).

What a worker builds once and keeps (models, schedule, reference) is cached in the worker's
process; a task ships only numbers (the nominal set, the uncertain parameters, the seeds).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from rcm_kin.control.gain_schedule import (
    THESIS_PITCH_DEG,
    THESIS_ROLL_DEG,
    GainSchedule,
    closed_loop_matrix,
    scheduled_gains,
)
from rcm_kin.control.linearization import linearize_grid
from rcm_kin.control.stability import damping_ratios, firmware_loop_matrix, survey_poses
from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.dynamics.parametric import shared_model
from rcm_kin.dynamics.state_space import DrivenDynamics
from rcm_kin.errors import JointLimitError, NonFiniteResultError, RcmKinError
from rcm_kin.firmware_rules import bilinear
from rcm_kin.hardware import FIRMWARE_PERIOD, P_GAINS
from rcm_kin.model import load_robot
from rcm_kin.robustness.sampling import Uncertain, draw, with_values
from rcm_kin.simulation.controllers import CONTROLLERS, Hold, make_controller
from rcm_kin.simulation.experiments import (
    check_in_limits,
    closed_loop,
    experiment_reference,
    psm_schedule,
    start_hold,
)
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import AXES, SimulationResult, tracking_metrics
from rcm_kin.simulation.plant_family import family_of
from rcm_kin.thesis import K_PITCH, K_ROLL

SURVEY_POINTS = 5       # per axis of the stability grid
MARGIN_FUNCTIONS = ("gravity", "jacobians")    # what a sample's model evaluates (linearize_grid)


@dataclass(frozen=True)
class Study:
    """What every task of one robustness run shares (small: pickled with each task)."""

    params: DriveParameters              # nominal set: the schedule is designed on it
    uncertain: tuple[Uncertain, ...]
    controllers: tuple[str, ...]         # names of :data:`rcm_kin.simulation.controllers.CONTROLLERS`
    experiment: str                      # "sine", "step" or "target"
    duration: float | None = None        # s; None: the experiment's default
    skip: float = 0.0                    # s left out of the tracking statistics
    survey_points: int = SURVEY_POINTS

    def __post_init__(self):
        unknown = [c for c in self.controllers if c not in CONTROLLERS]
        if unknown or not self.controllers:
            raise RcmKinError(f"unknown controller(s) {', '.join(unknown) or '(none given)'} "
                              f"(choose from {', '.join(CONTROLLERS)})")
        long_enough = self.duration is None or (np.isfinite(self.duration) and self.duration > self.skip)
        if not (np.isfinite(self.skip) and self.skip >= 0 and long_enough):
            raise RcmKinError(f"the statistics start within the run: 0 <= skip < duration, got skip {self.skip} s and "
                              f"duration {self.duration} s")
        if self.survey_points < 2:
            raise RcmKinError(f"the stability grid needs at least 2 points per axis, got {self.survey_points}")


@dataclass(frozen=True)
class SampleOutcome:
    """One sample: the drawn values and, per controller (the study's order) and axis (roll, pitch),
    what the closed loop did. Errors in degrees (NaN where the run was unstable)."""

    index: int
    values: np.ndarray            # (n_uncertain,) the drawn parameters, the study's order
    max_error_deg: np.ndarray     # (n_controllers, 2) largest |reference - measured|
    mean_error_deg: np.ndarray    # (n_controllers, 2) mean |reference - measured|
    saturated: np.ndarray         # (n_controllers, 2) bool: the command reached the PWM limit
    unstable: np.ndarray          # (n_controllers,) bool: the run diverged or left the joint range
    max_real: np.ndarray          # (n_controllers,) 1/s, continuous loop, worst pose (NaN: no linear law)
    spectral_radius: np.ndarray   # (n_controllers,) 400 Hz firmware loop, worst pose (NaN: no linear law)
    min_damping: np.ndarray       # (n_controllers,) least damping ratio of the 400 Hz loop's poles, worst pose


def linear_law(name: str, schedule: GainSchedule):
    """``(roll_deg, pitch_deg) -> (k_roll (2,), k_pitch (3,))`` of the controller ``name`` in the
    firmware's form ``u = -(Kp e + Kd v [+ Ki E])`` (feedforward terms do not change the loop), or
    None for a law of another form (the PID)."""
    if name == "p":
        return lambda r, p: (np.array([P_GAINS[0], 0.0]), np.array([P_GAINS[1], 0.0, 0.0]))
    if name == "thesis":
        grid = np.asarray(THESIS_ROLL_DEG), np.asarray(THESIS_PITCH_DEG)
        return lambda r, p: (bilinear(*grid, K_ROLL, r, p), bilinear(*grid, K_PITCH, r, p))
    if name == "lqr-fixed":
        return lambda r, p: scheduled_gains(schedule, 0.0, 0.0)
    if name.startswith("scheduled"):
        return lambda r, p: scheduled_gains(schedule, r, p)
    return None


INSERTION_STATES = [2, 5]     # the insertion's position and velocity in the loops' state


def roll_pitch_modes(matrix: np.ndarray) -> np.ndarray:
    """The eigenvalues of a closed-loop matrix (continuous (7, 7) or firmware (10, 10), first six
    states the model's ``[q; v]``) whose modes are the roll's and pitch's: those with at most half
    of their physical state (``|v_i|^2`` over ``q; v``) in the insertion's position and velocity.
    The insertion's own modes (its firmware P loop, the same under every controller and not drawn)
    would otherwise set the worst margin of every roll/pitch law."""
    w, V = np.linalg.eig(matrix)
    physical = np.abs(V[:6]) ** 2
    total = physical.sum(axis=0)
    insertion = np.divide(physical[INSERTION_STATES].sum(axis=0), total, out=np.zeros_like(total), where=total > 0)
    return w[insertion <= 0.5]


def loop_margins(model: DrivenDynamics, schedule: GainSchedule, law, points: int) -> tuple[float, float, float]:
    """Worst linear stability of the roll and pitch under ``law`` (:func:`linear_law`) over a
    ``points`` x ``points`` roll x pitch grid spanning the schedule's, at its insertion: the largest
    real part (1/s) of the continuous closed loop's roll/pitch modes (:func:`roll_pitch_modes`),
    the largest spectral radius of the 400 Hz firmware loop's, and the smallest damping ratio of
    the firmware loop's taken as ``s = ln(z) / T`` (:func:`rcm_kin.control.stability.damping_ratios`;
    the deadbeat modes, the stored previous angles, left out). A law without integral action
    (pitch Ki 0) leaves the loops' error integral a mode nothing depends on (exactly 0 in s, 1 in
    z); it is left out too, so a P loop is judged on its own modes."""
    _, _, R, P, Q = survey_poses(schedule, points)
    grid = linearize_grid(model, Q, compile=False)      # a bound model's functions are compiled already
    max_real, radius, damping = -np.inf, 0.0, np.inf
    for r, p, A, B in zip(R.ravel(), P.ravel(), grid.A, grid.B):
        k_roll, k_pitch = law(r, p)
        keep_s, keep_z = (slice(None), slice(None)) if k_pitch[2] else (slice(0, 6), slice(0, 9))
        s = roll_pitch_modes(closed_loop_matrix(A, B, k_roll, k_pitch)[keep_s, keep_s])
        z = roll_pitch_modes(firmware_loop_matrix(A, B, k_roll, k_pitch)[keep_z, keep_z])
        max_real = max(max_real, float(s.real.max()))
        radius = max(radius, float(np.abs(z).max()))
        z = z[np.abs(z) > 1e-9]
        damping = min(damping, float(damping_ratios(np.log(z.astype(complex)) / FIRMWARE_PERIOD).min()))
    return max_real, radius, damping


def _reference(experiment: str, period: float, duration: float | None):
    return _reference_of(load_robot("psm"), experiment, period, duration)


@functools.lru_cache(maxsize=4)
def _reference_of(robot, experiment: str, period: float, duration: float | None):
    """Keyed by the robot loaded now too: a target reference goes through its IK."""
    return experiment_reference(experiment, period, duration)


def sample_plant(params: DriveParameters, period: float):
    """The plant of a drawn set, its model functions compiled: its identified drive trains when it
    has them, else the smooth model's period map (as :func:`rcm_kin.simulation.experiments.psm_plant`),
    from the family of its structure (:func:`rcm_kin.simulation.plant_family.family_of`): compiled
    once per process, never per set."""
    return family_of(params, period).plant(params)


def sample_model(params: DriveParameters) -> DrivenDynamics:
    """The drawn set's model without Coulomb friction (its holding PWM, its loop margins): the
    parametric model of its structure bound to it (:func:`rcm_kin.dynamics.parametric.shared_model`),
    gravity and Jacobians compiled once per process, equal to ``driven_dynamics(psm, params,
    coulomb=False)`` bit for bit."""
    return shared_model(load_robot("psm"), params, coulomb=False, compile_names=MARGIN_FUNCTIONS).bind(params)


def closed_loop_run(plant, controller, reference, settings: FirmwareSettings,
                    hold: Hold | None = None) -> SimulationResult | None:
    """``controller`` on ``plant`` (``step``, ``initial``) along ``reference`` from ``hold`` (the
    steady hold of the first pose), in the compiled loop where there is one
    (:func:`rcm_kin.simulation.experiments.closed_loop`); None when the run is unstable: its state
    diverged (left the finite numbers) or its joints left their range."""
    try:
        result = closed_loop(plant, controller, reference, settings, hold=hold)
        check_in_limits(result)
    except (NonFiniteResultError, JointLimitError):
        return None
    return result


def run_sample(study: Study, index: int, seed: np.random.SeedSequence) -> SampleOutcome:
    """Sample ``index`` of ``study``, drawn from ``seed`` alone."""
    settings = FirmwareSettings()
    schedule = psm_schedule(study.params)
    reference = _reference(study.experiment, settings.period, study.duration)
    values = draw(study.uncertain, seed)
    params = with_values(study.params, study.uncertain, values)
    plant = sample_plant(params, settings.period)
    model = sample_model(params)
    hold = start_hold(reference, model=model)
    n = len(study.controllers)
    max_error, mean_error = np.full((n, 2), np.nan), np.full((n, 2), np.nan)
    saturated, unstable = np.zeros((n, 2), dtype=bool), np.zeros(n, dtype=bool)
    max_real, radius, damping = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
    for c, name in enumerate(study.controllers):
        result = closed_loop_run(plant, make_controller(name, schedule), reference, settings, hold)
        if result is None:
            unstable[c] = True
        else:
            metrics = tracking_metrics(result, study.skip)
            for a, axis in enumerate(AXES):
                m = metrics[axis]
                max_error[c, a], mean_error[c, a] = m.max_error_deg, m.mean_error_deg
                saturated[c, a] = m.saturation_s > 0
        law = linear_law(name, schedule)
        if law is not None:
            max_real[c], radius[c], damping[c] = loop_margins(model, schedule, law, study.survey_points)
    return SampleOutcome(index, values, max_error, mean_error, saturated, unstable, max_real, radius, damping)


def run_batch(study: Study, batch: list[tuple[int, np.random.SeedSequence]]) -> list[SampleOutcome]:
    """The samples ``(index, seed)`` of one task, in order."""
    return [run_sample(study, index, seed) for index, seed in batch]

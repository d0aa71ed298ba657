"""The thesis's tracking experiments on the PSM model: plant, controller and reference wired.

The plant is the nonlinear driven-joint model with Coulomb friction; the model-based
controllers use the gain schedule designed on the thesis grid (roll -20/0/20 x pitch
-15/0/15 deg, insertion 80 mm) on the same model without Coulomb friction, as ``rcm-kin
schedule`` does.
"""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np

from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG, GainSchedule, schedule_gains
from rcm_kin.control.schedule_cache import cached_schedule, schedule_key
from rcm_kin.control.schedule_file import read_schedule_file
from rcm_kin.dynamics.drive import DriveParameters, load_drive_parameters
from rcm_kin.dynamics.state_space import DrivenDynamics, driven_dynamics, holding_pwm
from rcm_kin.errors import JointLimitError, RcmKinError, as_number
from rcm_kin.model import load_robot
from rcm_kin.simulation.compiled_loop import run_closed_loop
from rcm_kin.simulation.controllers import MODEL_FREE, TUNED, Controller, Hold, StateFeedbackController, make_controller
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import SimulationResult, firmware_units, simulate
from rcm_kin.simulation.plant import Plant, SmoothPlant, drive_train_plant, period_map
from rcm_kin.simulation.references import EXPERIMENTS, Reference, sine_reference, step_reference, target_reference

DEFAULT_DURATION = {"sine": 6.0, "step": 3.0, "target": None}   # s; None: the recording's length


def experiment_reference(experiment: str, period: float, duration: float | None = None,
                         trajectory=None) -> Reference:
    """The reference of ``experiment`` (one of :data:`EXPERIMENTS`) at the controller period."""
    if experiment not in EXPERIMENTS:
        raise RcmKinError(f"unknown experiment '{experiment}' (choose from {', '.join(EXPERIMENTS)})")
    duration = DEFAULT_DURATION[experiment] if duration is None else duration
    if experiment == "sine":
        return sine_reference(duration, period)
    if experiment == "step":
        return step_reference(duration, period)
    return target_reference(load_robot("psm"), duration, period, trajectory)


def exact_key(value) -> tuple:
    """A hashable key of ``value`` that tells apart any two different numbers: floats by their
    exact bits (``float.hex``), arrays by dtype, shape and bytes, recursively over dataclass fields,
    dicts, lists and tuples (``repr`` keeps 8 significant digits of an array, so parameter sets
    differing in the 9th would share a cached schedule)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value).__qualname__,) + tuple((f.name, exact_key(getattr(value, f.name)))
                                                   for f in dataclasses.fields(value))
    if isinstance(value, dict):
        return ("dict",) + tuple(sorted((repr(k), exact_key(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return (type(value).__name__,) + tuple(exact_key(v) for v in value)
    if isinstance(value, (np.ndarray, np.generic)):
        array = np.ascontiguousarray(value)
        return ("array", array.dtype.str, array.shape, array.tobytes())
    if isinstance(value, float):
        return ("float", value.hex())
    if value is None or isinstance(value, (bool, int, str, bytes)):
        return (type(value).__name__, value)
    raise TypeError(f"no exact key for a {type(value).__name__}")


# keyed by the robot loaded now (a new object after its files changed) and the exact parameter values
_BUILT: dict[tuple, object] = {}               # (robot, exact_key(params, period, substeps, fast)) -> plant
_SCHEDULES: dict[tuple, GainSchedule] = {}     # (robot, exact_key(params)) -> schedule (about 0.5 s each)
_MODELS: dict[tuple, DrivenDynamics] = {}      # (robot, exact_key(params)) -> model without Coulomb friction


def _smooth_model(params: DriveParameters) -> DrivenDynamics:
    """The driven-joint model of ``params`` without Coulomb friction, built once per process (the
    schedule's design model; its gravity gives the holding PWM)."""
    key = (load_robot("psm"), exact_key(params))
    if key not in _MODELS:
        _MODELS[key] = driven_dynamics(load_robot("psm"), params, coulomb=False)
    return _MODELS[key]


def psm_plant(params: DriveParameters, period: float, substeps: int = 4, fast: bool = False) -> Plant:
    """The PSM plant with ``params`` (a :class:`~rcm_kin.simulation.plant.Plant`): the identified
    drive trains (:class:`~rcm_kin.simulation.plant.DriveTrainPlant`) when ``params`` has them, else
    the smooth model's period map (:class:`~rcm_kin.simulation.plant.SmoothPlant`, ``substeps`` RK4
    steps per ``period`` s); ``fast``: its kernel form, the model functions compiled (a
    :class:`~rcm_kin.simulation.compiled_plant.CompiledPlant`), where there is a C compiler."""
    psm = load_robot("psm")
    if params.drive_train:
        plant = drive_train_plant(psm, params, period)
    else:
        plant = SmoothPlant(period_map(driven_dynamics(psm, params).forward, period, substeps), period)
    return (plant.kernel_plant() or plant) if fast else plant


def psm_schedule(params: DriveParameters | None = None) -> GainSchedule:
    """The gain schedule of the PSM with ``params`` (default: shipped set) on the thesis grid,
    designed on the model without Coulomb friction (as ``rcm-kin schedule``); computed once per
    process and parameter set, and kept on disk (:mod:`rcm_kin.control.schedule_cache`: a fresh
    process reads it in milliseconds instead of importing SciPy and designing it again)."""
    params = params or load_drive_parameters()
    psm = load_robot("psm")
    key = (psm, exact_key(params))
    if key not in _SCHEDULES:
        disk_key = schedule_key("thesis grid", repr(exact_key(params)), repr(psm.description),
                                hashlib.sha256(psm.description.urdf.read_bytes()).hexdigest())
        _SCHEDULES[key] = cached_schedule(disk_key, lambda: schedule_gains(_smooth_model(params), THESIS_ROLL_DEG,
                                                                           THESIS_PITCH_DEG))
    return _SCHEDULES[key]


def _built_plant(params: DriveParameters, period: float, substeps: int, fast: bool) -> Plant:
    """:func:`psm_plant`, built once per process and arguments."""
    key = (load_robot("psm"), exact_key((params, float(period), int(substeps), bool(fast))))
    if key not in _BUILT:
        _BUILT[key] = psm_plant(params, period, substeps, fast)
    return _BUILT[key]


def psm_plant_and_schedule(params: DriveParameters | None = None, period: float = FirmwareSettings().period,
                           substeps: int = 4, fast: bool = False):
    """``(plant, GainSchedule)`` of the PSM with ``params`` (default: shipped set): the plant of
    :func:`psm_plant` (``fast``: its kernel form, whose closed loop runs in one compiled kernel)."""
    params = params or load_drive_parameters()
    return _built_plant(params, period, substeps, fast), psm_schedule(params)


def start_hold(reference: Reference, params: DriveParameters | None = None,
               model: DrivenDynamics | None = None) -> Hold:
    """The steady hold of ``reference``'s first pose: the pose in firmware units and its holding
    PWM (``g(q) / k_u``, counts) with ``model``, else the model of ``params`` (default: the
    shipped set)."""
    model = model or _smooth_model(params or load_drive_parameters())
    return Hold(firmware_units(reference.position[0]), holding_pwm(model, reference.position[0]))


def named_controller(name: str, params: DriveParameters | None = None, gains=None) -> Controller:
    """The controller ``name`` (the CLI's names: :data:`~rcm_kin.simulation.controllers.CONTROLLERS`
    with the schedule designed on ``params``, or :data:`~rcm_kin.simulation.controllers.TUNED`: the
    state-feedback law with the tables and options of the gain file ``gains``, default the shipped
    tuned design, :func:`rcm_kin.control.schedule_file.read_schedule_file`)."""
    if name == TUNED:
        loaded = read_schedule_file(gains)
        return StateFeedbackController(loaded.schedule, name=TUNED, **loaded.flags)
    if gains is not None:
        raise RcmKinError(f"a gain file is read by the '{TUNED}' controller, not '{name}' (its tables are designed on "
                          "the parameter set)", parameter="gains")
    return make_controller(name, None if name in MODEL_FREE else psm_schedule(params or load_drive_parameters()))


def run_experiment(experiment: str, controller: str, duration: float | None = None,
                   params: DriveParameters | None = None, settings: FirmwareSettings | None = None,
                   trajectory=None, seed: int = 0, progress: bool = False, fast: bool = True,
                   gains=None) -> SimulationResult:
    """Simulate one thesis experiment with one controller (names as in the CLI). ``fast``: the
    whole loop in one compiled kernel (:mod:`rcm_kin.simulation.compiled_loop`; without a C
    compiler the readable loop, with a warning); ``False`` runs the readable reference loop. Both
    give the same result (tests/simulation/test_compiled_loop.py, tests/simulation/test_simulation.py).
    The run starts from the steady hold of the first pose (:func:`start_hold`): integrals charged
    with its holding PWM. ``gains``: the gain file of the ``tuned`` controller (:func:`named_controller`)."""
    if settings is not None and not isinstance(settings, FirmwareSettings):
        raise RcmKinError(f"`settings` is a FirmwareSettings, got {type(settings).__name__}", parameter="settings")
    if params is not None and not isinstance(params, DriveParameters):
        raise RcmKinError(f"`params` is a DriveParameters (rk.load_drive_parameters), got {type(params).__name__}",
                          parameter="params")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise RcmKinError(f"`seed` is a whole number, at least 0, got {seed!r}", parameter="seed")
    if duration is not None:
        duration = as_number(duration, "duration", "s", 0.0, float("inf"), low_open=True)
    settings, params = settings or FirmwareSettings(), params or load_drive_parameters()
    law = named_controller(controller, params, gains)       # a designed schedule takes about 1 s
    plant = _built_plant(params, settings.period, 4, fast)
    reference = experiment_reference(experiment, settings.period, duration, trajectory)
    result = closed_loop(plant, law, reference, settings, seed, progress, fast, hold=start_hold(reference, params))
    check_in_limits(result)
    return result


def closed_loop(plant: Plant, controller: Controller, reference: Reference, settings: FirmwareSettings | None = None,
                seed: int = 0, progress: bool = False, fast: bool = True, hold: Hold | None = None) -> SimulationResult:
    """``controller`` on ``plant`` (:func:`psm_plant`) along ``reference``, from rest at its first
    pose, the controller's integrals charged to ``hold`` (:func:`start_hold`) when given. ``fast``:
    in one compiled kernel when the controller and the plant have kernel forms, else in the
    readable loop with an :class:`~rcm_kin.errors.EngineFallbackWarning`
    (:func:`~rcm_kin.simulation.compiled_loop.run_closed_loop`); ``False``: the readable reference
    loop (:func:`rcm_kin.simulation.loop.simulate`). The same result either way (the tests hold the
    engines to each other tick for tick). A state that leaves the finite numbers raises
    :class:`~rcm_kin.errors.NonFiniteResultError`."""
    if fast:
        return run_closed_loop(plant, controller, reference, settings, seed, progress, hold)
    return simulate(plant.step, controller, reference, settings, seed=seed, progress=progress,
                    initial=plant.initial, hold=hold)


def check_in_limits(result: SimulationResult) -> None:
    """Refuse a run whose joints left their limits (or became non-finite): the model means nothing
    there, and a controller that drives the robot there has failed (the one joint-limit policy)."""
    psm = load_robot("psm")
    index = [psm.actuated.index(j) for j in ("roll", "pitch", "insertion")]
    lower, upper = psm.lower[index], psm.upper[index]
    position = np.c_[np.radians(result.position[:, :2]), result.position[:, 2]]     # rad, rad, m
    bad = ~np.isfinite(position) | (position < lower - 1e-6) | (position > upper + 1e-6)
    if np.any(bad):
        k, j = np.argwhere(bad)[0]
        unit, scale = ("m", 1.0) if j == 2 else ("deg", 180 / np.pi)
        message = (f"the simulated {('roll', 'pitch', 'insertion')[j]} reached {position[k, j] * scale:.4g} {unit} at "
                   f"t = {result.time[k]:.3f} s, outside its joint range [{lower[j] * scale:.4g}, "
                   f"{upper[j] * scale:.4g}] {unit}: the closed loop does not hold the robot in its range "
                   "with these settings (controller, rate, limits)")
        raise JointLimitError(message, joints=(psm.actuated[index[j]],), values=position[k, [j]],
                              lower=lower[[j]], upper=upper[[j]])

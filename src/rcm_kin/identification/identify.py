"""``rcm-kin identify``: the drive trains of the PSM from a set of telemetry logs, validated.

Per joint the logs that can identify it (:mod:`rcm_kin.identification.log_catalog`) are
simulated by the stick-slip model (:mod:`rcm_kin.dynamics.stick_slip`) and the parameters
shared by all of them fitted (:mod:`rcm_kin.identification.drive_train`). With ``cv`` each log
is predicted by the model fitted on all the others.
The result goes into a drive parameter file: the ``[drive_train.<joint>]`` tables, and the
smooth model's constants (extra inertia, viscous, sliding friction) that the linearisation and
the gain schedule use, taken from the identified ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, load_drive_parameters, with_joint
from rcm_kin.dynamics.drive_uncertainty import DriveUncertainty, FoldSet
from rcm_kin.dynamics.state_space import DrivenDynamics, driven_dynamics
from rcm_kin.dynamics.stick_slip import AxisFriction, AxisPlant, axis_plant
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.bands import LEVEL, PredictionBand, calibrated_bands, named_preloads
from rcm_kin.identification.cross_validation import fit_with_cv, task_count, undetermined_ranges
from rcm_kin.identification.drive_train import (
    DEFAULT_TERMS,
    AxisLog,
    LogCheck,
    axis_log,
    check_log,
    closed_loop_log,
    jackknife_errors,
    predict_log,
    search_for,
    whole_log,
)
from rcm_kin.identification.log_catalog import CatalogEntry, catalog, classify
from rcm_kin.identification.speed_bounds import SpeedBound, speed_bounds
from rcm_kin.identification.telemetry import load_telemetry
from rcm_kin.model import load_robot

CLOSED_LOOP_START = 5.0        # s: a closed-loop record starts at the first rest after this
CLOSED_LOOP_SPAN = 10.0        # s of each closed-loop log used
GENERATIONS = (100, 100)        # evolutionary search: the fit on all logs, each cross-validation fold
TERMS = {"roll": ("presliding", "two_mass"),                # per joint: chosen by leave-one-log-out (docs/findings.md)
         "pitch": ("viscous", "presliding", "stiction")}

@dataclass(frozen=True)
class JointIdentification:
    joint: str
    friction: AxisFriction
    standard_errors: dict[str, float]      # per free parameter, its units: Gauss-Newton (local)
    jackknife_errors: dict[str, float]     # per free parameter: spread over the cross-validation folds
    logs: tuple[str, ...]                  # the logs fitted
    fits: tuple[LogCheck, ...]             # in-sample, per log
    cross_validation: tuple[LogCheck, ...]  # leave-one-log-out (empty without cv)
    bounds: tuple[SpeedBound, ...] = ()    # the constraints the fit satisfied (speed_bounds)
    folds: tuple[AxisFriction, ...] = ()   # per left-out log (aligned with cross_validation): its fold's fit
    inner_folds: tuple[tuple[AxisFriction, ...], ...] = ()  # per left-out log k: fits on all but k and j, j != k
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)   # undetermined parameters' ranges (SI)
    preloads: dict[str, float] = field(default_factory=dict)   # per step log: its best preload (fraction of F_p)
    cv_bands: tuple[PredictionBand, ...] = ()     # per left-out log (aligned with cross_validation): its band
    discrepancy: dict[str, float] = field(default_factory=dict)  # per log: its widening score, left out


@dataclass(frozen=True)
class Identification:
    joints: dict[str, JointIdentification]
    skipped: tuple[CatalogEntry, ...]
    params: DriveParameters                # the starting set with the identified drive trains
    notes: tuple[CatalogEntry, ...] = ()   # records that assume something (CatalogEntry.note)

    def as_dict(self) -> dict:
        def check(c: LogCheck) -> dict:
            return {"fit_percent": c.fit_percent, "travel_deg": c.travel_deg, "final_error_deg": c.final_error_deg,
                    "stick_time_s": c.stick_time, "predicted_stick_time_s": c.predicted_stick_time}
        return {"parameters": {j: r.friction.as_dict() for j, r in self.joints.items()},
                "standard_errors": {j: _finite(r.standard_errors) for j, r in self.joints.items()},
                "jackknife_standard_errors": {j: _finite(r.jackknife_errors) for j, r in self.joints.items()},
                "undetermined": {j: [n for n, v in r.standard_errors.items() if not np.isfinite(v)]
                                 for j, r in self.joints.items()},
                "logs": {j: list(r.logs) for j, r in self.joints.items()},
                "fits": {j: {c.name: check(c) for c in r.fits} for j, r in self.joints.items()},
                "cross_validation": {j: {c.name: check(c) for c in r.cross_validation}
                                     for j, r in self.joints.items()},
                "skipped": {f"{e.path.name} ({e.joint})": e.reason for e in self.skipped},
                "notes": {f"{e.path.name} ({e.joint})": e.note for e in self.notes},
                "folds": {j: [{"left_out": c.name, **f.as_dict()} for c, f in zip(r.cross_validation, r.folds)]
                          for j, r in self.joints.items()},
                "ranges": {j: {n: list(v) for n, v in r.ranges.items()} for j, r in self.joints.items()},
                "constraints": {j: {b.name: b.as_dict(r.friction) for b in r.bounds} for j, r in self.joints.items()},
                "preloads": {j: dict(r.preloads) for j, r in self.joints.items() if r.preloads},
                "discrepancy": {j: dict(r.discrepancy) for j, r in self.joints.items() if r.discrepancy},
                "cross_validation_band": {j: {b.name: b.scores() for b in r.cv_bands}
                                          for j, r in self.joints.items() if r.cv_bands}}


def _finite(errors: dict[str, float]) -> dict[str, float]:
    """The standard errors the data determine (a parameter the fit's residuals do not move has a
    NaN one: listed under ``undetermined`` instead)."""
    return {n: v for n, v in errors.items() if np.isfinite(v)}


def base_model(params: DriveParameters) -> DrivenDynamics:
    """The rigid-body model with the drive but without anything identified on the logs."""
    for joint in DRIVEN:
        params = with_joint(params, joint, extra_inertia=0.0, viscous=0.0, coulomb=0.0)
    return driven_dynamics(load_robot("psm"), params, coulomb=False)


def joint_records(entries: list[CatalogEntry], model: DrivenDynamics,
                  joint: str) -> tuple[list[AxisLog], list[AxisPlant]]:
    """The step logs and closed-loop records of ``joint`` (one per log file) and their plants."""
    logs = [axis_log(e.path, joint) if e.kind == "step"
            else closed_loop_log(e.path, joint, start=CLOSED_LOOP_START, duration=CLOSED_LOOP_SPAN)
            for e in entries if e.joint == joint and e.kind != "skipped"]
    return logs, [axis_plant(model, joint, log.pose) for log in logs]


def identify_joint(joint: str, logs: list[AxisLog], plants: list[AxisPlant], cv: bool, terms=None,
                   seed: int = 0, progress=None, bounds=(), workers: int | None = None,
                   hull: dict | None = None) -> JointIdentification:
    """Fit ``joint``'s drive train on ``logs`` subject to ``bounds`` (:mod:`speed_bounds`; with ``cv``
    cross-validated, leaving one log out, with the inner folds, and each left-out log's 90 % band,
    :func:`calibrated_bands`, its poses checked against ``hull``), the fits on ``workers`` processes
    (:func:`fit_with_cv`); ``progress()`` is called once per finished fit. The presliding preloads
    the logs' first rests show under the fit are its ``preloads``."""
    search = search_for(TERMS.get(joint, DEFAULT_TERMS) if terms is None else terms)
    result = fit_with_cv(search, plants, logs, seed, GENERATIONS, bounds, cv=cv, inner=cv, workers=workers,
                         progress=progress)
    friction, sigma = result.friction, result.standard_errors
    fits = tuple(check_log(log.name, log.measured, predict_log(friction, p, log), log.period)
                 for log, p in zip(logs, plants))
    errors = dict(zip(search.free, map(float, sigma)))
    ranges = undetermined_ranges(friction, plants, logs, [n for n, v in errors.items() if not np.isfinite(v)])
    bands, scores = calibrated_bands(result.folds, result.inner, plants, logs, LEVEL, ranges, hull) if cv else ((), ())
    return JointIdentification(joint, friction, errors,
                               jackknife_errors(result.folds, search.free) if result.folds else {},
                               tuple(log.name for log in logs), fits, result.checks, tuple(bounds), result.folds,
                               result.inner, ranges, named_preloads(friction, plants, logs, hull), bands, dict(scores))


def identify(paths, params: DriveParameters | None = None, joints=("roll",), cv: bool = False,
             seed: int = 0, progress: bool = False) -> Identification:
    """Identify the drive trains of ``joints`` from the logs in ``paths`` (files or folders),
    with a progress bar over the search's generations when ``progress``."""
    params = params or load_drive_parameters()
    entries = catalog(paths, joints)
    model = base_model(params)
    records = {}
    for joint in joints:
        records[joint] = joint_records(entries, model, joint)
        if not records[joint][0]:
            reasons = "; ".join(f"{e.path.name}: {e.reason}" for e in entries if e.joint == joint)
            raise RcmKinError(f"no log can identify the {joint}: {reasons or 'none given'}")
        if cv and len(records[joint][0]) < 2:
            raise RcmKinError(f"cross-validation of the {joint} needs at least 2 logs, got {records[joint][0][0].name}")
    total = sum(task_count(len(logs), cv, cv) for logs, _ in records.values())
    results = {}
    with tqdm(total=total, desc="identify", unit="fit", disable=not progress) as bar:
        for joint, (logs, plants) in records.items():
            bar.set_postfix_str(f"{joint}: {len(logs)} logs")
            bounds = speed_bounds(model, params, joint, _ramp_candidates(entries) if joint == "pitch" else ())
            results[joint] = identify_joint(joint, logs, plants, cv, seed=seed, progress=lambda: bar.update(),
                                            bounds=bounds, hull=params.uncertainty.hull)
    skipped = tuple(e for e in entries if e.kind == "skipped")
    notes = tuple(e for e in entries if e.note and e.joint in results)
    params = with_drive_trains(params, {j: r.friction for j, r in results.items()})
    return Identification(results, skipped, replace(params, uncertainty=with_uncertainty(params.uncertainty, results)),
                          notes)


def with_uncertainty(uncertainty: DriveUncertainty, results: dict[str, JointIdentification]) -> DriveUncertainty:
    """``uncertainty`` (its hull and holding residuals kept) with each identified joint's fold sets,
    preloads and widening scores (when cross-validated) and its undetermined parameters' ranges in
    place of any it had: an identified joint keeps nothing of the starting file's (a new drive train
    with the old one's folds or scores would be a band of another model)."""
    def replaced(old: dict, new) -> dict:
        return {**{j: v for j, v in old.items() if j not in results},
                **{j: new(r) for j, r in results.items() if new(r)}}
    return replace(uncertainty,
                   folds=replaced(uncertainty.folds, lambda r: tuple(FoldSet(c.name, f) for c, f
                                                                     in zip(r.cross_validation, r.folds))),
                   ranges=replaced(uncertainty.ranges, lambda r: r.ranges),
                   preloads=replaced(uncertainty.preloads, lambda r: tuple(r.preloads.values())),
                   discrepancy=replaced(uncertainty.discrepancy, lambda r: tuple(r.discrepancy.values())))


def _ramp_candidates(entries: list[CatalogEntry]) -> list:
    """The logs the pitch skipped that could be its PWM ramp (read again; unreadable ones left out)."""
    out = []
    for e in entries:
        if e.joint == "pitch" and e.kind == "skipped" and e.path.suffix == ".csv":
            try:
                out.append(load_telemetry(e.path))
            except RcmKinError:
                continue
    return out


def with_drive_trains(params: DriveParameters, frictions: dict[str, AxisFriction]) -> DriveParameters:
    """``params`` with identified drive trains, and the smooth model's constants taken from them:
    extra inertia and viscous friction as identified, the sliding friction as the Coulomb level
    plus the presliding spring's slip force (what a sliding axis feels)."""
    for joint, f in frictions.items():
        params = with_joint(params, joint, extra_inertia=f.extra_inertia, viscous=f.viscous + f.motor_viscous,
                            coulomb=f.coulomb + f.motor_coulomb + f.presliding_force)
    return replace(params, drive_train={**params.drive_train, **frictions})


def file_record(params: DriveParameters, path, joint: str) -> tuple[AxisLog, AxisPlant]:
    """The record :func:`predict_file` simulates in the log at ``path`` and its plant: a step log
    whole, from its first sample (at rest); a closed-loop log from its first rest with the
    controller that ran in the loop (:func:`closed_loop_log`). A log the model cannot speak for
    (:func:`classify`'s reasons), or a file without ``joint``'s drive train, is a clear error."""
    if joint not in params.drive_train:
        raise RcmKinError(f"{params.source} has no [drive_train.{joint}]: identify one first "
                          "(rcm-kin identify psm LOGS --out FILE.toml) and pass it with `params`", parameter="params")
    kind, reason = classify(load_telemetry(path), joint)
    if kind == "skipped":
        raise RcmKinError(f"{Path(path).name}: cannot predict the {joint}: {reason}")
    log = whole_log(path, joint) if kind == "step" else closed_loop_log(path, joint)
    return log, axis_plant(base_model(params), joint, log.pose)


def predict_file(params: DriveParameters, path, joint: str) -> tuple[AxisLog, np.ndarray, LogCheck]:
    """The identified ``joint`` model on the log at ``path`` (:func:`file_record`), no refitting:
    a step log from its first sample under its recorded PWM, a closed-loop log in its recorded
    loop. A prediction that leaves the model's range is a clear error. Returns the record, the
    predicted angle (rad) and its check."""
    log, plant = file_record(params, path, joint)
    return log, *predict_record(params, log, plant)


def predict_record(params: DriveParameters, log: AxisLog, plant: AxisPlant) -> tuple[np.ndarray, LogCheck]:
    """``params``'s drive train of ``log``'s joint on ``log`` (:func:`predict_log`): the predicted
    angle (rad) and its check, a non-finite prediction a clear error."""
    joint = log.joint
    predicted = predict_log(params.drive_train[joint], plant, log)
    check = check_log(log.name, log.measured, predicted, log.period)
    if not (np.all(np.isfinite(predicted)) and np.isfinite(check.fit_percent)):
        raise RcmKinError(f"{log.name}: the {joint} model's prediction is not finite (is [drive_train.{joint}] "
                          "sensible?)")
    return predicted, check

"""``rcm-kin identify``: the drive trains of the PSM from a set of telemetry logs, validated.

Per joint the logs that can identify it (:mod:`rcm_kin.identification.log_catalog`) are
simulated by the stick-slip model (:mod:`rcm_kin.dynamics.stick_slip`) and the parameters
shared by all of them fitted (:mod:`rcm_kin.identification.drive_train`). With ``cv`` each log
(each file, for closed-loop windows) is predicted by the model fitted on all the others.
The result goes into a drive parameter file: the ``[drive_train.<joint>]`` tables, and the
smooth model's constants (extra inertia, viscous, sliding friction) that the linearisation and
the gain schedule use, taken from the identified ones.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import numpy as np
from tqdm import tqdm

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, load_drive_parameters, with_joint
from rcm_kin.dynamics.state_space import DrivenDynamics, driven_dynamics
from rcm_kin.dynamics.stick_slip import AxisFriction, AxisPlant, axis_plant
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.drive_train import (DEFAULT_TERMS, AxisLog, LogCheck, axis_log, check_log,
                                                fit_friction, jackknife_errors, leave_one_out, predict_log,
                                                rest_windows, search_for)
from rcm_kin.identification.log_catalog import CatalogEntry, catalog
from rcm_kin.robot import load_robot

WINDOWS_PER_LOG = 40            # closed-loop windows used per log (evenly spread)
WINDOW = 0.3                    # s: closed-loop window length (the pitch without its loop diverges in ~0.25 s)
FLOOR = np.radians(0.2)         # rad RMS: least spread a closed-loop window is scaled by


@dataclass(frozen=True)
class JointIdentification:
    joint: str
    friction: AxisFriction
    standard_errors: dict[str, float]      # per free parameter, its units: Gauss-Newton (local)
    jackknife_errors: dict[str, float]     # per free parameter: spread over the cross-validation folds
    logs: tuple[str, ...]                  # the logs fitted (closed-loop: with their window count)
    fits: tuple[LogCheck, ...]             # in-sample, per step log (closed loop: per window)
    cross_validation: tuple[LogCheck, ...]  # leave-one-log-out (empty without cv)


@dataclass(frozen=True)
class Identification:
    joints: dict[str, JointIdentification]
    skipped: tuple[CatalogEntry, ...]
    params: DriveParameters                # the starting set with the identified drive trains

    def as_dict(self) -> dict:
        def check(c: LogCheck) -> dict:
            return {"fit_percent": c.fit_percent, "travel_deg": c.travel_deg, "final_error_deg": c.final_error_deg,
                    "stick_time_s": c.stick_time, "predicted_stick_time_s": c.predicted_stick_time}
        return {"parameters": {j: r.friction.as_dict() for j, r in self.joints.items()},
                "standard_errors": {j: r.standard_errors for j, r in self.joints.items()},
                "jackknife_standard_errors": {j: r.jackknife_errors for j, r in self.joints.items()},
                "logs": {j: list(r.logs) for j, r in self.joints.items()},
                "fits": {j: {c.name: check(c) for c in r.fits} for j, r in self.joints.items()},
                "cross_validation": {j: {c.name: check(c) for c in r.cross_validation}
                                     for j, r in self.joints.items()},
                "skipped": {f"{e.path.name} ({e.joint})": e.reason for e in self.skipped}}


def base_model(params: DriveParameters) -> DrivenDynamics:
    """The rigid-body model with the drive but without anything identified on the logs."""
    for joint in DRIVEN:
        params = with_joint(params, joint, extra_inertia=0.0, viscous=0.0, coulomb=0.0)
    return driven_dynamics(load_robot("psm"), params, coulomb=False)


def joint_records(entries: list[CatalogEntry], model: DrivenDynamics,
                  joint: str) -> tuple[list[AxisLog], list[AxisPlant], list[str]]:
    """The step logs and closed-loop windows of ``joint``, their plants, and the file each is from."""
    logs, plants, files = [], [], []
    for e in entries:
        if e.joint != joint or e.kind == "skipped":
            continue
        if e.kind == "step":
            found = [axis_log(e.path, joint)]
        else:
            windows = rest_windows(e.path, joint, WINDOW)
            found = [windows[i] for i in np.unique(np.linspace(0, len(windows) - 1, WINDOWS_PER_LOG).astype(int))] \
                if windows else []
        if found:
            plant = axis_plant(model, joint, found[0].pose)
            logs += found
            plants += [plant] * len(found)
            files += [e.path.name] * len(found)
    return logs, plants, files


def identify_joint(joint: str, logs: list[AxisLog], plants: list[AxisPlant], files: list[str], cv: bool,
                   terms=DEFAULT_TERMS, seed: int = 0, progress=None) -> JointIdentification:
    """Fit ``joint``'s drive train on ``logs`` (and cross-validate, leaving one file out)."""
    search = search_for(terms)
    closed = any(len(log.name.split("@")) > 1 for log in logs)
    floor = FLOOR if closed else 0.0
    friction, sigma = fit_friction(search, plants, logs, seed=seed, floor=floor, progress=progress)
    fits = tuple(check_log(log.name, log.measured, predict_log(friction, p, log), log.period)
                 for log, p in zip(logs, plants))
    checks, folds = [], []
    if cv:
        if len(set(files)) < 2:
            raise RcmKinError(f"cross-validation of the {joint} needs logs from at least 2 files")
        run = _leave_file_out if closed else leave_one_out_files
        checks, folds = run(search, plants, logs, files, friction, seed, floor)
    counts = {f: files.count(f) for f in dict.fromkeys(files)}
    return JointIdentification(joint, friction, dict(zip(search.free, map(float, sigma))),
                               jackknife_errors(folds, search.free) if folds else {},
                               tuple(f if n == 1 else f"{f} ({n} windows)" for f, n in counts.items()),
                               fits, tuple(checks))


def leave_one_out_files(search, plants, logs, files, start, seed, floor):
    """Step logs: one record per file, so leaving a file out is leaving its log out."""
    return leave_one_out(search, plants, logs, start, seed=seed, floor=floor)


def _leave_file_out(search, plants, logs, files, start, seed, floor) -> list[LogCheck]:
    """Per file, its windows predicted by the model fitted on the other files' (median fit)."""
    out, folds = [], []
    for name in dict.fromkeys(files):
        keep = [i for i, f in enumerate(files) if f != name]
        friction, _ = fit_friction(search, [plants[i] for i in keep], [logs[i] for i in keep], seed=seed,
                                   start=start, generations=40, floor=floor)
        folds.append(friction)
        checks = [check_log(logs[i].name, logs[i].measured, predict_log(friction, plants[i], logs[i]),
                            logs[i].period) for i, f in enumerate(files) if f == name]
        out.append(LogCheck(name, float(np.median([c.fit_percent for c in checks])),
                            float(np.mean([c.travel_deg for c in checks])),
                            float(np.mean([c.final_error_deg for c in checks])),
                            float(np.mean([c.stick_time for c in checks])),
                            float(np.mean([c.predicted_stick_time for c in checks]))))
    return out, folds


def identify(paths, params: DriveParameters | None = None, joints=("roll", "pitch"), cv: bool = False,
             seed: int = 0, progress: bool = False) -> Identification:
    """Identify the drive trains of ``joints`` from the logs in ``paths`` (files or folders)."""
    params = params or load_drive_parameters()
    entries = catalog(paths, joints)
    model = base_model(params)
    results = {}
    with tqdm(total=len(joints), desc="identify", unit="joint", disable=not progress) as bar:
        for joint in joints:
            logs, plants, files = joint_records(entries, model, joint)
            if not logs:
                raise RcmKinError(f"no log can identify the {joint}: " + "; ".join(
                    f"{e.path.name}: {e.reason}" for e in entries if e.joint == joint) or "none given")
            bar.set_postfix_str(f"{joint}: {len(logs)} records")
            results[joint] = identify_joint(joint, logs, plants, files, cv, seed=seed)
            bar.update()
    skipped = tuple(e for e in entries if e.kind == "skipped")
    return Identification(results, skipped, with_drive_trains(params, {j: r.friction for j, r in results.items()}))


def with_drive_trains(params: DriveParameters, frictions: dict[str, AxisFriction]) -> DriveParameters:
    """``params`` with identified drive trains, and the smooth model's constants taken from them:
    extra inertia and viscous friction as identified, the sliding friction as the Coulomb level
    plus the presliding spring's slip force (what a sliding axis feels)."""
    for joint, f in frictions.items():
        params = with_joint(params, joint, extra_inertia=f.extra_inertia, viscous=f.viscous + f.motor_viscous,
                            coulomb=f.coulomb + f.motor_coulomb + f.presliding_force)
    return replace(params, drive_train={**params.drive_train, **frictions})

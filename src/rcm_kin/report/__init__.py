"""``rcm-kin report``: the main job on the bundled models, written as a browsable index.html.

Sections (one module each in :mod:`rcm_kin.report.sections`, one template each in ``templates/``):
pictures and meshcat pages of the robots, the models and their kinematic self-checks, holding-effort
maps with the thesis Fig 4.6/4.7 curves, the drive parameters and the counterweight designs, the
MTM's torque map, counterweight and linear models, the linear models per grid pose, the model-based
gain schedule beside the thesis's tables, the thesis's tracking experiments (P against the
scheduled controller) with animations, the gains tuned by simulation (the shipped design on the
nominal robot beside the thesis law and the LQR/LQI schedule, and its design study), the
controllers' robustness to the parameter uncertainty (a small Monte Carlo, the same as `rcm-kin
robustness` gives on Dask), and the safety filters and certificates. With a data folder:
calibration, identification per pose, the grey-box fit, and the identified drive train against
every step log (each also left out of the fit) on the measured logs.

Each section computes a plain data object; :mod:`rcm_kin.report.render` renders them. The
sections are cut into independent pieces (:func:`report_jobs`) that a process pool runs on the
machine's cores (:func:`run_jobs`), and put together in a fixed order. Every link in index.html
is relative to the report folder, so the folder can be moved or served.
"""

from __future__ import annotations

import html
import os
import time
from collections.abc import Callable
from concurrent.futures import as_completed
from dataclasses import dataclass
from pathlib import Path

from rcm_kin.atomic import write_text
from rcm_kin.errors import RcmKinError, output_folder, recording_warnings, reissue
from rcm_kin.parallel import check_workers, machine_workers, process_pool


def write_report(out: str | Path, data: str | Path | None = None, map_points: int = 61,
                 progress: bool = False, workers: int | None = None) -> Path:
    """Run the pipeline on the bundled models (and, with ``data``, on a folder of measured logs);
    ``map_points`` per axis of the holding-effort maps. Returns the path of index.html.

    Independent pieces of the sections (:func:`report_jobs`) run in a pool of ``workers``
    processes (default: the cores this process may use, at most 4); each writes its own files and
    returns its data object, the sections are put together from them and the index lists them in
    a fixed order, so the report is the same whatever the number of workers or the order in which
    they finish. A report that fails leaves an index.html that says so."""
    from rcm_kin.identification.calibration import calibration_logs
    from rcm_kin.statics.maps import check_map_size

    if not isinstance(out, (str, Path)) or not str(out).strip():
        raise RcmKinError(f"`out` is a folder's path, got {str(out)[:40]!r}", parameter="out")
    if isinstance(map_points, bool) or not isinstance(map_points, int) or map_points < 2:
        raise RcmKinError(f"the effort maps need a whole number of at least 2 points per axis, got {map_points!r}",
                          parameter="map_points")
    check_map_size(map_points**2)
    if workers is not None:
        check_workers(workers)
    if data is not None:
        calibration_logs(data)           # the measured logs are there before minutes of work
    out = output_folder(out)
    try:
        return _write_sections(out, data, map_points, progress, workers or min(4, machine_workers()))
    except (RcmKinError, OSError) as exc:   # a folder with files but no index would look like a report
        write_text(out / "index.html", f"<!doctype html><title>rcm-kin report: failed</title>"
                                       f"<p>The report was not completed: {html.escape(str(exc))}</p>\n")
        raise


@dataclass(frozen=True)
class Job:
    """A piece of the report that a pool worker runs on its own: ``function(*arguments)``, a data
    object back (pickled), its files written into the report folder."""

    label: str
    function: Callable
    arguments: tuple


@dataclass(frozen=True)
class JobResult:
    """What a piece gave back, how long it took and which worker ran it."""

    value: object
    seconds: float      # wall time in the worker
    worker: int         # the worker's process id
    warnings: tuple = ()    # (category, message) of each warning the piece raised


def report_jobs(out: Path, data, map_points: int) -> list[Job]:
    """The report's independent pieces, the longest first so that the pool's workers finish
    together (each worker takes the next piece when it is free). CPU seconds of each piece alone
    in a worker forked after :func:`preload`, its own imports included (``benchmarks/bench_report.py
    --alone``; ``--pieces`` times them in the pool; docs/performance.md): safety's linear scenarios
    2.6-2.9, safety's certificates 1.9-2.0, tracking 1.2-1.8 per experiment, safety's PSM teleoperation
    1.4-1.8, robustness 1.6, tuned gains 1.4, effort maps 1.2, MTM 1.0, gain schedule 0.8, MuJoCo 0.8,
    robot views 0.7, models 0.7 (the list's order is close enough: within a few tenths of a second of
    the best split on 2 workers). The pieces that need the nominal gain schedule design it once per
    worker (:func:`rcm_kin.simulation.experiments.psm_schedule`)."""
    from rcm_kin.report.sections.drive_train import drive_train_section
    from rcm_kin.report.sections.gravity import gravity_section
    from rcm_kin.report.sections.measured import measured_section
    from rcm_kin.report.sections.models import models_section
    from rcm_kin.report.sections.mtm import mtm_section
    from rcm_kin.report.sections.mujoco import mujoco_section
    from rcm_kin.report.sections.robots import robots_section
    from rcm_kin.report.sections.robustness import robustness_section
    from rcm_kin.report.sections.safety import safety_checks, scenario_runs
    from rcm_kin.report.sections.tuning import tuning_section
    from rcm_kin.safety.scenarios import SCENARIOS

    linear = tuple(s for s in SCENARIOS if s != "psm")      # the scenarios with a barrier figure, in one piece
    recording = _mtm_recording(data)
    jobs = []
    if data is not None:
        jobs += [Job("measured data", measured_section, (out, Path(data))),
                 Job("identified drive train", drive_train_section, (out, Path(data)))]
    return jobs + [
        Job("tracking: sine", _tracking_part, (out, "sine", recording)),
        Job("tracking: target", _tracking_part, (out, "target", recording)),
        Job("safety: PSM teleoperation", scenario_runs, (out, ("psm",))),
        Job("robustness", robustness_section, (out,)),
        Job("safety: linear scenarios", scenario_runs, (out, linear)),
        Job("gains tuned by simulation", tuning_section, (out,)),
        Job("effort maps", gravity_section, (out, map_points)), Job("MTM", mtm_section, (out, map_points)),
        Job("gain schedule, linear models", _schedule_sections, (out,)),
        Job("safety: certificates, RCM", safety_checks, ()),
        Job("MuJoCo", mujoco_section, (out,)), Job("robot views", robots_section, (out,)),
        Job("models checked", models_section, (out,))]


def _timed(function: Callable, arguments: tuple) -> JobResult:
    start = time.perf_counter()
    value, raised = recording_warnings(function, *arguments)
    return JobResult(value, time.perf_counter() - start, os.getpid(), tuple(raised))


def run_jobs(jobs: list[Job], workers: int, progress: bool = False) -> dict[str, JobResult]:
    """``jobs`` in a pool of ``workers`` forked processes, taken in their order; label -> result.
    The first error in a job is raised here, the other jobs cancelled or stopped (:func:`process_pool`)."""
    from tqdm import tqdm

    preload()
    results = {}
    with tqdm(total=len(jobs), desc="report", unit="part", disable=not progress) as bar:
        with process_pool(workers) as pool:
            futures = {pool.submit(_timed, job.function, job.arguments): job.label for job in jobs}
            for future in as_completed(futures):
                results[futures[future]] = future.result()
                reissue(results[futures[future]].warnings)   # a forked worker's warnings reach the caller
                bar.set_postfix_str(futures[future])
                bar.update()
    return results


# imported before the fork, once, by the modules that more than one worker imports (each worker
# imported them again: matplotlib alone is about 0.5 s of CPU a worker); the others stay in theirs
PRELOAD = ("rcm_kin.visualization.views", "scipy.interpolate", "rcm_kin.simulation.experiments")


def preload() -> None:
    """Import :data:`PRELOAD` and matplotlib's figure and Agg canvas
    (:func:`rcm_kin.plotting.figure_classes`) in this process, before the pool forks."""
    import importlib

    from rcm_kin.plotting import figure_classes

    figure_classes()
    for name in PRELOAD:
        importlib.import_module(name)


def _write_sections(out: Path, data, map_points: int, progress: bool, workers: int) -> Path:
    """The sections (see :func:`write_report`) from the pieces run in a process pool, then index.html."""
    from rcm_kin.report.render import render_index
    from rcm_kin.report.sections.safety import safety_from_parts
    from rcm_kin.report.sections.tracking import tracking_from_parts

    results = {label: r.value for label, r in run_jobs(report_jobs(out, data, map_points), workers, progress).items()}
    schedule, linear = results["gain schedule, linear models"]
    tracking = tracking_from_parts([results["tracking: sine"], results["tracking: target"]], _mtm_recording(data))
    safety = safety_from_parts([results["safety: linear scenarios"], results["safety: PSM teleoperation"]],
                               results["safety: certificates, RCM"])
    sections = [results["robot views"], results["models checked"], results["effort maps"], results["MTM"], linear,
                schedule,
                tracking, results["gains tuned by simulation"], results["robustness"], safety]
    sections += [s for s in [results["MuJoCo"]] if s is not None]   # with the [mujoco] extra
    if data is not None:
        sections.append(results["measured data"])
        identified = results["identified drive train"]
        sections += [identified] if identified is not None else []
    index = out / "index.html"
    write_text(index, render_index(sections))
    return index


def _schedule_sections(out: Path) -> tuple:
    """The gain schedule and the linear models of its grid."""
    from rcm_kin.report.sections.linear_models import linear_models_section
    from rcm_kin.report.sections.schedule import schedule_section

    schedule = schedule_section(out)
    return schedule, linear_models_section(out, schedule.schedule)


def _tracking_part(out: Path, experiment: str, recording: Path | None):
    """One tracking experiment with the nominal gain schedule (the schedule section's)."""
    from rcm_kin.report.sections.tracking import tracking_experiment
    from rcm_kin.simulation.experiments import psm_schedule

    return tracking_experiment(out, psm_schedule(), experiment, recording)


def _mtm_recording(data) -> Path | None:
    """The MTM recording of a data folder (``mtm_target_trajectory.csv``), if there is one."""
    found = sorted(Path(data).glob("**/mtm_target_trajectory.csv")) if data is not None else []
    return found[0] if found else None

"""``rcm-kin report``: the main job on the bundled models, written as a browsable index.html.

Sections (one module each in :mod:`rcm_kin.report.sections`, one template each in
``templates/``): pictures and meshcat pages of the robots, the models and their kinematic
self-checks, holding-effort maps with the thesis Fig 4.6/4.7 curves, the drive parameters and
the counterweight designs, the linear models per grid pose, the model-based gain schedule
beside the thesis's tables, the thesis's tracking experiments (P against the scheduled
controller) with animations, the controllers' robustness to the parameter uncertainty (a small
Monte Carlo, the same as `rcm-kin robustness` gives on Dask), and the safety filters and certificates. With a data folder:
calibration, identification per pose, the grey-box fit, and the identified drive train against
every step log (each also left out of the fit) on the measured logs.

Each section computes a plain data object; :mod:`rcm_kin.report.render` renders them. Every
link in index.html is relative to the report folder, so the folder can be moved or served.
"""

from __future__ import annotations

import html
from pathlib import Path

from rcm_kin.errors import RcmKinError, output_folder


def write_report(out: str | Path, data: str | Path | None = None, map_points: int = 61,
                 progress: bool = False, workers: int | None = None) -> Path:
    """Run the pipeline on the bundled models (and, with ``data``, on a folder of measured logs);
    ``map_points`` per axis of the holding-effort maps. Returns the path of index.html.

    Independent sections run in a pool of ``workers`` processes (default: the cores this process
    may use, at most 4); each writes its own files and returns its data object, and the index
    lists them in a fixed order, so the report is the same whatever the number of workers or the
    order in which they finish. A report that fails leaves an index.html that says so."""
    from rcm_kin.robustness.execution import machine_workers
    from rcm_kin.statics.calibration import calibration_logs
    from rcm_kin.statics.gravity_map import check_map_size

    if map_points < 2:
        raise RcmKinError("the effort maps need at least 2 points per axis")
    check_map_size(map_points**2)
    if data is not None:
        calibration_logs(data)           # the measured logs are there before minutes of work
    out = output_folder(out)
    try:
        return _write_sections(out, data, map_points, progress, workers or min(4, machine_workers()))
    except (RcmKinError, OSError) as exc:   # a folder with files but no index would look like a report
        (out / "index.html").write_text(f"<!doctype html><title>rcm-kin report: failed</title>"
                                        f"<p>The report was not completed: {html.escape(str(exc))}</p>\n")
        raise


def _write_sections(out: Path, data, map_points: int, progress: bool, workers: int) -> Path:
    """The sections (see :func:`write_report`) in a process pool, then index.html."""
    from concurrent.futures import ProcessPoolExecutor
    from multiprocessing import get_context

    from tqdm import tqdm

    from rcm_kin.report.render import render_index
    from rcm_kin.report.sections.drive_train import drive_train_section
    from rcm_kin.report.sections.gravity import gravity_section
    from rcm_kin.report.sections.measured import measured_section
    from rcm_kin.report.sections.models import models_section
    from rcm_kin.report.sections.mujoco import mujoco_section
    from rcm_kin.report.sections.robots import robots_section
    from rcm_kin.report.sections.robustness import robustness_section
    from rcm_kin.report.sections.safety import safety_section

    # (label, function, arguments), the longest first (safety ~18 s, the control chain ~15 s, robustness
    # ~13 s in its worker, the rest a few s each on this machine) so that the pool's
    # workers finish together
    jobs = [("safety", safety_section, (out,)),
            ("gain schedule, linear models, tracking", _control_sections, (out, _mtm_recording(data))),
            ("robustness", robustness_section, (out,)),
            ("effort maps", gravity_section, (out, map_points)), ("robot views", robots_section, (out,)),
            ("models checked", models_section, (out,)), ("MuJoCo", mujoco_section, (out,))]
    if data is not None:
        jobs += [("measured data", measured_section, (out, Path(data))),
                 ("identified drive train", drive_train_section, (out, Path(data)))]
    with tqdm(total=len(jobs) + 1, desc="report", unit="section", disable=not progress) as bar:
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("fork")) as pool:
            futures = [pool.submit(function, *arguments) for _, function, arguments in jobs]
            results = {}
            for (label, _, _), future in zip(jobs, futures):
                results[label] = future.result()
                bar.set_postfix_str(label)
                bar.update()
        schedule, linear, tracking = results["gain schedule, linear models, tracking"]
        sections = [results["robot views"], results["models checked"], results["effort maps"], linear, schedule,
                    tracking, results["robustness"], results["safety"]]
        sections += [s for s in [results["MuJoCo"]] if s is not None]   # with the [mujoco] extra
        if data is not None:
            sections.append(results["measured data"])
            identified = results["identified drive train"]
            sections += [identified] if identified is not None else []
        index = out / "index.html"
        index.write_text(render_index(sections))
        bar.set_postfix_str("index.html")
        bar.update()
    return index


def _control_sections(out: Path, recording: Path | None) -> tuple:
    """The sections that share the gain schedule: the schedule, the linear models, the tracking."""
    from rcm_kin.report.sections.linear_models import linear_models_section
    from rcm_kin.report.sections.schedule import schedule_section
    from rcm_kin.report.sections.tracking import tracking_section

    schedule = schedule_section(out)
    return schedule, linear_models_section(out, schedule.schedule), tracking_section(out, schedule.schedule, recording)


def _mtm_recording(data) -> Path | None:
    """The MTM recording of a data folder (``mtm_target_trajectory.csv``), if there is one."""
    found = sorted(Path(data).glob("**/mtm_target_trajectory.csv")) if data is not None else []
    return found[0] if found else None

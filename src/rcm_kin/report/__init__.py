"""``rcm-kin report``: the main job on the bundled models, written as a browsable index.html.

Sections (one module each in :mod:`rcm_kin.report.sections`, one template each in
``templates/``): pictures and meshcat pages of the robots, the models and their kinematic
self-checks, holding-effort maps with the thesis Fig 4.6/4.7 curves, the drive parameters and
the counterweight designs, the linear models per grid pose, the model-based gain schedule
beside the thesis's tables, the thesis's tracking experiments (P against the scheduled
controller) with animations, and the safety filters and certificates. With a data folder:
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
                 progress: bool = False) -> Path:
    """Run the pipeline on the bundled models (and, with ``data``, on a folder of measured logs);
    ``map_points`` per axis of the holding-effort maps. Returns the path of index.html."""
    from rcm_kin.statics.calibration import calibration_logs
    from rcm_kin.statics.gravity_map import check_map_size

    if map_points < 2:
        raise RcmKinError("the effort maps need at least 2 points per axis")
    check_map_size(map_points**2)
    if data is not None:
        calibration_logs(data)           # the measured logs are there before minutes of work
    out = output_folder(out)
    try:
        return _write_sections(out, data, map_points, progress)
    except RcmKinError as exc:           # a folder with files but no index would look like a report
        (out / "index.html").write_text(f"<!doctype html><title>rcm-kin report: failed</title>"
                                        f"<p>The report was not completed: {html.escape(str(exc))}</p>\n")
        raise


def _write_sections(out: Path, data, map_points: int, progress: bool) -> Path:
    """The sections in order (see :func:`write_report`), then index.html."""
    from tqdm import tqdm

    from rcm_kin.report.render import render_index
    from rcm_kin.report.sections.drive_train import drive_train_section
    from rcm_kin.report.sections.gravity import gravity_section
    from rcm_kin.report.sections.linear_models import linear_models_section
    from rcm_kin.report.sections.measured import measured_section
    from rcm_kin.report.sections.models import models_section
    from rcm_kin.report.sections.robots import robots_section
    from rcm_kin.report.sections.safety import safety_section
    from rcm_kin.report.sections.schedule import schedule_section
    from rcm_kin.report.sections.tracking import tracking_section

    with tqdm(total=8 if data is None else 9, desc="report", unit="step", disable=not progress) as bar:
        def step(name: str) -> None:
            bar.set_postfix_str(name)
            bar.update()

        robots = robots_section(out)
        step("robot views")
        models = models_section(out)
        step("models checked")
        gravity = gravity_section(out, map_points)
        step("effort maps")
        schedule = schedule_section(out)
        step("gain schedule")
        linear = linear_models_section(out, schedule.schedule)
        step("linear models")
        tracking = tracking_section(out, schedule.schedule, _mtm_recording(data))
        step("tracking experiments")
        sections = [robots, models, gravity, linear, schedule, tracking, safety_section(out)]
        step("safety")
        if data is not None:
            sections.append(measured_section(out, Path(data)))
            identified = drive_train_section(out, Path(data))
            sections += [identified] if identified is not None else []
            step("measured data")
        index = out / "index.html"
        index.write_text(render_index(sections))
        step("index.html")
    return index


def _mtm_recording(data) -> Path | None:
    """The MTM recording of a data folder (``mtm_target_trajectory.csv``), if there is one."""
    found = sorted(Path(data).glob("**/mtm_target_trajectory.csv")) if data is not None else []
    return found[0] if found else None

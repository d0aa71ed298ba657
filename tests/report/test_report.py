"""The main job: `rcm-kin report` writes index.html and every file it links.

Each section is tested on small inputs (its data object, the files it wrote, its template with
relative links only); one end-to-end run of the whole report is marked slow.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from rcm_kin.cli import main
from rcm_kin.report.render import Table, render_index, render_section

LINK = re.compile(r'(?:href|src)="([^"#]+)"')


def linked_files(folder):
    index = (folder / "index.html").read_text()
    return index, LINK.findall(index)


def assert_renders(section, out: Path, expected: set[str] = frozenset()) -> str:
    """The section's template renders, every link is relative and names a written file."""
    html = render_section(section)
    links = LINK.findall(html)
    assert expected <= set(links)
    for link in links:
        assert not link.startswith("/") and "://" not in link and ".." not in link, link
        assert (out / link).stat().st_size > 0, link
    assert str(out) not in html
    return html


def test_table_escapes_and_relative_paths(tmp_path):
    from rcm_kin.report.render import relative

    table = Table.of([["<b>", 1.5]], ["a & b", "x"])
    assert table.rows == (("<b>", "1.5"),)
    assert relative(tmp_path / "tracking" / "x.png", tmp_path) == "tracking/x.png"

    @dataclasses.dataclass(frozen=True)
    class Probe:
        template = "linear_models.html.j2"
        table: Table
        data: str

    html = render_section(Probe(table, "linear_models.json"))
    assert "&lt;b&gt;" in html and "a &amp; b" in html and "<b>" not in html
    page = render_index([Probe(table, "linear_models.json")])
    assert page.startswith("<!doctype html>") and "<h1>rcm-kin report</h1>" in page


def test_models_section(tmp_path):
    from rcm_kin.report.sections.models import models_section

    s = models_section(tmp_path, samples=3)
    assert [m.robot for m in s.models] == ["psm", "mtm"]
    assert s.checks.samples == 3 and s.checks.psm_ik_round_trip < 1e-6 and s.checks.closure_residual < 1e-8
    assert s.models[0].joints.header == ("joint", "type", "role", "lower", "upper")
    assert {"actuated", "passive"} <= {row[2] for row in s.models[0].joints.rows}
    html = assert_renders(s, tmp_path, {"model_summary.json", "kinematic_checks.json"})
    assert "Kinematic self-checks (3 random PSM configurations)" in html


def test_robots_section(tmp_path):
    from rcm_kin.report.sections.robots import robots_section

    s = robots_section(tmp_path, names=("mtm",))
    assert [(v.picture, v.page) for v in s.views] == [("mtm.png", "mtm_view.html")]
    assert_renders(s, tmp_path, {"mtm.png", "mtm_view.html"})


def test_gravity_section(tmp_path):
    from rcm_kin.hardware import DPM_COUNTERWEIGHT, HOME_INSERTION, MAIN_COUNTERWEIGHT
    from rcm_kin.report.sections.gravity import gravity_section

    s = gravity_section(tmp_path, map_points=3, design_points=3)
    assert s.insertion_mm == pytest.approx(HOME_INSERTION * 1e3) and s.map_points == 3
    assert s.figures == {"torque_map": "torque_map.png", "trend_curves": "trend_curves.png",
                         "insertion_map": "insertion_map.png"}
    assert len(s.designs.rows) == 2 and s.dpm_distance_ratio > 1.0
    assert s.osmdv_main == pytest.approx((MAIN_COUNTERWEIGHT[0], MAIN_COUNTERWEIGHT[1] * 1e3))
    assert s.osmdv_dpm[1] == pytest.approx(DPM_COUNTERWEIGHT[1] * 1e3)
    html = assert_renders(s, tmp_path, {"torque_map.png", "trend_curves.png", "insertion_map.png",
                                        "torque_map.csv", "insertion_map.csv"})
    assert "Counterweight design" in html and "200.28 mm" in html and "Fig 4.6" in html
    assert s.drive_source == "psm_drive.toml"


def test_mtm_section(tmp_path):
    """The MTM's section: its map's CSV is plain Pinocchio's gravity at every pose, the placed
    counterweight beats the one as built, and the linear models' holding torques are gravity's."""
    import csv
    import json

    import numpy as np
    import pinocchio as pin

    from rcm_kin.model.loading import urdf_dir
    from rcm_kin.report.sections.mtm import mtm_section

    s = mtm_section(tmp_path, map_points=4)
    html = assert_renders(s, tmp_path, {"mtm/torque_map.png", "mtm/torque_map.csv", "mtm/linear_models.json"})
    assert "The MTM" in html and "CAD (URDF inertias)" in html and s.model == "CAD (URDF inertias)"
    model = pin.buildModelFromUrdf(str(urdf_dir() / "mtm.urdf"))
    data = model.createData()
    idx = {n: model.joints[model.getJointId(n)].idx_q for n in ("j1", "j3")}

    def gravity(j1, j3):
        q = np.zeros(model.nq)
        q[idx["j1"]], q[idx["j3"]] = j1, j3
        return pin.computeGeneralizedGravity(model, data, q)

    with open(tmp_path / "mtm" / "torque_map.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 16
    for row in rows:
        tau = gravity(np.radians(float(row["j1_deg"])), np.radians(float(row["j3_deg"])))
        assert float(row["tau_j1"]) == pytest.approx(tau[idx["j1"]], abs=2e-9)
        assert float(row["tau_j3"]) == pytest.approx(tau[idx["j3"]], abs=2e-9)
    for entry in json.loads((tmp_path / "mtm" / "linear_models.json").read_text()):
        tau = gravity(np.radians(entry["j1_deg"]), np.radians(entry["j3_deg"]))
        np.testing.assert_allclose(entry["u_hold_N_m"], tau[[idx["j1"], idx["j3"]]], atol=1e-12)
    design = {row[0]: [float(c) for c in row[1:]] for row in s.counterweight.rows}
    assert design["j1"][2] < design["j1"][1] < design["j1"][0]       # placed < as built < without


@pytest.fixture(scope="module")
def schedule_section_small(tmp_path_factory):
    from rcm_kin.report.sections.schedule import schedule_section

    out = tmp_path_factory.mktemp("schedule")
    return out, schedule_section(out, survey_points=3)


def test_schedule_section(schedule_section_small):
    from rcm_kin.thesis import K_PITCH, K_ROLL

    out, s = schedule_section_small
    assert s.survey_points == 3 and len(s.gains.rows) == 15
    assert [row[0] for row in s.verdicts.rows] == ["model-based schedule", "thesis tables",
                                                   "thesis tables, Kd sign flipped"]
    c = s.contrast
    assert c.thesis_kp_roll == (K_ROLL[..., 0].min(), K_ROLL[..., 0].max())
    assert c.thesis_kp_pitch == (K_PITCH[..., 0].min(), K_PITCH[..., 0].max())
    assert c.thesis_roll_zero == pytest.approx(2.0609, abs=1e-4) and c.stiffness_ratio > 10
    html = assert_renders(s, out, {"stability_maps.png", "gain_schedule/gains.json", "gain_schedule/gain_schedule.h"})
    assert "Tables 4.4-4.8" in html and "+2.06 rad/s" in html


def test_linear_models_section(schedule_section_small, tmp_path):
    from rcm_kin.report.sections.linear_models import linear_models_section

    schedule = schedule_section_small[1].schedule
    s = linear_models_section(tmp_path, schedule)
    assert len(s.table.rows) == schedule.roll_deg.size * schedule.pitch_deg.size
    assert_renders(s, tmp_path, {"linear_models.json"})


def test_tracking_section(schedule_section_small, tmp_path):
    from rcm_kin.report.sections.tracking import CONTROLLERS, tracking_section
    from rcm_kin.thesis import SINE_TRACKING_ERROR_DEG

    s = tracking_section(tmp_path, schedule_section_small[1].schedule, experiments=("sine",), duration=0.6)
    assert len(s.table.rows) == 2 * len(CONTROLLERS)
    thesis = {(row[1], row[2]): row[-1] for row in s.table.rows}
    assert thesis[("p", "roll")] == "{:.2f} / {:.2f}".format(*SINE_TRACKING_ERROR_DEG[("p", "roll")])
    assert thesis[("scheduled-gravity", "roll")] == ""
    html = assert_renders(s, tmp_path, {"tracking/sine_errors.png", "tracking/sine_p.png",
                                        "tracking/sine_animation.html"})
    assert "Sinusoid: roll 20 deg" in html


def test_safety_section(tmp_path):
    from rcm_kin.report.sections.safety import safety_section

    s = safety_section(tmp_path, scenarios=("ellipsoid",), filters=("blend", "none"), chains=("psm",),
                       programs=("1",))
    assert [row[:2] for row in s.scenarios.rows] == [("ellipsoid", "blend"), ("ellipsoid", "none")]
    assert s.psm_no_go_mm is None and len(s.rcm.rows) == 1
    assert s.certificates is None or s.certificates.rows[0][0] == "1"
    html = assert_renders(s, tmp_path, {"safety_barriers.png"})
    assert "Remote centre of motion" in html


@pytest.fixture
def small_data(tmp_path, shared_data):
    """Two logs of each identification folder and the MTM recording, linked from the shared data."""
    folder = tmp_path / "data"
    for sub in ("roll-step", "pitch-prbs"):
        (folder / "psm-sysid" / sub).mkdir(parents=True)
        for log in sorted((shared_data / "psm-sysid" / sub).glob("*pitch_0*.csv"))[:2]:
            (folder / "psm-sysid" / sub / log.name).symlink_to(log)
    return folder


def test_measured_section(small_data, tmp_path):
    from rcm_kin.report.sections.measured import measured_section

    out = tmp_path / "report"
    out.mkdir()
    s = measured_section(out, small_data)
    assert s.data_name == "data" and s.holding_points > 0
    assert [m.joint for m in s.pose_models] == ["roll", "pitch"]
    html = assert_renders(s, out, {"identification/roll_pose_models.csv", "identification/pitch_pose_models.csv"})
    assert "Calibration on the holding efforts" in html and str(small_data) not in html


def test_drive_train_section(small_data, tmp_path):
    """The shipped roll drive train against the (two) roll steps of the folder: a row and a figure
    per log, all linked relatively."""
    from rcm_kin.report.sections.drive_train import drive_train_section

    out = tmp_path / "report"
    out.mkdir()
    s = drive_train_section(out, small_data, cv=False)
    names = [name for name, _ in s.figures]
    assert len(names) == 2 and len(s.checks.rows) == 2 and all(n.startswith("roll_step_response") for n in names)
    html = assert_renders(s, out, {path for _, path in s.figures})
    assert "[drive_train.roll]" in html and str(small_data) not in html


@pytest.mark.slow
def test_report_end_to_end(tmp_path, capsys):
    """The whole report through the CLI: every section, every link relative and written."""
    assert main(["report", "--out", str(tmp_path), "--map-points", "3"]) == 0
    index, links = linked_files(tmp_path)
    assert {"torque_map.png", "trend_curves.png", "torque_map.csv", "kinematic_checks.json", "stability_maps.png",
            "gain_schedule/gain_schedule.h", "linear_models.json", "psm.png", "psm_view.html", "mtm_view.html",
            "tracking/sine_errors.png", "tracking/target_animation.html", "davinci_view.html",
            "safety_barriers.png", "mtm/torque_map.png", "mtm/linear_models.json", "tuning.png", "tuning_gains.png",
            "tuned_gains/gains.json"} <= set(links)
    for link in links:
        assert not link.startswith("/") and (tmp_path / link).stat().st_size > 0, link
    for section in ("Kinematic self-checks", "Counterweight design", "Gain schedule", "Linear models per grid pose",
                    "Tracking experiments", "Gains tuned by simulation", "Safety", "SOS barrier certificates",
                    "The MTM"):
        assert section in index
    order = [index.index(f"<h2>{h}") for h in ("Tracking experiments", "Gains tuned by simulation", "Robustness")]
    assert order == sorted(order)
    assert str(tmp_path) not in index
    assert "%|" not in capsys.readouterr().err                # progress bars only on a terminal


@pytest.mark.parametrize("argv, message", [
    (["--map-points", "1"], "at least 2"),
    (["--data", "/nonexistent"], "no data folder"),
])
def test_report_user_errors(tmp_path, capsys, argv, message):
    assert main(["report", "--out", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err


def test_mtm_recording_of_a_data_folder(shared_data, tmp_path):
    from rcm_kin.report import _mtm_recording

    assert _mtm_recording(shared_data).name == "mtm_target_trajectory.csv"
    assert _mtm_recording(tmp_path) is None and _mtm_recording(None) is None

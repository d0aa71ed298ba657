"""The main job: `rcm-kin report` writes index.html and every file it links."""

from __future__ import annotations

import re

import pytest

from rcm_kin.cli import main


def linked_files(folder):
    index = (folder / "index.html").read_text()
    return index, re.findall(r'(?:href|src)="([^"#]+)"', index)


def test_report_links_exist(tmp_path, capsys):
    assert main(["report", "--out", str(tmp_path), "--map-points", "5"]) == 0
    index, links = linked_files(tmp_path)
    assert {"torque_map.png", "trend_curves.png", "torque_map.csv", "kinematic_checks.json", "stability_maps.png",
            "gain_schedule/gain_schedule.h", "linear_models.json", "psm.png", "psm_view.html", "mtm_view.html",
            "tracking/sine_errors.png", "tracking/target_animation.html", "davinci_view.html",
            "safety_barriers.png"} <= set(links)
    for link in links:
        assert (tmp_path / link).stat().st_size > 0, link
    for section in ("Kinematic self-checks", "Counterweight design", "Gain schedule", "Linear models per grid pose",
                    "Tracking experiments", "Safety", "SOS barrier certificates"):
        assert section in index
    assert "report" in capsys.readouterr().err                # progress on stderr


def test_report_with_measured_data(tmp_path, shared_data, capsys):
    assert main(["report", "--out", str(tmp_path), "--map-points", "3", "--data", str(shared_data)]) == 0
    index, links = linked_files(tmp_path)
    assert {"identification/roll_pose_models.csv", "identification/roll_greybox.png"} <= set(links)
    for link in links:
        assert (tmp_path / link).stat().st_size > 0, link
    assert "Calibration on the holding efforts" in index and "MTM recording" in index


@pytest.mark.parametrize("argv, message", [
    (["--map-points", "1"], "at least 2"),
    (["--data", "/nonexistent"], "no data folder"),
])
def test_report_user_errors(tmp_path, capsys, argv, message):
    assert main(["report", "--out", str(tmp_path), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err

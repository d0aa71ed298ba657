"""The main job: `rcm-kin report` writes index.html and every file it links."""

from __future__ import annotations

import re

from rcm_kin.cli import main


def test_report_links_exist(tmp_path, capsys):
    assert main(["report", "--out", str(tmp_path)]) == 0
    index = (tmp_path / "index.html").read_text()
    links = re.findall(r'(?:href|src)="([^"]+)"', index)
    assert {"torque_map.png", "trend_curves.png", "torque_map.csv", "kinematic_checks.json", "stability_maps.png",
            "gain_schedule/gain_schedule.h"} <= set(links)
    for link in links:
        assert (tmp_path / link).stat().st_size > 0, link
    assert "Kinematic self-checks" in index and "Counterweight design" in index and "Gain schedule" in index

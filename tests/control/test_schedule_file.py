"""A gains.json read back: the tables and law options of the file, and the shipped tuned design."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.codegen.firmware_export import write_gain_schedule
from rcm_kin.control.schedule_file import SHIPPED_TUNED, read_schedule_file
from rcm_kin.simulation.experiments import psm_schedule, run_experiment
from rcm_kin.simulation.loop import tracking_metrics
from rcm_kin.thesis import K_PITCH


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("gains")
    write_gain_schedule(psm_schedule(), folder, gravity_feedforward=True, friction_feedforward=True)
    return folder / "gains.json"


def test_a_written_schedule_reads_back_table_for_table(written):
    s, loaded = psm_schedule(), read_schedule_file(written)
    for name in ("roll_deg", "pitch_deg", "k_roll", "k_pitch", "u_hold", "ff_pitch", "A", "B", "A_cl"):
        np.testing.assert_array_equal(getattr(loaded.schedule, name), getattr(s, name), err_msg=name)
    assert loaded.schedule.friction == s.friction and loaded.schedule.insertion == s.insertion
    assert loaded.flags == {"scheduled": True, "gravity": True, "track_velocity": True, "friction": True}


def test_the_file_runs_as_the_controller_it_was_written_from(written):
    """``tuned`` with the LQR/LQI file and both feedforwards is ``scheduled-friction``, tick for tick."""
    from_file = run_experiment("sine", "tuned", gains=written)
    designed = run_experiment("sine", "scheduled-friction")
    np.testing.assert_array_equal(from_file.command, designed.command)
    np.testing.assert_array_equal(from_file.measured, designed.measured)


def test_a_file_without_feedforwards_runs_without_them(tmp_path):
    write_gain_schedule(psm_schedule(), tmp_path)
    loaded = read_schedule_file(tmp_path / "gains.json")
    assert loaded.flags == {"scheduled": True, "gravity": False, "track_velocity": True, "friction": False}
    np.testing.assert_array_equal(run_experiment("step", "tuned", gains=tmp_path / "gains.json").command,
                                  run_experiment("step", "scheduled").command)


@pytest.mark.parametrize("edit, word", [
    (lambda d: d.pop("k_roll"), "k_roll"),
    (lambda d: d.__setitem__("k_pitch", [[1.0]]), "k_pitch"),
    (lambda d: d["k_roll"][0][0].__setitem__(0, float("nan")), "k_roll"),
    (lambda d: d.__setitem__("points", d["points"][:3]), "points"),
    (lambda d: d.__setitem__("controller", {"gravity": True}) or d.pop("u_hold"), "controller"),
    (lambda d: d.__setitem__("controller", {"scheduled": "yes"}), "controller"),
    (lambda d: d.__setitem__("roll_deg", [0.0, -1.0, 2.0]), "roll_deg"),
    (lambda d: d.__setitem__("friction_feedforward", {"pwm": [1.0]}), "friction_feedforward"),
    (lambda d: d.__setitem__("insertion_m", "80 mm"), "insertion_m"),
    (lambda d: d.__setitem__("insertion_m", True), "insertion_m"),
    (lambda d: d.pop("insertion_m"), "insertion_m"),
    (lambda d: d.__setitem__("roll_deg", 3), "roll_deg"),
    (lambda d: d.__setitem__("points", {}), "points"),
    (lambda d: d["k_pitch"][1][1].__setitem__(2, 0.0), "Ki"),
])
def test_a_file_that_does_not_fit_is_one_error_naming_the_key(written, tmp_path, edit, word):
    data = json.loads(written.read_text())
    edit(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(RcmKinError, match=word) as info:
        read_schedule_file(path)
    assert info.value.parameter == "gains" and str(path) in str(info.value)


@pytest.mark.parametrize("text", ["", "[1, 2]", "{not json"])
def test_what_is_not_a_gains_file_is_refused(tmp_path, text):
    path = tmp_path / "gains.json"
    path.write_text(text)
    with pytest.raises(RcmKinError, match="gains.json"):
        read_schedule_file(path)
    with pytest.raises(RcmKinError, match="cannot read"):
        read_schedule_file(tmp_path / "missing.json")


def test_the_cli_reads_gains_only_for_the_tuned_controller(written, capsys):
    assert main(["simulate", "psm", "--experiment", "step", "--controller", "p", "--gains", str(written)]) == 2
    assert "'tuned' controller" in capsys.readouterr().err
    assert main(["simulate", "psm", "--experiment", "step", "--controller", "tuned", "--gains",
                 str(written.parent / "missing.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "Traceback" not in err


def test_the_shipped_tuned_design_beats_the_thesis_law_on_the_nominal_robot():
    """The shipped file (rcm-kin schedule psm --tune on the shipped drive file) against the flashed
    thesis tables on the shipped model, both experiments and axes, max and mean error from 1 s."""
    loaded = read_schedule_file(SHIPPED_TUNED)
    assert not np.allclose(loaded.schedule.k_pitch[..., 0], K_PITCH[..., 0])
    for experiment in ("sine", "target"):
        tuned = tracking_metrics(run_experiment(experiment, "tuned"), 1.0)
        thesis = tracking_metrics(run_experiment(experiment, "thesis"), 1.0)
        for axis in ("roll", "pitch"):
            assert tuned[axis].max_error_deg <= thesis[axis].max_error_deg, (experiment, axis)
            assert tuned[axis].mean_error_deg <= thesis[axis].mean_error_deg, (experiment, axis)
            assert tuned[axis].saturation_s <= thesis[axis].saturation_s, (experiment, axis)

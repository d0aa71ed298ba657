"""Every bad input of the validation issue is a one-line ``error:`` with status 2, or a correct result:
parameter files checked where they are read, bounded work, one joint-limit policy, bad log rows,
output paths, safety numbers that are never NaN-safe, the Python API's exceptions."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, load_drive_parameters
from rcm_kin.errors import JointLimitError, LogDataError, ParameterFileError, WorkLimitError

SHIPPED = DEFAULT_PARAMETERS.read_text()


def run(capsys, *argv):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:          # argparse's usage errors and --version exit, as before
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(capsys, argv, message):
    code, out, err = run(capsys, *argv)
    assert code == 2, (argv, out, err)
    assert err.startswith("error: ") and err.count("\n") == 1 and "Traceback" not in err, err
    assert message in err, err
    return err


def drive_file(tmp_path, old: str, new: str) -> Path:
    """The shipped drive parameter file with its first ``old`` replaced by ``new``."""
    assert old in SHIPPED
    path = tmp_path / "drive.toml"
    path.write_text(SHIPPED.replace(old, new, 1))
    return path


def step_log(path: Path, rows: int = 1200, bad: str | None = None) -> Path:
    """A synthetic open-loop roll step log; rows 600-699 hold ``bad`` as the position when given."""
    t = np.arange(rows) * 0.0025
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["__time", "/t/roll/position", "/t/roll/velocity", "/t/pitch/position", "/t/pitch/velocity"])
        for i, ti in enumerate(t):
            angle = 8.0 * (1 - np.exp(-(ti - 0.5) / 0.2)) if ti >= 0.5 else 0.0
            w.writerow([ti, bad if bad is not None and 600 <= i < 700 else angle, -40.0 if ti >= 0.5 else 0.0, 0, 0])
    return path


# --- parameter files: type, unit, range, with the file and the key named -------------------------------
@pytest.mark.parametrize("old, new, key", [
    ("volts_per_pwm = 0.117", "volts_per_pwm = nan  #", "volts_per_pwm"),
    ("gear_ratio = 20.0", "gear_ratio = 0.0", "gear_ratio"),
    ("resistance = 0.582", "resistance = -1e300", "resistance"),
    ("torque_constant = 0.0302", "torque_constant = inf", "torque_constant"),
    ("pwm_sign = -1.0", "pwm_sign = 0.5", "pwm_sign"),
    ("coulomb = 1.0734", 'coulomb = "big"', "coulomb"),
    ("viscous = 0.0", "viscous = true", "viscous"),
    ("presliding_slope = 5.9", "presliding_slope = 59  #", "presliding_slope"),
    ("roll_link = [0.0, -0.2", "roll_link = [nan, -0.2", "roll_link"),
])
def test_drive_file_values_are_checked_where_read(tmp_path, old, new, key):
    path = drive_file(tmp_path, old, new)
    with pytest.raises(ParameterFileError, match=key) as raised:
        load_drive_parameters(path)
    assert str(path) in str(raised.value)


def test_shipped_drive_file_passes_its_schema():
    params = load_drive_parameters()
    assert params["roll"].gear_ratio == 20.0 and params.drive_train["roll"].presliding_slope > 0


@pytest.mark.parametrize("command", [
    ["gravity", "psm", "0.1"], ["torque-map", "psm", "--out", "maps"], ["dynamics", "psm", "--q", "0", "0", "0.08"],
    ["linearize", "psm", "--roll", "0", "--pitch", "0"], ["schedule", "psm", "--out", "gains"],
    ["simulate", "psm", "--experiment", "step", "--controller", "p"], ["greybox", "log.csv", "--joint", "roll"],
    ["excite", "psm", "--duration", "10", "--out", "x.csv"],
])
def test_every_command_refuses_a_bad_drive_file(capsys, tmp_path, monkeypatch, command):
    monkeypatch.chdir(tmp_path)
    step_log(tmp_path / "log.csv")
    path = drive_file(tmp_path, "gear_ratio = 20.0", "gear_ratio = 0.0")
    assert_one_line_error(capsys, [*command, "--params", path], "gear_ratio = 0 is outside [0.1, 10000]")
    assert not (tmp_path / "maps").exists() and not (tmp_path / "x.csv").exists()


# --- sizes: 1-point grids work, huge ones are refused with what they would need --------------------------
def test_one_point_torque_map_is_the_gravity_command_at_that_pose(capsys, tmp_path):
    code, out, err = run(capsys, "torque-map", "psm", "--roll=10:10:1", "--pitch=-5:-5:1", "--insertion", "0.08",
                         "--out", tmp_path, "--json")
    assert code == 0, err
    assert json.loads(out)["poses"] == 1
    with (tmp_path / "torque_map.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 1
    code, out, err = run(capsys, "gravity", "psm", "10", "-5", "0.08", "--deg", "--json")
    held = json.loads(out)
    np.testing.assert_allclose([float(rows[0][f"pwm_{j}"]) for j in ("roll", "pitch", "insertion")], held["pwm"],
                               rtol=0, atol=1e-6)      # the CSV rounds to 9 decimals


@pytest.mark.parametrize("argv, message", [
    (["torque-map", "psm", "--roll=-30:30:100000", "--out", "m"], "6,100,000 poses is beyond the 1,002,001"),
    (["torque-map", "psm", "--pitch=0:1:100000000", "--out", "m"], "100,000,000 poses"),
    (["torque-map", "psm", "--roll=5:6:1", "--out", "m"], "LO = HI and N = 1"),
    (["simulate", "psm", "--experiment", "sine", "--controller", "p", "--duration", "1e6"], "(0, 10000] s"),
    (["simulate", "psm", "--experiment", "sine", "--controller", "p", "--duration", "5000"],
     "2,000,001 controller periods; the limit is 200,000"),
    (["simulate", "psm", "--experiment", "sine", "--controller", "p", "--rate", "1e9"], "[1, 100000] Hz"),
    (["schedule", "psm", "--check-points", "100000", "--out", "g"], "at most 201"),
    (["report", "--out", "r", "--map-points", "100000"], "at most 1,001"),
    (["greybox", "log.csv", "--joint", "roll", "--samples", "10000000000"], "at most 100,000"),
])
def test_huge_work_is_refused_before_it_starts(capsys, tmp_path, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    assert_one_line_error(capsys, argv, message)
    assert not any(tmp_path.iterdir())


# --- one joint-limit policy: outside the limits is refused, by every command ------------------------------
@pytest.mark.parametrize("argv", [
    ["fk", "psm", "90", "0", "0.08", "--deg"], ["fk", "psm", "0", "0", "0.5"], ["fk", "psm", "1e300"],
    ["gravity", "psm", "90", "0", "0.08", "--deg"], ["gravity", "psm", "0", "0", "0.5"],
    ["view", "psm", "--q", "0", "0", "0.5", "--png", "v.png"], ["view", "mtm", "--q", "1e300", "--png", "v.png"],
    ["dynamics", "psm", "--q", "1.6", "0", "0.08"], ["linearize", "psm", "--roll", "90", "--pitch", "0"],
    ["torque-map", "psm", "--roll=-60:60:5", "--out", "m"],
])
def test_poses_outside_the_joint_limits_are_refused(capsys, tmp_path, monkeypatch, argv):
    monkeypatch.chdir(tmp_path)
    err = assert_one_line_error(capsys, argv, "")
    assert "limits" in err or "joint range" in err
    assert not any(tmp_path.iterdir())


def test_simulation_leaving_the_joint_range_is_an_error(capsys):
    """At 5 Hz the P loop throws the pitch far past its +-30 deg: not a result."""
    assert_one_line_error(capsys, ["simulate", "psm", "--experiment", "sine", "--controller", "p", "--rate", "5"],
                          "outside its joint range")


def test_non_finite_results_are_errors_not_output(capsys):
    assert_one_line_error(capsys, ["dynamics", "psm", "--q", "0", "0", "0.08", "--v", "1e300", "0", "0", "--json"],
                          "not finite (qdd[0])")


# --- logs with bad rows -------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", ["inf", "nan", ""])
@pytest.mark.parametrize("command", [["sysid", "{log}", "--joint", "roll"], ["greybox", "{log}", "--joint", "roll"],
                                     ["predict", "psm", "{log}", "--joint", "roll"]])
def test_bad_log_rows_are_an_error_not_a_collapsed_fit(capsys, tmp_path, bad, command):
    log = step_log(tmp_path / "bad.csv", bad=bad)
    err = assert_one_line_error(capsys, [w.format(log=log) for w in command], "100 rows with a missing or non-finite")
    assert "data row 601" in err and "/t/roll/position" in err


@pytest.mark.parametrize("fault, message", [("swap", "time goes back 0.0025 s at data row 502 (line 503)"),
                                            ("jump", "a gap of 1000 s in the time stamps at data row 701 (line 702)")])
@pytest.mark.parametrize("command", [["sysid", "{log}", "--joint", "roll"], ["greybox", "{log}", "--joint", "roll"],
                                     ["predict", "psm", "{log}", "--joint", "roll"]])
def test_log_time_stamps_out_of_order_or_with_a_gap_are_one_line_errors(capsys, tmp_path, fault, message, command):
    """Out-of-order rows were dropped silently (a changed fit); a 1000 s jump made `sysid` build a
    16 GB grid. Both are refused when the log is read, naming the row."""
    log = step_log(tmp_path / f"{fault}.csv")
    lines = log.read_text().splitlines(keepends=True)
    if fault == "swap":                    # data rows 501 and 502 (lines 502 and 503)
        lines[501], lines[502] = lines[502], lines[501]
    else:                                  # from data row 701 (line 702) on, 1000 s later
        lines[701:] = [f"{float(x.split(',', 1)[0]) + 1000.0!r},{x.split(',', 1)[1]}" for x in lines[701:]]
    log.write_text("".join(lines))
    err = assert_one_line_error(capsys, [w.format(log=log) for w in command], message)
    assert str(log) in err


def test_bad_log_rows_in_the_library_are_a_log_data_error(tmp_path):
    from rcm_kin.identification.telemetry import load_telemetry

    with pytest.raises(LogDataError, match="100 rows"):
        load_telemetry(step_log(tmp_path / "bad.csv", bad="inf"))
    assert load_telemetry(step_log(tmp_path / "good.csv")).time.size == 1200


def test_work_limits_in_the_library(psm, params):
    from rcm_kin.statics.maps import MAX_POSES, gravity_map

    with pytest.raises(WorkLimitError, match=r"beyond the 1,002,001 \(1001 x 1001\)"):
        gravity_map(psm, params, np.zeros(MAX_POSES + 1), [0.0], [0.08])


def test_binary_trajectory_is_an_error(capsys, tmp_path):
    binary = tmp_path / "t.csv"
    binary.write_bytes(bytes(range(256)) * 4)
    assert_one_line_error(capsys, ["simulate", "psm", "--experiment", "target", "--controller", "p",
                                   "--trajectory", binary], "not a CSV text file")


# --- paths ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, message", [
    (["torque-map", "psm", "--out", ""], "empty path"),
    (["view", "psm", "--html", ""], "empty output path"),
    (["view", "psm", "--png", "x.txt"], "must end in .png"),
    (["view", "psm", "--png", "notes.png"], "exists: choose another output file or add --force"),
    (["calibrate", "data", "--out", "notes.txt"], "must end in .toml"),
    (["calibrate", "data", "--out", "params.toml"], "exists"),
    (["greybox", "log.csv", "--joint", "roll", "--out", "params.toml"], "exists"),
    (["report", "--out", "r", "--data", "."], "no roll-step/ or pitch-prbs/ logs"),
])
def test_outputs_never_overwrite_what_we_do_not_own(capsys, tmp_path, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    step_log(tmp_path / "log.csv")
    for name in ("notes.txt", "notes.png", "params.toml"):
        (tmp_path / name).write_text("someone's notes")
    before = sorted(tmp_path.iterdir())
    assert_one_line_error(capsys, argv, message)
    assert sorted(tmp_path.iterdir()) == before
    assert all(p.read_text() == "someone's notes" for p in before if p.name != "log.csv")


def test_view_writes_and_summarises_in_json(capsys, tmp_path):
    code, out, err = run(capsys, "view", "psm", "--q", "10", "-5", "0.08", "--deg", "--png", tmp_path / "v.png",
                         "--html", tmp_path / "v.html", "--json")
    assert code == 0, err
    summary = json.loads(out)
    assert summary["written"] == [str(tmp_path / "v.png"), str(tmp_path / "v.html")]
    assert all(Path(p).stat().st_size > 0 for p in summary["written"])
    np.testing.assert_allclose(summary["q"][:3], [np.radians(10), np.radians(-5), 0.08], rtol=0, atol=1e-15)


# --- safety numbers ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, message", [
    (["safety", "simulate", "ellipsoid", "--kappa", "nan"], "needs a finite number in (0, 100] m, got 'nan'"),
    (["safety", "simulate", "ellipsoid", "--kappa", "1e300"], "needs a number in (0, 100] m, got '1e300'"),
    (["safety", "simulate", "ellipsoid", "--kappa", "0"], "(0, 100] m, got '0'"),
    (["safety", "certify", "2", "--r-max", "inf"], "needs a finite number in (0, 1], got 'inf'"),
])
def test_safety_inputs(capsys, argv, message):
    assert_one_line_error(capsys, argv, message)


def test_a_nan_barrier_never_reads_as_safe():
    from rcm_kin.safety.scenarios import SafetyRun

    run_ = SafetyRun(scenario="x", filter="blend", time=np.arange(4) * 0.1, state=np.zeros((4, 1)),
                     command=np.zeros((4, 1)), barrier=np.array([-1.0, np.nan, -0.5, -0.2]), sigma=np.zeros(4))
    assert run_.summary()["violations"] == 1
    with pytest.raises(RcmKinError, match="kappa"):
        from rcm_kin.safety.scenarios import run_scenario
        run_scenario("ellipsoid", kappa=float("nan"))


# --- contract gaps and the Python API ---------------------------------------------------------------------
def test_version(capsys):
    from importlib.metadata import version

    code, out, _ = run(capsys, "--version")
    assert code == 0 and out == f"rcm-kin {version('rcm-kin')}\n"


def test_readme_tool_pose_example_reaches_its_pose(capsys):
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    line = next(l for l in readme.splitlines() if l.startswith("rcm-kin ik psm") and "--rpy" in l)
    argv = line.split("#")[0].split()[1:]
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0, err
    result = json.loads(out)
    assert result["position_error"] < 1e-9 and result["orientation_error"] < 1e-9


def test_python_api_raises_rcm_kin_errors(psm):
    from rcm_kin import load_robot
    from rcm_kin.kinematics.fk import forward_kinematics

    with pytest.raises(RcmKinError, match="named by a string"):
        load_robot(None)
    with pytest.raises(RcmKinError, match="joint values must be numbers"):
        forward_kinematics(psm, "abc")
    with pytest.raises(JointLimitError, match="roll 90 deg not in"):
        psm.check_limits(psm.check_q([np.radians(90)], allow_short=True))


def _failing_robot_views(out):
    """A section that fails (module level: the report's process pool pickles it by name)."""
    raise RcmKinError("robot views failed <here>")


def _skipped_section(*arguments):
    """A section that does nothing (the long ones, so that the failure comes quickly)."""


def test_a_failed_report_still_has_an_index_saying_so(capsys, tmp_path, monkeypatch):
    import rcm_kin.report as report
    import rcm_kin.report.sections.robots as robots
    import rcm_kin.report.sections.robustness as robustness
    import rcm_kin.report.sections.safety as safety

    monkeypatch.setattr(robots, "robots_section", _failing_robot_views)
    for module, name in ((safety, "scenario_runs"), (safety, "safety_checks"), (robustness, "robustness_section"),
                         (report, "_schedule_sections"), (report, "_tracking_part")):
        monkeypatch.setattr(module, name, _skipped_section)
    assert_one_line_error(capsys, ["report", "--out", tmp_path / "r", "--json"], "robot views failed <here>")
    index = (tmp_path / "r" / "index.html").read_text()
    assert "not completed" in index and "robot views failed &lt;here&gt;" in index


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="reads the process tree from Linux /proc")
def test_sigterm_on_view_stops_its_meshcat_server(tmp_path):
    """A served view stopped by SIGTERM (as a supervisor or `kill` would) takes its server with it."""
    import os
    import signal
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "rcm_kin.cli", "view", "psm"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    children = []
    try:
        for line in proc.stdout:
            if line.startswith("serving"):
                break
        children = Path(f"/proc/{proc.pid}/task/{proc.pid}/children").read_text().split()
        assert children, "the meshcat server runs as a child process"
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=60) == 0
        assert not [c for c in children if Path(f"/proc/{c}").exists()]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for child in children:                  # no orphan left behind even when the test fails
            if Path(f"/proc/{child}").exists():
                os.kill(int(child), signal.SIGKILL)

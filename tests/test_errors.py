"""The error rules: library exceptions carry their fields (set at the real raise sites) and name
parameters, not flags (the CLI names the flags); warnings go through ``warnings``, never printed;
no ``assert`` for checks and no function-local rcm_kin imports in the library."""

from __future__ import annotations

import ast
import csv
import importlib
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rcm_kin
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS
from rcm_kin.errors import (
    CompilerFallbackWarning,
    JointLimitError,
    LogDataError,
    LogDataWarning,
    NonFiniteResultError,
    ParameterFileError,
    RcmKinError,
    RcmKinWarning,
    WorkLimitError,
)

comp = importlib.import_module("rcm_kin.symbolic.compiled")   # the module (the package's ``compiled`` is the function)
SOURCE = Path(rcm_kin.__file__).parent
SHIPPED = DEFAULT_PARAMETERS.read_text()


def drive_file(tmp_path: Path, old: str, new: str) -> Path:
    assert old in SHIPPED
    path = tmp_path / "drive.toml"
    path.write_text(SHIPPED.replace(old, new, 1))
    return path


def telemetry_csv(path: Path, rows: int = 50, bad_row: int | None = None, cut: bool = False) -> Path:
    """A roll log of ``rows`` data rows; data row ``bad_row`` (from 1) holds inf as the position;
    ``cut``: a last row cut off mid-way."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["__time", "/t/roll/position", "/t/roll/velocity"])
        for i in range(rows):
            w.writerow([i * 0.0025, "inf" if bad_row == i + 1 else 0.1 * i, -40.0])
        if cut:
            fh.write("1.0,2.0\n")
    return path


# --- fields ----------------------------------------------------------------------------------------------
def test_the_fields_default_to_none_and_survive_pickling():
    plain = RcmKinError("plain")
    assert plain.parameter is None and plain.parameters == () and str(plain) == "plain"
    for cls, fields in [(ParameterFileError, ("path", "table", "key")),
                        (JointLimitError, ("joints", "values", "lower", "upper")),
                        (WorkLimitError, ("requested", "limit")), (LogDataError, ("path", "row", "column")),
                        (NonFiniteResultError, ("where",))]:
        exc = cls("message")
        assert str(exc) == "message" and exc.parameter is None and all(getattr(exc, f) is None for f in fields)
    exc = pickle.loads(pickle.dumps(WorkLimitError("too much", requested=5, limit=3, parameter=("a", "b"))))
    assert (str(exc), exc.requested, exc.limit, exc.parameters) == ("too much", 5, 3, ("a", "b"))


@pytest.mark.parametrize("old, new, table, key", [
    ("gear_ratio = 20.0", "gear_ratio = 0.0", "roll", "gear_ratio"),
    ("gear_ratio = 20.0", "gear_ratio = 'x'", "roll", "gear_ratio"),
    ("\n[gravity_offsets]\n", "\n[gravity_offsets]\nextra = [1.0]\n", "gravity_offsets", "extra"),
])
def test_parameter_file_error_names_file_table_and_key(tmp_path, old, new, table, key):
    from rcm_kin.dynamics.drive import load_drive_parameters

    path = drive_file(tmp_path, old, new)
    with pytest.raises(ParameterFileError) as caught:
        load_drive_parameters(path)
    assert Path(caught.value.path) == path and caught.value.table == table and caught.value.key == key
    assert str(caught.value).startswith(f"{path}: ")


def test_a_legacy_pwm_limit_names_the_parameter_not_the_flag(tmp_path):
    from rcm_kin.dynamics.drive import load_drive_parameters

    path = drive_file(tmp_path, "gear_ratio = 20.0", "gear_ratio = 20.0\npwm_limit = 120.0")
    with pytest.raises(ParameterFileError, match="differs from the firmware") as caught:
        load_drive_parameters(path)
    exc = caught.value
    assert (exc.table, exc.key, exc.parameter) == ("roll", "pwm_limit", "pwm_limit")
    assert "`pwm_limit`" in str(exc) and "--" not in str(exc)


def test_joint_limit_error_carries_joints_values_and_limits(psm):
    q = np.array(psm.lower) - 0.5           # every joint below its lower limit
    q[1] = 0.5 * (psm.lower[1] + psm.upper[1])
    with pytest.raises(JointLimitError, match="outside the joint limits") as caught:
        psm.check_limits(q)
    exc = caught.value
    outside = [i for i in range(psm.nq) if i != 1]
    assert exc.joints == tuple(psm.actuated[i] for i in outside)
    np.testing.assert_array_equal(exc.values, q[outside])
    np.testing.assert_array_equal(exc.lower, np.asarray(psm.lower)[outside])
    np.testing.assert_array_equal(exc.upper, np.asarray(psm.upper)[outside])
    assert all(name in str(exc) for name in exc.joints)


def test_work_limit_errors_carry_what_was_asked_and_the_limit():
    from rcm_kin.robustness.work import MAX_POSES as SWEEP_POSES
    from rcm_kin.robustness.work import check_counterweight_sweep
    from rcm_kin.statics.maps import MAX_POSES, check_map_size

    check_map_size(MAX_POSES)
    with pytest.raises(WorkLimitError, match="beyond the 1,002,001") as caught:
        check_map_size(MAX_POSES + 1)
    assert (caught.value.requested, caught.value.limit) == (MAX_POSES + 1, MAX_POSES)
    with pytest.raises(WorkLimitError, match="fewer masses or `points`") as caught:
        check_counterweight_sweep(10, 10, 1000)
    assert (caught.value.requested, caught.value.limit, caught.value.parameter) == (10**8, SWEEP_POSES, "points")


def test_log_data_error_names_the_path_row_and_column(tmp_path):
    from rcm_kin.identification.telemetry import load_telemetry

    path = telemetry_csv(tmp_path / "bad.csv", bad_row=7)
    with pytest.raises(LogDataError, match="the first in data row 7, column '/t/roll/position'") as caught:
        load_telemetry(path)
    assert (caught.value.path, caught.value.row, caught.value.column) == (path, 7, "/t/roll/position")


def test_simulation_errors_carry_their_fields():
    """The closed loop's refusals: the joint that left its range (with its position and limits),
    a run longer than the limit (periods asked for and the limit), a diverged state (the time)."""
    from rcm_kin.simulation.experiments import check_in_limits
    from rcm_kin.simulation.firmware import FirmwareSettings
    from rcm_kin.simulation.loop import SimulationResult, diverged
    from rcm_kin.simulation.references import MAX_SAMPLES, sine_reference

    n = 5
    position = np.zeros((n, 3))
    position[:, 2] = 0.08
    position[3, 1] = 170.0                                        # deg: the pitch far outside its range
    zeros = np.zeros((n, 3))
    result = SimulationResult("p", np.arange(n) * 0.0025, zeros, zeros, position, zeros, zeros, FirmwareSettings())
    with pytest.raises(JointLimitError, match="the simulated pitch reached 170 deg at t = 0.007 s") as caught:
        check_in_limits(result)
    exc = caught.value
    assert exc.joints == ("pitch",) and np.allclose(exc.values, [np.radians(170.0)])
    assert exc.lower.shape == exc.upper.shape == (1,) and exc.upper[0] < exc.values[0]
    assert f"{np.degrees(exc.upper[0]):.4g}]" in str(exc)
    with pytest.raises(WorkLimitError, match="controller periods; the limit is 200,000") as caught:
        sine_reference(1000.0, 0.0025)
    assert (caught.value.requested, caught.value.limit) == (400_001, MAX_SAMPLES)
    assert caught.value.parameter == "duration"
    exc = diverged(400, 0.0025, "pid")
    assert str(exc) == "the simulation diverged at t = 1.000 s (pid)" and exc.where == "t = 1.000 s"


def test_non_finite_result_error_says_where():
    from rcm_kin.cli.common import check_finite

    check_finite({"a": [1.0, 2.0]})
    with pytest.raises(NonFiniteResultError, match="not finite") as caught:
        check_finite({"a": [1.0, float("nan")]})
    assert caught.value.where and caught.value.where in str(caught.value)


# --- parameters, not flags; the CLI names the flags --------------------------------------------------------
def test_library_messages_name_parameters(mtm):
    from rcm_kin.control.gain_schedule import parse_grid
    from rcm_kin.identification.excitation import check_request
    from rcm_kin.kinematics.ik import inverse_kinematics

    cases = [(lambda: inverse_kinematics(mtm, [0.2, 0.0, -0.2], [0, float("nan"), 0]), "rpy"),
             (lambda: check_request(10.0, ["roll"], 1), "harmonics"),
             (lambda: parse_grid("a:b"), "grid"), (lambda: parse_grid("1,2"), "grid")]
    for call, parameter in cases:
        with pytest.raises(RcmKinError) as caught:
            call()
        assert caught.value.parameter == parameter and f"`{parameter}`" in str(caught.value)
        assert " --" not in str(caught.value) and not str(caught.value).startswith("--")


def test_no_library_message_names_a_flag():
    """A raised error's or warning's string constant in the library (the CLI aside) names no
    ``--flag`` except in an ``rcm-kin ...`` command line it quotes."""
    found = []
    for path in SOURCE.rglob("*.py"):
        if "cli" in path.relative_to(SOURCE).parts:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and (getattr(node.func, "id", None) or getattr(node.func, "attr", "")
                                               ).endswith(("Error", "warn")):
                for part in ast.walk(node):
                    if (isinstance(part, ast.Constant) and isinstance(part.value, str) and "--" in part.value
                            and "rcm-kin " not in part.value):
                        found.append(f"{path.name}:{part.lineno}: {part.value}")
    assert not found


@pytest.mark.parametrize("argv, line", [
    (["ik", "mtm", "0.2", "0", "-0.2", "--frame", "wrist_center", "--rpy", "0", "0", "0"],
     "error: --rpy asks for a full pose of wrist_center, which its joints move in 3 independent directions only "
     "(6 needed): give the position alone or another --frame"),
    (["schedule", "psm", "--grid", "a:b", "--out", "gains"], "error: --grid values must be numbers, got 'a:b'"),
])
def test_the_cli_names_the_flags(capsys, tmp_path, monkeypatch, argv, line):
    from rcm_kin.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert capsys.readouterr().err.splitlines() == [line]


def test_flag_substitution():
    from rcm_kin.cli.common import with_flags

    message = "check `delta`, `error_bound`, `r_max`; the topic `topic` stays topic, `other` stays"
    assert with_flags(message, ("delta", "error_bound", "r_max", "topic", "other"), set()) == \
        "check --delta, --error-bound, --r-max; the topic --topic stays topic, `other` stays"
    assert with_flags("`other` x", ("other",), {"--other"}) == "--other x"    # the command's own flag
    assert with_flags("`params` x", (), {"--params"}) == "`params` x"       # only the parameters named


# --- warnings ----------------------------------------------------------------------------------------------
def test_compiler_fallback_is_a_warning_not_output(model, monkeypatch, capsys):
    monkeypatch.setenv("CC", "/nonexistent/cc")
    comp._available.cache_clear()
    comp._warn.cache_clear()
    with pytest.warns(CompilerFallbackWarning, match=r"^no C compiler '/nonexistent/cc' found") as caught:
        assert comp.compiled(model.gravity) is model.gravity
        assert comp.compiled(model.forward) is model.forward
    assert len(caught) == 1 and issubclass(caught[0].category, RcmKinWarning)
    assert caught[0].filename == __file__
    assert capsys.readouterr() == ("", "")


def test_csv_formatter_fallback_is_a_warning_not_output(monkeypatch, capsys):
    from rcm_kin.csv_native import _formatter, native_formatter

    monkeypatch.setenv("CC", "/nonexistent/cc")
    _formatter.cache_clear()
    with pytest.warns(CompilerFallbackWarning, match="CSV tables are formatted by NumPy"):
        assert native_formatter() is None
    assert capsys.readouterr() == ("", "")


def test_left_out_rows_are_a_log_data_warning(tmp_path, capsys):
    from rcm_kin.identification.telemetry import load_telemetry

    with pytest.warns(LogDataWarning, match="1 rows with a wrong number of fields left out"):
        log = load_telemetry(telemetry_csv(tmp_path / "cut.csv", cut=True))
    assert log.time.size == 50 and capsys.readouterr() == ("", "")


def test_the_cli_prints_each_warning_once_after_success(tmp_path):
    """A fresh process with the compiler hidden: one ``warning:`` line per distinct warning (the
    compiled gravity, the CSV formatter), nothing else on stderr."""
    env = {**os.environ, "CC": "/nonexistent/cc", "PYTHONPATH": str(SOURCE.parent)}
    run = subprocess.run([sys.executable, "-m", "rcm_kin.cli", "torque-map", "psm", "--roll=0:10:2",
                          "--pitch=0:5:2", "--out", str(tmp_path / "maps"), "--json"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stderr.splitlines() == [
        "warning: no C compiler '/nonexistent/cc' found (set CC): CasADi functions run interpreted, slower",
        "warning: no C compiler '/nonexistent/cc' found (set CC): CSV tables are formatted by NumPy, slower"]


@pytest.mark.parametrize("edit, table, key", [
    (lambda t: t.replace("\n[roll]\n", "\n[roll]\nbogus = 1.0\n", 1), "roll", "bogus"),
    (lambda t: t.replace("\n[drive_train.roll]\n", "\n[drive_train.elbow]\n", 1), "drive_train.elbow", None),
    (lambda t: t + "\n[drive_train.pitch]\nnot_a_term = 1.0\n", "drive_train.pitch", "not_a_term"),
])
def test_every_schema_violation_is_a_parameter_file_error_with_its_fields(tmp_path, edit, table, key):
    from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, load_drive_parameters

    text = DEFAULT_PARAMETERS.read_text()
    path = tmp_path / "drive.toml"
    edited = edit(text)
    assert edited != text
    path.write_text(edited)
    with pytest.raises(ParameterFileError) as raised:
        load_drive_parameters(path)
    assert (raised.value.path, raised.value.table, raised.value.key) == (path, table, key)


def test_parameter_and_robot_files_are_read_within_a_bound(tmp_path):
    """A file far larger than any parameter file or URDF is refused unread (not parsed into memory)."""
    import rcm_kin as rk
    from rcm_kin.errors import MAX_TEXT_FILE_BYTES, WorkLimitError

    big = tmp_path / "drive.toml"
    with big.open("wb") as fh:
        fh.truncate(MAX_TEXT_FILE_BYTES + 1)          # sparse: one byte over the bound
    with pytest.raises(WorkLimitError, match="larger than 8 MiB") as caught:
        rk.load_drive_parameters(big)
    assert caught.value.limit == MAX_TEXT_FILE_BYTES
    sidecar = tmp_path / "arm.toml"
    sidecar.write_text('urdf = "arm.urdf"\n')
    with (tmp_path / "arm.urdf").open("wb") as fh:
        fh.truncate(MAX_TEXT_FILE_BYTES + 1)
    with pytest.raises(WorkLimitError, match="URDF .* larger than 8 MiB"):
        rk.load_robot(str(sidecar))

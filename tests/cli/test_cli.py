"""The CLI contracts of the models issue: ``info``, ``fk``, ``ik`` with --json, and one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from oracles.dh_reference import psm_frames

from rcm_kin.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def run_json(capsys, *argv):
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0, err
    return json.loads(out)


@pytest.mark.parametrize("robot, n", [("psm", 7), ("mtm", 7), ("davinci", 13), ("davinci_rcm", 13)])
def test_info_contract(capsys, robot, n):
    info = run_json(capsys, "info", robot)
    assert info["robot"] == robot
    assert info["gravity"] == [0.0, 0.0, -9.81]
    assert len(info["actuated"]) == n
    for joint in info["joints"]:
        assert {"name", "type", "lower", "upper", "axis_world"} <= set(joint)
        assert joint["lower"] < joint["upper"]
        assert np.linalg.norm(joint["axis_world"]) == pytest.approx(1.0, abs=1e-12)
    names = [j["name"] for j in info["joints"]]
    assert set(info["actuated"]) <= set(names)


def test_info_psm_axes(capsys):
    """Roll horizontal, insertion along gravity at q = 0 (the robot as built)."""
    joints = {j["name"]: j for j in run_json(capsys, "info", "psm")["joints"]}
    assert joints["roll"]["axis_world"][2] == 0.0
    assert joints["insertion"]["axis_world"] == [0.0, 0.0, -1.0]
    assert joints["pitch"]["upper"] == pytest.approx(np.radians(30))


def test_fk_contract(capsys):
    fk = run_json(capsys, "fk", "psm", "10", "-5", "0.08", "--deg")
    q = np.array([np.radians(10), np.radians(-5), 0.08, 0, 0, 0, 0])
    np.testing.assert_allclose(fk["q"], q, atol=1e-15)
    np.testing.assert_allclose(fk["frames"]["shaft_tip"]["position"], psm_frames(q)["shaft_tip"][:3, 3], atol=1e-12)
    np.testing.assert_allclose(fk["frames"]["tool_tip"]["rotation"], psm_frames(q)["tool_tip"][:3, :3], atol=1e-12)
    assert set(fk["frames"]) == {"rcm", "shaft_tip", "tool_tip"}
    assert fk["closure_residual"] < 1e-12


def test_ik_contract_round_trip(capsys):
    fk = run_json(capsys, "fk", "psm", "0.2", "-0.3", "0.1")
    target = [str(x) for x in fk["frames"]["shaft_tip"]["position"]]
    ik = run_json(capsys, "ik", "psm", *target)
    np.testing.assert_allclose(ik["q"], [0.2, -0.3, 0.1], atol=1e-9)
    assert ik["position_error"] < 1e-12
    mtm = run_json(capsys, "ik", "mtm", "0.26", "0.02", "-0.2")
    assert mtm["position_error"] < 1e-9 and len(mtm["q"]) == 3


@pytest.mark.parametrize("argv, message", [
    (["ik", "psm", "1", "1", "1"], "out of reach"),
    (["ik", "mtm", "2", "0", "0"], "no configuration within the joint limits"),
    (["fk", "psm", "a"], "joint values must be numbers"),
    (["fk", "psm", *["0"] * 8], "takes 7 joint values"),
    (["fk", "kuka"], "unknown robot 'kuka'"),
    (["ik", "psm", "0", "0"], "the following arguments are required"),
    (["ik", "mtm", "0.2", "0", "-0.2", "--frame", "nope"], "mtm has no frame 'nope' (--frame)"),
    (["ik", "psm", "0", "0", "0"], "the remote centre of motion itself"),
    (["fk", "psm", "nan"], "finite"),
])
def test_user_errors_are_one_line(capsys, argv, message):
    try:
        code, out, err = run(capsys, *argv)
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
        out, err = capsys.readouterr()
    assert code == 2
    assert err.startswith("error:") and message in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_console_script_exit_status():
    """The installed entry point, as users call it: status 2 and one stderr line."""
    result = subprocess.run([sys.executable, "-m", "rcm_kin.cli", "ik", "psm", "0", "0", "-1"],
                            capture_output=True, text=True)
    assert result.returncode == 2
    assert result.stderr.startswith("error: ") and result.stderr.count("\n") == 1

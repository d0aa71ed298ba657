"""The order of a drive file's joint tables means nothing: ``params.driven`` is the robot's actuated
order (the bundled PSM's: roll, pitch, insertion on reading; another robot's after ``check_drive``).
Checked against the TOML's own numbers read by ``tomllib`` and against the shipped file's results;
also: the positional order of ``driven_dynamics`` is the one of before ``joints``, and
``driven_gravity_function`` has no name-based default."""

from __future__ import annotations

import inspect
import json
import re
import tomllib

import numpy as np
import pytest
from oracles.cli_calls import run
from oracles.dyn_robots import DRIVE_KEYS, drive_text, write_mypsm

import rcm_kin as rk
from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, DRIVEN, check_drive, drive_effort, load_drive_parameters
from rcm_kin.dynamics.state_space import driven_dynamics, driven_gravity_function
from rcm_kin.errors import ParameterFileError, RcmKinError


def table(text: str, name: str) -> str:
    """The block of the top-level table ``[name]`` of a TOML text (up to the next table)."""
    match = re.search(rf"^\[{name}\]\n.*?(?=^\[)", text, flags=re.S | re.M)
    assert match, name
    return match.group(0)


def reordered_psm_file(folder):
    """The shipped PSM drive file with [pitch] moved before [roll] (the tables only; same numbers)."""
    text = DEFAULT_PARAMETERS.read_text()
    roll, pitch = table(text, "roll"), table(text, "pitch")
    text = text.replace(roll + pitch, pitch + roll)
    assert text.index("\n[pitch]\n") < text.index("\n[roll]\n")
    path = folder / "psm_reorder.toml"
    path.write_text(text)
    return path


def test_the_psm_file_is_in_driven_order_whatever_its_table_order(tmp_path):
    path = reordered_psm_file(tmp_path)
    raw = tomllib.loads(path.read_text())
    assert list(k for k in raw if k in DRIVEN) == ["pitch", "roll", "insertion"]
    params = load_drive_parameters(path)
    assert params.driven == DRIVEN
    tau = np.array([2.0, 6.0, -5.0])
    pwm = drive_effort(params, tau).pwm
    for k, joint in enumerate(DRIVEN):       # PWM = sign R tau / (k_t N V_pwm), from the file's own numbers
        t = raw[joint]
        want = t["pwm_sign"] * t["resistance"] * tau[k] / (t["torque_constant"] * t["gear_ratio"] * t["volts_per_pwm"])
        assert pwm[k] == pytest.approx(want, rel=1e-12)
    np.testing.assert_array_equal(pwm, drive_effort(load_drive_parameters(), tau).pwm)


def test_a_reordered_psm_file_gives_the_shipped_numbers_in_every_command(capsys, tmp_path, monkeypatch):
    path = reordered_psm_file(tmp_path)
    monkeypatch.chdir(tmp_path)
    for argv in (["linearize", "psm", "--roll", "10", "--pitch=-5", "--json"],
                 ["simulate", "psm", "--experiment", "step", "--controller", "p", "--duration", "0.3", "--json"]):
        code, shipped, err = run(capsys, *argv)
        assert code == 0, err
        code, out, err = run(capsys, *argv, "--params", path)
        assert code == 0, err
        ours = json.loads(out)
        ours.pop("model", None)
        want = json.loads(shipped)
        want.pop("model", None)
        assert ours == want, argv
    for name in ("a", "b"):
        code, _, err = run(capsys, "torque-map", "psm", "--roll=0:10:2", "--pitch=0:0:1", "--out", name,
                           *(["--params", path] if name == "b" else []))
        assert code == 0, err
    assert (tmp_path / "a" / "torque_map.csv").read_text() == (tmp_path / "b" / "torque_map.csv").read_text()


def test_a_psm_file_with_another_joint_table_names_it(capsys, tmp_path):
    text = DEFAULT_PARAMETERS.read_text()
    extra = table(text, "roll").replace("[roll]", "[instrument_roll]")
    path = tmp_path / "psm_extra.toml"
    path.write_text(text.replace("\n[gravity_offsets]\n", "\n" + extra + "[gravity_offsets]\n"))
    with pytest.raises(ParameterFileError, match=r"psm_extra.toml: \[instrument_roll\] is not a driven joint of the "
                                                 r"bundled psm.*roll, pitch, insertion only"):
        load_drive_parameters(path)
    code, out, err = run(capsys, "torque-map", "psm", "--roll=0:0:1", "--pitch=0:0:1", "--params", path,
                         "--out", tmp_path / "m")
    assert code == 2 and out == "" and err.count("\n") == 1 and "[instrument_roll]" in err, err
    assert "drive_effort" not in err and not (tmp_path / "m").exists()


def test_another_robots_joints_are_in_its_actuated_order(tmp_path, mtm):
    values = {k: 1.0 for k in DRIVE_KEYS} | {"rotor_inertia": 1e-6, "coulomb": 0.0, "viscous": 0.0}
    joints = {"j3": values | {"gear_ratio": 30.0}, "j2": values | {"gear_ratio": 50.0, "pwm_sign": -1.0}}
    path = tmp_path / "mtm_drive.toml"
    path.write_text(drive_text("mtm", joints))
    params = check_drive(mtm, load_drive_parameters(path))
    assert params.driven == ("j2", "j3")
    assert params["j2"].gear_ratio == 50.0 and params["j3"].gear_ratio == 30.0
    model = driven_dynamics(mtm, load_drive_parameters(path))
    assert model.joints == ("j2", "j3")
    for k, joint in enumerate(model.joints):      # k_u = sign k_t N V_pwm / R of the joint's own table
        t = joints[joint]
        want = t["pwm_sign"] * t["torque_constant"] * t["gear_ratio"] * t["volts_per_pwm"] / t["resistance"]
        assert model.drive.input_gain[k] == pytest.approx(want, rel=1e-12)
    torque = driven_dynamics(mtm, joints=("j2", "j3"))     # the same pose, torque input: g = k_u u0
    q = [0.3, -0.4]
    np.testing.assert_allclose(np.array(model.gravity(q)).ravel(), np.array(torque.gravity(q)).ravel(), rtol=1e-12)


def test_driven_dynamics_keeps_its_positional_order(psm, params):
    names = list(inspect.signature(driven_dynamics).parameters.values())
    assert [p.name for p in names[:4]] == ["robot", "params", "q_fixed", "coulomb"]
    assert names[4].name == "joints" and names[4].kind is inspect.Parameter.KEYWORD_ONLY
    q_fixed = np.zeros(psm.nq)
    q_fixed[psm.actuated.index("instrument_roll")] = 0.4
    q_fixed[psm.actuated.index("wrist_pitch")] = 0.6
    old_call = driven_dynamics(psm, params, q_fixed, False)            # the call of before
    np.testing.assert_array_equal(old_call.q_fixed, q_fixed)
    assert old_call.coulomb is False
    q = np.array([0.2, -0.3, 0.1])
    held = np.array(old_call.gravity(q)).ravel()
    np.testing.assert_array_equal(held, np.array(driven_dynamics(psm, params, q_fixed=q_fixed).gravity(q)).ravel())
    assert np.abs(held - np.array(driven_dynamics(psm, params).gravity(q)).ravel()).max() > 1e-4
    with pytest.raises(TypeError):
        driven_dynamics(psm, params, q_fixed, False, DRIVEN)


def test_driven_gravity_function_has_no_name_based_default(tmp_path):
    sidecar, _ = write_mypsm(tmp_path)
    robot = rk.load_robot(sidecar)          # a PSM copy: joints named roll, pitch, insertion, and 4 more
    g = driven_gravity_function(robot, {})
    assert g.size1_out(0) == len(robot.actuated) == 7
    q = np.array([0.2, -0.3, 0.1, 0.3, -0.2, 0.1, 0.0])
    want = rk.gravity_torque(robot, q)       # the reduced model's gravity by Pinocchio
    np.testing.assert_allclose(np.array(g(q)).ravel(), want, rtol=1e-9, atol=1e-12)
    three = driven_gravity_function(robot, {}, joints=DRIVEN, q_fixed=np.r_[0, 0, 0, q[3:]])
    np.testing.assert_allclose(np.array(three(q[:3])).ravel(), want[:3], rtol=1e-9, atol=1e-12)


def test_joints_with_a_drive_is_said_for_people(psm, params):
    with pytest.raises(RcmKinError, match="must be those, or left out") as refused:
        driven_dynamics(psm, params, joints=("roll", "pitch"))
    assert "None" not in str(refused.value)


def test_torques_of_the_wrong_joints_name_the_drive_file(params):
    with pytest.raises(RcmKinError, match=r"psm_drive.toml describe 3 joints \(roll, pitch, insertion\), given "
                                          r"torques of 4") as refused:
        drive_effort(params, np.ones(4))
    assert "drive_effort" not in str(refused.value)


def test_one_rule_picks_the_drive_everywhere(tmp_path):
    """resolve_drive: None the robot's own, "cad" none, a path or parameters checked; the map, the
    dynamics and the MJCF follow it alike."""
    import rcm_kin as rk
    from rcm_kin.dynamics.drive import CAD, resolve_drive
    from rcm_kin.export.mjcf import mjcf_tree

    psm = rk.load_robot("psm")
    assert resolve_drive(psm).source == rk.load_drive_parameters().source
    assert resolve_drive(psm, CAD) is None
    assert rk.driven_dynamics(psm, CAD).input_unit.startswith("torque")
    assert "CAD (URDF inertias)" in mjcf_tree(psm, CAD).getroot()[0].text
    assert "calibration psm_drive.toml" in mjcf_tree(psm).getroot()[0].text
    with pytest.raises(rk.RcmKinError, match="describes robot 'psm', not 'mtm'"):
        resolve_drive(rk.load_robot("mtm"), rk.load_drive_parameters())

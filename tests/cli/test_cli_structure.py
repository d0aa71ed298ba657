"""The CLI package stays small (modules <= 250 lines, functions <= 60), and the library functions
taken out of it agree with independent computations."""

from __future__ import annotations

import ast
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import rcm_kin.cli
from rcm_kin import RcmKinError
from rcm_kin.identification.transfer_function import polynomial_text
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.ik import inverse_kinematics
from rcm_kin.model import joint_table, load_robot
from rcm_kin.model.reduced import tree_configuration
from rcm_kin.safety.sos import poly_eval, poly_text
from rcm_kin.statics.maps import holding_effort

CLI_MODULES = sorted(Path(rcm_kin.cli.__file__).parent.glob("*.py"))


@pytest.mark.parametrize("path", CLI_MODULES, ids=lambda p: p.name)
def test_cli_module_size(path):
    assert len(path.read_text().splitlines()) <= 250


@pytest.mark.parametrize("path", CLI_MODULES, ids=lambda p: p.name)
def test_cli_function_size(path):
    tree = ast.parse(path.read_text())
    long = [f"{node.name} ({node.end_lineno - node.lineno + 1} lines)" for node in ast.walk(tree)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno + 1 > 60]
    assert not long


# libraries only some commands need (each costs 0.05-0.3 s to import): the CLI's start-up, which
# every command pays, must not load them (it took 0.56 s with SciPy and python-control, now 0.24 s)
HEAVY = ("scipy", "control", "matplotlib", "numba", "cvxpy", "daqp", "clarabel", "meshcat", "dask", "jinja2",
         "mujoco", "rosbags", "yourdfpy", "rclpy")


def test_cli_start_up_leaves_the_heavy_libraries_for_the_commands():
    code = "import sys, rcm_kin.cli; print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert "pinocchio" in loaded and not set(HEAVY) & set(loaded)


def test_a_command_imports_its_own_module_only():
    """``rcm-kin fk ...`` builds the parser of ``fk`` alone: the other commands' modules (and what
    they import) are not loaded; its help is the full parser's."""
    code = ("import sys, rcm_kin.cli as c; p = c.build_parser('fk'); "
            "print(sorted(m for m in sys.modules if m.startswith('rcm_kin.cli.')))")
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "rcm_kin.cli.kinematics" in loaded and "rcm_kin.cli.robustness" not in loaded
    assert "rcm_kin.cli.simulation" not in loaded and "rcm_kin.cli.views" not in loaded
    alone = rcm_kin.cli.build_parser("identify")._subparsers._group_actions[0].choices
    full = rcm_kin.cli.build_parser()._subparsers._group_actions[0].choices
    assert list(alone) == ["identify"] and alone["identify"].format_help() == full["identify"].format_help()


def test_cli_has_every_command():
    commands = rcm_kin.cli.build_parser()._subparsers._group_actions[0].choices
    assert list(commands) == ["info", "fk", "ik", "gravity", "torque-map", "counterweights", "calibrate", "dynamics",
                              "linearize", "schedule", "simulate", "robustness", "sweep", "sysid", "greybox",
                              "identify", "predict", "excite", "view", "safety", "report", "export",
                              "ros2"]


# --- inverse kinematics: every solution put through forward kinematics lands on its target ---
@pytest.mark.parametrize("name, q, rpy", [
    ("psm", [0.2, -0.3, 0.1], False),
    ("psm", [-0.4, 0.1, 0.05], False),
    ("psm", [0.1, -0.1, 0.1, 0.2, 0.1, -0.1], True),
    ("mtm", [0.3, 0.2, -0.1], False),
])
def test_inverse_kinematics_round_trip(name, q, rpy):
    robot = load_robot(name)
    q_true = robot.check_q(q, allow_short=True)
    solution = inverse_kinematics(robot, frame_placement(robot, q_true, "shaft_tip" if name == "psm" and not rpy
                                                         else "tool_tip" if rpy else "wrist_center").translation,
                                  pin.rpy.matrixToRpy(frame_placement(robot, q_true, "tool_tip").rotation)
                                  if rpy else None)
    target = frame_placement(robot, q_true, solution.frame)
    reached = frame_placement(robot, solution.q_full, solution.frame)
    assert np.linalg.norm(reached.translation - target.translation) < 1e-9
    assert solution.position_error < 1e-9
    assert len(solution.q) == len(solution.joints) == len(q)
    np.testing.assert_array_equal(solution.q_full[:len(q)], solution.q)
    assert solution.joints == robot.actuated[:len(q)]
    if rpy:
        assert np.linalg.norm(pin.log3(reached.rotation.T @ target.rotation)) < 1e-9
        assert solution.orientation_error < 1e-9
    else:
        assert solution.orientation_error is None
    if name == "psm":                       # the closed form is unique inside the limits
        np.testing.assert_allclose(solution.q, q, atol=1e-9)


@pytest.mark.parametrize("name, rpy, message", [("mtm", [0, np.nan, 0], "`rpy` is 3 finite angles"),
                                                ("davinci", [0, 0], "`rpy` is 3 finite angles"),
                                                ("psm", None, "out of reach")])
def test_inverse_kinematics_errors(name, rpy, message):
    target = [1.0, 1.0, 1.0] if name == "psm" else [0.2, 0.0, -0.2]
    with pytest.raises(RcmKinError, match=message):
        inverse_kinematics(load_robot(name), target, rpy)


# --- joint table: limits and kinds from the URDF text, axes by finite differences of the placements ---
@pytest.mark.parametrize("name", ["psm", "mtm", "davinci"])
def test_joint_table_matches_urdf(name):
    robot = load_robot(name)
    urdf = {j.get("name"): j for j in ET.parse(robot.description.urdf).getroot().iter("joint")
            if j.get("type") != "fixed"}
    table = joint_table(robot)
    assert [row.name for row in table] == list(robot.tree.names[1:])
    assert {row.name for row in table} == set(urdf)
    passive = {p.joint for p in robot.description.passive}
    q_tree = tree_configuration(robot, np.zeros(robot.nq))
    for row in table:
        limit = urdf[row.name].find("limit")
        assert row.kind == ("prismatic" if urdf[row.name].get("type") == "prismatic" else "revolute")
        assert row.role == ("passive" if row.name in passive else "actuated")
        assert (row.lower, row.upper) == pytest.approx((float(limit.get("lower")), float(limit.get("upper"))))
        np.testing.assert_allclose(row.axis, _axis_by_differences(robot, q_tree, row.name, row.kind), atol=1e-6)


def _axis_by_differences(robot, q_tree, joint: str, kind: str, eps: float = 1e-7) -> np.ndarray:
    """Base-frame axis of ``joint``: how its own placement moves when only that joint moves."""
    jid = robot.tree.getJointId(joint)
    placements = []
    for step in (0.0, eps):
        q = q_tree.copy()
        q[robot.tree.joints[jid].idx_q] += step
        data = robot.tree.createData()
        pin.forwardKinematics(robot.tree, data, q)
        placements.append(data.oMi[jid].copy())
    before, after = placements
    if kind == "prismatic":
        return (after.translation - before.translation) / eps
    return pin.log3(after.rotation @ before.rotation.T) / eps


def test_joint_table_is_the_info_payload(capsys):
    import json

    assert rcm_kin.cli.main(["info", "mtm", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)["joints"]
    rows = joint_table(load_robot("mtm"))
    assert [(j["name"], j["type"], j["role"], j["lower"], j["upper"]) for j in shown] == \
        [(r.name, r.kind, r.role, r.lower, r.upper) for r in rows]


# --- polynomial text: known strings, and the text evaluates to the polynomial ---
def test_polynomial_text_known():
    assert polynomial_text([1.0, -2.5, 0.001234567]) == "1 s^2 - 2.5 s + 0.0012346"
    assert polynomial_text([-3.0, 4.0]) == "-3 s + 4"
    assert polynomial_text([2.0, 0.0, 0.0, -1.0], "z") == "2 z^3 + 0 z^2 + 0 z - 1"


def test_polynomial_text_evaluates_to_the_polynomial():
    coefficients = [0.5, 4.0426, -8.3312, 16.288]
    text = polynomial_text(coefficients).replace(" s", " * s").replace("^", "**")
    for s in (0.3, -1.7, 2.0):
        assert eval(text, {"s": s}) == pytest.approx(np.polyval(coefficients, s), rel=1e-4)


def test_poly_text_known():
    p = {(2, 0): 1.5, (1, 1): -2.0, (0, 0): 0.25, (0, 1): 1e-7}
    assert poly_text(p, ("x", "y")) == "+1.5 x^2  -2 x y  +1e-07 y  +0.25"


def test_poly_text_evaluates_to_the_polynomial():
    p = {(0, 0, 2): -3.25, (1, 2, 0): 0.125, (0, 1, 0): 7.0, (0, 0, 0): -1.0}
    text = poly_text(p, ("a", "b", "c"))
    expression = " + ".join("*".join(term.replace("^", "**").split()) for term in text.split("  "))
    for x in np.random.default_rng(0).normal(size=(5, 3)):
        assert eval(expression, dict(zip("abc", x))) == pytest.approx(poly_eval(p, x)[0], rel=1e-12)


# --- holding effort: the MTM's against Pinocchio's gravity, the PSM's PWM back to its torque ---
def test_holding_effort():
    from rcm_kin.dynamics.drive import load_drive_parameters, pwm_to_torque
    from rcm_kin.model.gravity import gravity_torque

    mtm = load_robot("mtm")
    q = mtm.check_q([0.2, -0.3, 0.4], allow_short=True)
    effort = holding_effort(mtm, q)
    assert effort.drive is None
    np.testing.assert_allclose(effort.tau, gravity_torque(mtm, q), atol=1e-9)
    psm = load_robot("psm")
    effort = holding_effort(psm, psm.check_q([0.2, -0.3, 0.1], allow_short=True))
    np.testing.assert_allclose(pwm_to_torque(load_drive_parameters(), effort.drive.pwm), effort.tau[:3], atol=1e-9)

"""Gain scheduling, stability checks and the firmware export (the gain-scheduling issue)."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest
from scipy.linalg import solve_continuous_are

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.codegen.firmware_export import header_text
from rcm_kin.control.gain_schedule import (
    THESIS_PITCH_DEG,
    THESIS_ROLL_DEG,
    axis_model,
    closed_loop_matrix,
    lqr_axis,
    parse_grid,
    pitch_gains,
    roll_gains,
    schedule_gains,
    scheduled_gains,
)
from rcm_kin.control.linearization import linearize
from rcm_kin.control.stability import firmware_loop_matrix, stability_survey
from rcm_kin.control.weights import Weights
from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.firmware_rules import bilinear

# The thesis's identified roll model at (0, 0) and its firmware gains (reference sheet).
THESIS_A = np.array([[-6.1202, -4.0720], [4.0, 0.0]])
THESIS_B = np.array([[2.0], [0.0]])


def test_lqr_reproduces_the_thesis_roll_gains():
    K = lqr_axis(THESIS_A, THESIS_B, np.diag([500.0, 0.25]), np.array([[0.0075]]))
    np.testing.assert_allclose(K, [255.1886, 4.0860], atol=5e-5)     # the thesis prints 4 decimals


def test_lqi_equals_lqr_on_the_augmented_system_by_riccati():
    """LQI through python-control's integral_action against scipy's Riccati solve on [A 0; C 0]."""
    A = THESIS_A
    Q, R = np.diag([500.0, 0.25, 40.0]), np.array([[0.0075]])
    K = lqr_axis(A, THESIS_B, Q, R, integral=True)
    A_aug = np.block([[A, np.zeros((2, 1))], [np.array([[1.0, 0.0, 0.0]])]])
    B_aug = np.vstack([THESIS_B, [[0.0]]])
    P = solve_continuous_are(A_aug, B_aug, Q, R)
    np.testing.assert_allclose(K, (np.linalg.solve(R, B_aug.T @ P))[0], rtol=1e-9)


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("integral", [False, True])
def test_lqr_axis_is_python_controls_lqr(seed, integral):
    """The SciPy Riccati solve that replaced python-control's ``lqr`` (and its second of imports)
    gives python-control's gains, with and without ``integral_action``, to 1e-10."""
    import control

    rng = np.random.default_rng(seed)
    a, b = rng.normal(0.0, 3.0, (2, 2)), rng.normal(0.0, 2.0, (2, 1))
    Q, R = np.diag(rng.uniform(0.1, 500.0, 3 if integral else 2)), np.array([[rng.uniform(1e-3, 1.0)]])
    extra = {"integral_action": np.array([[1.0, 0.0]])} if integral else {}
    expected = np.asarray(control.lqr(a, b, Q, R, **extra)[0])[0]
    np.testing.assert_allclose(lqr_axis(a, b, Q, R, integral=integral), expected, rtol=1e-10, atol=1e-10)


def test_lqr_axis_refuses_unsymmetric_weights():
    with pytest.raises(RcmKinError, match="symmetric"):
        lqr_axis(THESIS_A, THESIS_B, np.array([[1.0, 2.0], [0.0, 1.0]]), np.array([[1.0]]))


@pytest.fixture(scope="module")
def design(psm):
    return driven_dynamics(psm, coulomb=False)


@pytest.fixture(scope="module")
def thesis_schedule(design):
    return schedule_gains(design, THESIS_ROLL_DEG, THESIS_PITCH_DEG)


def test_firmware_signs_close_the_loop_the_lqr_designed(design):
    """With the roll and pitch decoupled, the 7-state firmware-law matrix has exactly the poles
    python-control reports for each axis design: the sign/unit mapping to (Kp, Kd, Ki) is right."""
    import control
    lin = linearize(design, [0.2, -0.1, 0.08])
    A, B = lin.A.copy(), lin.B.copy()
    for i in range(3):                         # remove the cross-couplings
        for j in range(3):
            if i != j:
                A[3 + i, j] = A[3 + i, 3 + j] = B[3 + i, j] = 0.0
    w = Weights()
    k_roll, k_pitch = roll_gains(A, B, w), pitch_gains(A, B, w)
    poles = np.linalg.eigvals(closed_loop_matrix(A, B, k_roll, k_pitch))
    _, _, e_roll = control.lqr(*axis_model(A, B, 0), *w.roll())
    _, _, e_pitch = control.lqr(*axis_model(A, B, 1), *w.pitch(), integral_action=np.array([[1.0, 0.0]]))
    for e in np.r_[e_roll, e_pitch]:
        assert np.min(np.abs(poles - e)) < 1e-8 * abs(e)
    assert k_roll[0] > 0 and k_pitch[0] > 0 and k_pitch[2] > 0   # restoring, as the thesis's tables


def test_schedule_is_stable_at_nodes_and_between(design, thesis_schedule):
    for A_cl in thesis_schedule.A_cl.reshape(-1, 7, 7):
        assert np.linalg.eigvals(A_cl).real.max() < 0
    survey = stability_survey(design, thesis_schedule, points=9)
    assert survey.stable
    # a pitch gain of the wrong sign is caught
    flipped = stability_survey(design, thesis_schedule, points=3,
                               gains=lambda r, p: (scheduled_gains(thesis_schedule, r, p)[0],
                                                   scheduled_gains(thesis_schedule, r, p)[1] * [-1, 1, 1]))
    assert not flipped.stable


def test_firmware_loop_tends_to_the_continuous_loop(design, thesis_schedule):
    """Sampling at 1 MHz with no velocity filter, ln(z)/T of the firmware loop are the continuous poles."""
    A, B = thesis_schedule.A[1, 1], thesis_schedule.B[1, 1]
    kr, kp = thesis_schedule.k_roll[1, 1], thesis_schedule.k_pitch[1, 1]
    continuous = np.linalg.eigvals(closed_loop_matrix(A, B, kr, kp))
    period = 1e-6
    z = np.linalg.eigvals(firmware_loop_matrix(A, B, kr, kp, period=period, roll_filter=0.0))
    s = np.log(z[np.abs(z) > 1e-3].astype(complex)) / period
    for e in continuous:
        assert np.min(np.abs(s - e)) < 1e-3 * abs(e)


def test_bilinear_interpolation_nodes_midpoints_and_clamping(thesis_schedule):
    s = thesis_schedule
    for j, p in enumerate(s.pitch_deg):
        for i, r in enumerate(s.roll_deg):
            np.testing.assert_array_equal(scheduled_gains(s, r, p)[1], s.k_pitch[j, i])
    mid = scheduled_gains(s, 10.0, 7.5)[0]
    np.testing.assert_allclose(mid, s.k_roll[1:, 1:].mean(axis=(0, 1)), rtol=1e-13)
    np.testing.assert_array_equal(scheduled_gains(s, 80.0, -40.0)[0], s.k_roll[0, -1])   # clamped corner
    np.testing.assert_array_equal(scheduled_gains(s, 25.0, 3.0)[1], scheduled_gains(s, 20.0, 3.0)[1])
    with pytest.raises(RcmKinError, match="finite"):
        scheduled_gains(s, float("nan"), 0.0)


def test_pitch_feedforward_inverts_the_pitch_model(thesis_schedule):
    """u_ff = F_v rdot + F_a rddot plus the holding slope reproduces rddot through the axis model."""
    a, b = axis_model(thesis_schedule.A[1, 1], thesis_schedule.B[1, 1], 1)
    F_v, F_a = thesis_schedule.ff_pitch[1, 1]
    rdot, rddot = 12.0, -30.0
    u = F_v * rdot + F_a * rddot
    np.testing.assert_allclose(a[1, 1] * rdot + b[1, 0] * u, rddot, rtol=1e-12)


@pytest.mark.parametrize("text, message", [("1,2", "ROLLS:PITCHES"), ("a:1,2", "numbers"), ("0:1,2", "at least 2"),
                                           ("-40,0:0,1", "joint range"), ("0,0:0,1", "increasing")])
def test_bad_grids_are_refused(text, message):
    with pytest.raises(RcmKinError, match=message):
        parse_grid(text)


def test_bad_weights_are_refused():
    with pytest.raises(RcmKinError, match="positive"):
        Weights(roll_pwm=0.0)


C_DRIVER = r"""
#include <stdio.h>
#include "gain_schedule.h"
int main(void)
{
    double r, p, rdot, kr[2], kp[3], ff[2], uh[2];
    while (scanf("%lf %lf %lf", &r, &p, &rdot) == 3) {
        rcm_gain_schedule(r, p, kr, kp);
        rcm_pitch_feedforward(r, p, ff);
        rcm_holding_pwm(r, p, uh);
        printf("%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
               kr[0], kr[1], kp[0], kp[1], kp[2], ff[0], ff[1], uh[0], uh[1],
               rcm_friction_feedforward(rdot, 0), rcm_friction_feedforward(rdot, 1),
               rcm_friction_feedforward(rdot, 2));
    }
    return 0;
}
"""


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
def test_header_compiles_and_matches_python(tmp_path, design):
    schedule = schedule_gains(design, [-30, -10, 0, 20], [-25, 0, 30], insertion=0.05, friction_ramp_deg_s=3.5)
    (tmp_path / "gain_schedule.h").write_text(header_text(schedule, gravity_feedforward=True,
                                                          friction_feedforward=True))
    (tmp_path / "main.c").write_text(C_DRIVER)
    subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2", "-o", "gs", "main.c", "-lm"],
                   cwd=tmp_path, check=True, capture_output=True)
    rng = np.random.default_rng(11)
    points = np.vstack([rng.uniform(-40, 40, (200, 2)), [[-30, -25], [0, 0], [20, 30], [-10, 0], [100, -100]]])
    # reference velocities (deg/s): at rest, inside the ramp, at it, beyond it, both signs
    rdots = np.r_[rng.uniform(-60, 60, 200), 0.0, 1e-3, -0.7, 3.5, -45.0]
    # Python floats: the repr of a NumPy 2 scalar is "np.float64(..)", which scanf cannot read
    stdin = "\n".join(f"{float(r)!r} {float(p)!r} {float(v)!r}" for (r, p), v in zip(points, rdots))
    out = subprocess.run([str(tmp_path / "gs")], input=stdin, capture_output=True, text=True, check=True).stdout
    c_values = np.array([[float(v) for v in line.split()] for line in out.splitlines()])
    assert c_values.shape == (len(points), 12)
    for (r, p), v, c in zip(points, rdots, c_values):
        kr, kp = scheduled_gains(schedule, r, p)
        ff = bilinear(schedule.roll_deg, schedule.pitch_deg, schedule.ff_pitch, r, p)
        uh = bilinear(schedule.roll_deg, schedule.pitch_deg, schedule.u_hold, r, p)
        np.testing.assert_allclose(c[:9], np.r_[kr, kp, ff, uh], rtol=1e-14, atol=1e-12)
        np.testing.assert_allclose(c[9:], np.r_[schedule.friction.feedforward([v, v]), 0.0], rtol=0, atol=1e-12)


def test_cli_dynamics_and_linearize_contracts(capsys, design):
    # --coulomb: the model dynamics evaluates (smoothed Coulomb friction), so that A is its Jacobian
    assert main(["linearize", "psm", "--roll", "10", "--pitch=-5", "--insertion", "0.06", "--coulomb", "--json"]) == 0
    lin = json.loads(capsys.readouterr().out)
    assert set(lin) == {"x0", "u0", "A", "B", "C", "D", "state", "input", "model", "input_unit", "coulomb_slope"}
    assert lin["coulomb_slope"] is True
    assert lin["model"] == "calibration psm_drive.toml" and lin["input_unit"] == "PWM [counts]"
    x0, u0, A = np.array(lin["x0"]), np.array(lin["u0"]), np.array(lin["A"])
    np.testing.assert_allclose(x0[:3], [np.radians(10), np.radians(-5), 0.06])

    def qdd(q, v, u):
        assert main(["dynamics", "psm", "--q", *(repr(float(x)) for x in q), "--v", *(repr(float(x)) for x in v),
                     "--u", *(repr(float(x)) for x in u),
                     "--json"]) == 0
        return np.array(json.loads(capsys.readouterr().out)["qdd"])

    np.testing.assert_allclose(qdd(x0[:3], x0[3:], u0), 0, atol=1e-10)          # an equilibrium of dynamics
    h = 1e-6                                                                    # and A is its Jacobian
    for k in range(6):
        dx = np.eye(6)[k] * h
        col = (qdd(*np.split(x0 + dx, 2), u0) - qdd(*np.split(x0 - dx, 2), u0)) / (2 * h)
        np.testing.assert_allclose(col, A[3:, k], atol=1e-6 * max(1, np.abs(A).max()))


def test_cli_schedule_writes_the_contract_files(tmp_path, capsys):
    out = tmp_path / "gains"
    assert main(["schedule", "psm", "--grid=-20,0,20:-15,0,15", "--check-points", "5", "--out", str(out),
                 "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["stable"] is True
    gains = json.loads((out / "gains.json").read_text())
    assert gains["roll_deg"] == [-20, 0, 20] and gains["pitch_deg"] == [-15, 0, 15]
    assert np.array(gains["k_roll"]).shape == (3, 3, 2) and np.array(gains["k_pitch"]).shape == (3, 3, 3)
    assert len(gains["points"]) == 9
    point = gains["points"][5]                                   # pitch 0, roll 20
    assert (point["roll_deg"], point["pitch_deg"]) == (20, 0)
    assert np.array(point["A"]).shape == (6, 6) and np.array(point["A_cl"]).shape == (7, 7)
    np.testing.assert_allclose(np.array(gains["k_roll"])[1][2], roll_gains(np.array(point["A"]),
                                                                           np.array(point["B"]), Weights()))
    assert (out / "gain_schedule.h").read_text().count("rcm_gain_schedule(double roll_deg") == 1
    assert len((out / "gains.csv").read_text().splitlines()) == 10
    assert main(["schedule", "mtm", "--out", str(out)]) == 2
    assert "schedule needs a drive" in capsys.readouterr().err


def test_thesis_gains_on_the_thesis_roll_model_by_python_control():
    """The closed-loop poles of the firmware law on G(s), against python-control's feedback."""
    import control

    from rcm_kin.control.thesis_comparison import THESIS_K_ROLL, THESIS_ROLL_TF, thesis_roll_closed_loop
    kp, kd = THESIS_K_ROLL[1, 1]
    # u = -(Kp (r - y) + Kd ydot) = (Kp - Kd s) y - Kp r: positive feedback through Kp - Kd s
    loop = control.feedback(control.tf(*THESIS_ROLL_TF), control.tf([-kd, kp], [1.0]), sign=1)
    np.testing.assert_allclose(np.sort_complex(thesis_roll_closed_loop(kp, kd)), np.sort_complex(loop.poles()),
                               rtol=1e-9)


def test_thesis_tables_beside_the_model(design):
    from rcm_kin.control.thesis_comparison import compare_with_thesis
    c = compare_with_thesis(design, points=5)
    assert c.ours.stable
    # the thesis's Kd has the accelerating sign on the model, so its loops are unstable there
    assert not c.thesis.stable and c.thesis_damping_flipped.stable

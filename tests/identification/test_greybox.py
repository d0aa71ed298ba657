"""Grey-box fit of the drive's friction and inertia scale (issue 5)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rcm_kin.cli import main
from rcm_kin.dynamics.drive import load_drive_parameters, with_joint
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm
from rcm_kin.identification.greybox import fit_greybox, step_logs

DEG_PER_RAD = 180.0 / np.pi   # the logs hold degrees
TRUE = {"extra_inertia": 0.12, "viscous": 0.4, "coulomb": 0.6, "coulomb_velocity": 0.01}
HEADER = ["time", "roll_position", "roll_velocity", "pitch_position", "pitch_velocity"]


def synthetic_step_log(path, psm, params, roll_deg, pitch_deg, du, period=0.002, samples=700):
    """A roll step from rest at a pose, integrated by scipy (Radau, rtol 1e-10) on the physics
    with the true parameters: an independent route to the data the fit sees."""
    truth = with_joint(params, "roll", **TRUE)
    model = driven_dynamics(psm, truth)
    pose = np.array([roll_deg / DEG_PER_RAD, pitch_deg / DEG_PER_RAD, 0.08])
    u_hold = holding_pwm(model, pose)[0]
    d = model.drive

    def rhs(_, s):
        q = pose.copy()
        q[0] = s[0]
        tau = (d.input_gain[0] * (u_hold + du) - d.damping[0] * s[1]
               - d.coulomb[0] * np.tanh(s[1] / d.coulomb_velocity[0]) - float(model.gravity(q)[0]))
        return [s[1], tau / float(model.mass_matrix(q)[0, 0])]

    t = np.arange(samples) * period
    step_at = 50
    sol = solve_ivp(rhs, (0, t[-1] - t[step_at]), [pose[0], 0.0], t_eval=t[step_at:] - t[step_at],
                    method="Radau", rtol=1e-10, atol=1e-12)
    roll = np.r_[np.full(step_at, pose[0]), sol.y[0]] * DEG_PER_RAD
    pwm = np.r_[np.full(step_at, u_hold), np.full(samples - step_at, u_hold + du)]
    rows = zip(t, roll, pwm, np.full(samples, pitch_deg), np.zeros(samples))
    path.write_text(",".join(HEADER) + "\n" + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path


def test_greybox_recovers_friction_and_inertia_of_synthetic_steps(tmp_path, psm):
    params = load_drive_parameters()
    paths = [synthetic_step_log(tmp_path / f"step_{k}.csv", psm, params, r, p, du)
             for k, (r, p, du) in enumerate(((0.0, 0.0, -12.0), (-10.0, 5.0, -10.0), (10.0, -5.0, 9.0)))]
    fit = fit_greybox(params, "roll", step_logs(paths, "roll", samples=600))
    np.testing.assert_allclose(fit.after, [TRUE[n] for n in fit.names], rtol=2e-3)
    np.testing.assert_allclose(fit.coulomb_per_log, TRUE["coulomb"], rtol=2e-3)
    assert np.all(fit.fit_after > 99.9) and np.all(fit.fit_after > fit.fit_before)
    assert fit.params["roll"].coulomb == pytest.approx(fit.after[2])


def test_greybox_cli_writes_a_usable_parameter_file(tmp_path, psm, capsys):
    params = load_drive_parameters()
    path = synthetic_step_log(tmp_path / "step.csv", psm, params, 0.0, 0.0, -12.0, samples=400)
    out = tmp_path / "fitted.toml"
    assert main(["greybox", str(path), "--joint", "roll", "--samples", "300", "--out", str(out), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert set(payload["after"]) == set(TRUE) and payload["written"] == str(out)
    assert load_drive_parameters(out)["roll"].extra_inertia == pytest.approx(payload["after"]["extra_inertia"])
    assert main(["simulate", "psm", "--experiment", "step", "--controller", "p", "--duration", "0.5",
                 "--params", str(out), "--json"]) == 0


def test_extra_inertia_adds_to_the_joint_diagonal(psm):
    params = with_joint(load_drive_parameters(), "roll", extra_inertia=0.0)
    q = np.array([0.1, -0.2, 0.1])
    M = np.array(driven_dynamics(psm, params).mass_matrix(q))
    M2 = np.array(driven_dynamics(psm, with_joint(params, "roll", extra_inertia=0.25)).mass_matrix(q))
    np.testing.assert_allclose(M2 - M, np.diag([0.25, 0.0, 0.0]), rtol=0, atol=1e-15)

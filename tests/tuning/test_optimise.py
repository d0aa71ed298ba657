"""The search (:func:`rcm_kin.tuning.optimise.minimise`) on a problem whose optimum is known in
closed form: the LQR of a double integrator, each candidate gain scored by its quadratic cost, and
the frozen-loop radius a design is judged by (:func:`rcm_kin.tuning.optimise.loop_radius`)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_continuous_are, solve_continuous_lyapunov

from rcm_kin.control.linearization import linearize_grid
from rcm_kin.control.stability import firmware_loop_matrix
from rcm_kin.dynamics.state_space import driven_dynamics
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import FIRMWARE_PERIOD, HOME_INSERTION
from rcm_kin.robustness.task import roll_pitch_modes
from rcm_kin.tuning.design import DesignSpace
from rcm_kin.tuning.optimise import loop_radius, minimise

# double integrator x1' = x2, x2' = u; cost int x' Q x + r u^2
A = np.array([[0.0, 1.0], [0.0, 0.0]])
B = np.array([[0.0], [1.0]])
Q1, Q2, R = 9.0, 2.0, 0.5
Q = np.diag([Q1, Q2])
K_MAX = 10.0                     # the unit box maps to K in [0, 10]^2
K_STAR = np.array([np.sqrt(Q1 / R), np.sqrt(Q2 / R + 2 * np.sqrt(Q1 / R))])    # closed form
UNSTABLE = 1e6
SEED = 3


def lqr_cost(K: np.ndarray) -> float:
    """trace(P) of ``u = -K x``: the mean cost over unit initial states (large when unstable)."""
    K = np.atleast_2d(K)
    closed = A - B @ K
    if np.linalg.eigvals(closed).real.max() >= 0:
        return UNSTABLE
    P = solve_continuous_lyapunov(closed.T, -(Q + R * K.T @ K))
    return float(np.trace(P))


def score(x: np.ndarray) -> float:
    return lqr_cost(K_MAX * np.asarray(x))


def search(**kwargs):
    options = {"seed": SEED, "budget_s": 30.0, "popsize": 10, "tol": 1e-10} | kwargs
    return minimise(score, 2, **options)


@pytest.fixture(scope="module")
def found():
    return search()


def test_the_closed_form_is_the_riccati_solution():
    P = solve_continuous_are(A, B, Q, np.array([[R]]))
    np.testing.assert_allclose(K_STAR, (B.T @ P / R).ravel(), rtol=1e-12)
    assert lqr_cost(K_STAR) == pytest.approx(np.trace(P), rel=1e-10)
    assert lqr_cost(np.array([1.0, -0.1])) == UNSTABLE


def test_minimise_recovers_the_lqr_gains(found):
    assert found.stopped == "converged"
    np.testing.assert_allclose(K_MAX * found.x, K_STAR, rtol=1e-3)
    best = lqr_cost(K_STAR)
    assert best - 1e-12 <= found.fun <= best * (1 + 1e-6)      # nothing beats the optimum
    assert found.fun == score(found.x)
    assert found.evaluations > 2 * 10 * 2 and found.wall_s > 0


def test_the_generations_best_never_worsens(found):
    history = np.array(found.history)
    assert history.size >= 2
    assert np.all(np.diff(history) <= 0)
    assert history[-1] == found.fun


def test_a_seed_gives_one_answer(found):
    again = search()
    np.testing.assert_array_equal(again.x, found.x)
    assert again.history == found.history and again.evaluations == found.evaluations
    other = search(seed=SEED + 1)
    assert not np.array_equal(other.x, found.x)


def test_forked_workers_give_the_serial_answer(found):
    forked = search(workers=2)
    np.testing.assert_array_equal(forked.x, found.x)
    assert forked.fun == found.fun
    assert forked.history == found.history and forked.evaluations == found.evaluations


def test_a_start_at_the_optimum_is_kept_when_the_budget_ends_at_once():
    start = K_STAR / K_MAX
    m = search(budget_s=1e-9, popsize=5, start=(start,))
    assert m.stopped == "time budget"
    assert len(m.history) == 1                       # one generation, then the budget ended the search
    np.testing.assert_allclose(m.x, start, rtol=0, atol=1e-15)
    assert m.fun == pytest.approx(lqr_cost(K_STAR), rel=1e-12)
    cold = search(budget_s=1e-9, popsize=5)          # without the start, one generation is far off
    assert cold.fun > m.fun * (1 + 1e-6)


@pytest.mark.parametrize(("argument", "value"), [
    ("budget_s", 0.0), ("budget_s", -1.0), ("budget_s", float("nan")),
    ("workers", 0), ("workers", 65), ("popsize", 1), ("popsize", 101),
])
def test_bad_arguments_are_refused(argument, value):
    with pytest.raises(RcmKinError) as error:
        minimise(score, 2, **{argument: value})
    assert error.value.parameter == argument


def test_a_population_too_small_for_scipy_is_refused_by_name():
    with pytest.raises(RcmKinError) as error:
        minimise(score, 2, popsize=2, budget_s=1.0)
    assert error.value.parameter == "popsize"


def test_loop_radius_is_the_worst_firmware_loop_over_poses_and_draws(psm, nominal_draws):
    """Against the frozen-gain firmware loops built directly, at the gains the design gives each pose."""
    space = DesignSpace("scheduled")
    rng = np.random.default_rng(11)
    for _ in range(2):
        values = space.values(rng.random(len(space.parameters)))
        want = 0.0
        for d in nominal_draws.draws:
            model = driven_dynamics(psm, d.params, coulomb=False)
            r, p = d.loops.roll_deg, d.loops.pitch_deg
            poses = np.column_stack([np.radians(r), np.radians(p), np.full(r.size, HOME_INSERTION)])
            grid = linearize_grid(model, poses, compile=False)
            for A_, B_, roll, pitch in zip(grid.A, grid.B, r, p):
                scale = {axis: 1 + values[f"{axis}_kp_roll_slope"] * roll / 20
                         + values[f"{axis}_kp_pitch_slope"] * pitch / 15 for axis in ("roll", "pitch")}
                k_roll = [values["roll_kp"] * scale["roll"], values["roll_kd"]]
                k_pitch = [values["pitch_kp"] * scale["pitch"], values["pitch_kd"], values["pitch_ki"]]
                Phi = firmware_loop_matrix(A_, B_, k_roll, k_pitch, FIRMWARE_PERIOD)
                want = max(want, float(np.abs(roll_pitch_modes(Phi)).max()))
        assert loop_radius(values, nominal_draws) == pytest.approx(want, abs=1e-10)

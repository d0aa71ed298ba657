"""The CBF-QP solved by DAQP's active-set method (issue 16): the same optimum as Clarabel, the
KKT conditions checked on their own, a clear error when infeasible, and the scenarios' decisions
equal to those of a Clarabel solve per step."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.optimize import nnls

from rcm_kin import RcmKinError
from rcm_kin.safety.barriers import Ellipsoid
from rcm_kin.safety.cbf import BarrierTerms, barrier_terms, cbf_qp, cbf_qp_problem, qp_matrices, solve_cbf_qp

ALPHA = 20.0
CLARABEL_TOL = 1e-12     # tightened gap and feasibility tolerances of the reference solves
AGREE = 1e-8             # |u - u_clarabel| allowed (m): what such a Clarabel solve reaches on these data
KKT = 1e-9               # stationarity, feasibility and complementarity residuals (m)
ACTIVE = 1e-9            # a constraint within this (m) of its bound counts as active


def clarabel_qp(u_nominal, terms, alpha, u_max):
    """The same QP through a fresh Clarabel solver with tightened tolerances (the reference)."""
    import clarabel

    settings = clarabel.DefaultSettings()
    settings.verbose = False
    settings.tol_gap_abs = settings.tol_gap_rel = settings.tol_feas = CLARABEL_TOL
    settings.tol_ktratio = 1e-10
    P, q, A, b = qp_matrices(np.asarray(u_nominal, dtype=float), terms, alpha, u_max)
    solution = clarabel.DefaultSolver(P, q, A, b, [clarabel.NonnegativeConeT(len(b))], settings).solve()
    assert str(solution.status) == "Solved"
    return np.array(solution.x)


def constraints(terms, alpha, u_max, m):
    """``G u <= h`` with every row scaled to unit length (the same half-spaces; a zero row kept),
    so residuals are distances in the inputs' units."""
    G = np.array([t.lg for t in terms] + list(np.eye(m)) + list(-np.eye(m)), dtype=float).reshape(-1, m)
    h = np.array([-t.lf - alpha * t.value for t in terms] + list(u_max) * 2)
    norms = np.linalg.norm(G, axis=1)
    norms[norms == 0] = 1.0
    return G / norms[:, None], h / norms


def kkt_residuals(u, u_nominal, terms, alpha, u_max):
    """KKT of ``min |u - u_nom|^2 s.t. G u <= h`` at ``u``, computed without any QP solver:
    the multipliers of the active rows by non-negative least squares on stationarity
    ``2 (u - u_nom) + G_a^T lam = 0``. Returns (stationarity, primal violation, complementarity,
    least multiplier)."""
    G, h = constraints(terms, alpha, u_max, u.size)
    slack = h - G @ u
    active = slack <= ACTIVE
    lam = np.zeros(len(h))
    if active.any():
        lam[active], _ = nnls(G[active].T, -2 * (u - u_nominal))
    stationarity = np.abs(2 * (u - u_nominal) + G.T @ lam).max()
    return stationarity, max(0.0, -slack.min()), np.abs(lam * slack).max(), lam.min()


def random_instance(rng, largest=3):
    """A feasible CBF-QP: m in 1..3 inputs, k in 1..3 barrier rows of scales 0.1 to 10^largest
    (the scenarios' |LgB| reach 8e4), through a common feasible point, sometimes tight there; a
    zero row now and then."""
    m, k = rng.integers(1, 4), rng.integers(1, 4)
    u_max = rng.uniform(0.05, 0.2, m)
    point = rng.uniform(-0.8, 0.8, m) * u_max
    terms = []
    for _ in range(k):
        lg = rng.normal(size=m) * 10 ** rng.uniform(-1, largest)
        if rng.random() < 0.05:
            lg = np.zeros(m)
        bound = lg @ point + (0.0 if rng.random() < 0.3 else rng.exponential(0.02) * np.linalg.norm(lg))
        value = rng.uniform(-1, 0.2)
        terms.append(BarrierTerms(value, -bound - ALPHA * value, lg))
    return rng.uniform(-0.3, 0.3, m), terms, u_max


def active_kind(u, terms, u_max):
    G, h = constraints(terms, ALPHA, u_max, u.size)
    active = h - G @ u <= ACTIVE
    barriers = int(active[:len(terms)].sum())
    return barriers, bool(active[len(terms):].any())


def test_qp_equals_clarabel_and_meets_kkt_on_random_instances():
    """(a) the DAQP solution equals a tight Clarabel solve within AGREE, (b) KKT to 1e-9 at it,
    over instances where the box, a barrier, both, and several barriers decide; and equal to
    the optimum found by enumerating active sets (exact, 1e-12). Rows up to 1e3: beyond, the
    tight Clarabel solve itself stops short (AlmostSolved); the next test goes there without it."""
    rng = np.random.default_rng(16)
    kinds = {"free": 0, "box": 0, "barrier": 0, "both": 0, "several barriers": 0}
    worst = 0.0
    for _ in range(600):
        u_nom, terms, u_max = random_instance(rng)
        u = cbf_qp(u_nom, terms, ALPHA, u_max)
        worst = max(worst, np.abs(u - clarabel_qp(u_nom, terms, ALPHA, u_max)).max())
        stationarity, violation, complementarity, least = kkt_residuals(u, u_nom, terms, ALPHA, u_max)
        assert stationarity <= KKT and violation <= KKT and complementarity <= KKT and least >= 0
        np.testing.assert_allclose(u, enumerated_qp(u_nom, terms, ALPHA, u_max), rtol=0, atol=1e-12)
        barriers, box = active_kind(u, terms, u_max)
        kinds["several barriers" if barriers > 1 else
              {(0, False): "free", (0, True): "box", (1, False): "barrier", (1, True): "both"}[(barriers, box)]] += 1
    assert worst <= AGREE, worst
    assert min(kinds.values()) >= 20, kinds


def test_qp_meets_kkt_with_barrier_rows_up_to_1e5():
    """(b) without Clarabel: rows of scales up to 1e5 (the PSM scenario's LgB reach 8e4), KKT to
    1e-9 and the enumerated optimum to 1e-12."""
    rng = np.random.default_rng(61)
    decided = 0
    for _ in range(600):
        u_nom, terms, u_max = random_instance(rng, largest=5)
        u = cbf_qp(u_nom, terms, ALPHA, u_max)
        stationarity, violation, complementarity, least = kkt_residuals(u, u_nom, terms, ALPHA, u_max)
        assert stationarity <= KKT and violation <= KKT and complementarity <= KKT and least >= 0
        np.testing.assert_allclose(u, enumerated_qp(u_nom, terms, ALPHA, u_max), rtol=0, atol=1e-12)
        decided += active_kind(u, terms, u_max)[0] > 0
    assert decided > 300


def enumerated_qp(u_nominal, terms, alpha, u_max):
    """The optimum by enumerating active sets (KKT linear systems, multipliers >= 0, feasible),
    for a handful of constraints: exact and independent of any QP solver."""
    m = u_nominal.size
    G, h = constraints(terms, alpha, u_max, m)
    for r in range(m + 1):
        for active in itertools.combinations(range(len(h)), r):
            Ga = G[list(active)]
            K = np.block([[2 * np.eye(m), Ga.T], [Ga, np.zeros((r, r))]])
            if np.linalg.matrix_rank(K) < m + r:
                continue
            solution = np.linalg.solve(K, np.r_[2 * u_nominal, h[list(active)]])
            u, lam = solution[:m], solution[m:]
            if np.all(lam >= -1e-12) and np.all(G @ u <= h + 1e-12):
                return u
    raise AssertionError("no active set fits")


def scenario_steps(n=300):
    """(u_nominal, sampled terms) at states of the filtered ellipsoid run, as run_linear forms
    them, with nominal inputs that often push into the ellipsoid."""
    from rcm_kin.control.linearization import zero_order_hold
    from rcm_kin.safety.scenarios import CARTESIAN_TAU, ellipsoid_run

    run = ellipsoid_run("qp")
    A, B = np.diag(-1 / CARTESIAN_TAU), np.diag(1 / CARTESIAN_TAU)
    dt = run.time[1] - run.time[0]
    Ad, Bd = zero_order_hold(A, B, dt)
    e = Ellipsoid(np.zeros(3), np.array([0.03, 0.06, 0.03]))
    rng = np.random.default_rng(5)
    def terms(x):
        return [barrier_terms(e, x, (Ad @ x - x) / dt, Bd / dt)]
    return [(rng.uniform(-0.2, 0.2, 3), terms(run.state[k])) for k in rng.choice(len(run.time), n, replace=False)]


def test_prebuilt_qp_on_the_scenarios_steps_is_the_exact_optimum():
    problem = cbf_qp_problem(3, 1, 0.1)
    u_max = np.full(3, 0.1)
    decided = 0
    for u_nom, terms in scenario_steps():
        u = solve_cbf_qp(problem, u_nom, terms, ALPHA)
        np.testing.assert_array_equal(u, cbf_qp(u_nom, terms, ALPHA, 0.1))       # prebuilt = on its own
        np.testing.assert_allclose(u, enumerated_qp(u_nom, terms, ALPHA, u_max), rtol=0, atol=1e-12)
        np.testing.assert_allclose(u, clarabel_qp(u_nom, terms, ALPHA, u_max), rtol=0, atol=AGREE)
        decided += active_kind(u, terms, u_max)[0] > 0
    assert decided > 20                                   # the barrier row decided many of them


@pytest.mark.parametrize("scale", [1e-3, 1.0, 1e3])
def test_a_barrier_the_nominal_input_misses_by_a_hair_is_still_met(scale):
    """The nominal input 1e-8 m beyond a barrier's half-space (at any scale of LgB): the result is
    the projection onto it, met to 1e-12 m (DAQP's default feasibility tolerance, 1e-6, would let
    the violation through)."""
    a = np.array([0.6, 0.8, 0.0]) * scale
    u_nom = np.array([0.03, -0.02, 0.05])
    bound = a @ u_nom - 1e-8 * scale
    u = cbf_qp(u_nom, [BarrierTerms(0.0, -bound, a)], ALPHA, 0.1)
    assert a @ u <= bound + 1e-12 * scale
    np.testing.assert_allclose(u, u_nom - 1e-8 * a / scale, rtol=0, atol=1e-15)


@pytest.mark.parametrize("rows, bounds", [
    ([[1.0, 0.0, 0.0]], [-0.2]),                           # u0 <= -0.2 against |u0| <= 0.1
    ([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]], [-0.05, -0.05]),  # u0 <= -0.05 and u0 >= 0.05
    ([[0.0, 0.0, 0.0]], [-1e-3]),                          # LgB = 0 and B must still decrease
])
def test_infeasible_qp_is_a_clear_error(rows, bounds):
    terms = [BarrierTerms(0.0, -b, np.array(r)) for r, b in zip(rows, bounds)]
    with pytest.raises(RcmKinError, match="the CBF-QP has no solution here \\(infeasible\\)"):
        cbf_qp(np.zeros(3), terms, ALPHA, 0.1)


def test_qp_refuses_data_that_are_not_finite():
    for terms in ([BarrierTerms(np.nan, 0.0, np.ones(3))], [BarrierTerms(0.0, 0.0, np.array([1.0, np.inf, 0.0]))]):
        with pytest.raises(RcmKinError, match="not finite"):
            cbf_qp(np.zeros(3), terms, ALPHA, 0.1)
    with pytest.raises(RcmKinError, match="not finite"):
        cbf_qp(np.array([np.nan, 0.0, 0.0]), [BarrierTerms(-1.0, 0.0, np.ones(3))], ALPHA, 0.1)


@pytest.mark.parametrize("scenario, duration", [("ellipsoid", 2.0), ("slide", 2.0), ("heart", 3.0)])
def test_scenario_decisions_equal_a_clarabel_solve_per_step(monkeypatch, scenario, duration):
    """(d) the scenario run on DAQP against the same run with a tight Clarabel solve per step:
    commands within 1e-8 m, states within 1e-10 m, the same steps filtered, the same safety
    outcome (unsafe samples, and the margin within 1e-10)."""
    from rcm_kin.safety import scenarios
    runs = {"ellipsoid": scenarios.ellipsoid_run, "slide": scenarios.slide_run, "heart": scenarios.heart_run}
    fast = runs[scenario]("qp", duration=duration)
    monkeypatch.setattr(scenarios, "solve_cbf_qp",
                        lambda problem, u, terms, alpha: clarabel_qp(u, terms, alpha, problem.u_max))
    reference = runs[scenario]("qp", duration=duration)
    np.testing.assert_allclose(fast.command, reference.command, rtol=0, atol=1e-8)
    np.testing.assert_allclose(fast.state, reference.state, rtol=0, atol=1e-10)
    np.testing.assert_array_equal(fast.sigma, reference.sigma)
    a, b = fast.summary(), reference.summary()
    assert a["violations"] == b["violations"] == 0
    assert a["min_margin"] == pytest.approx(b["min_margin"], rel=0, abs=1e-10)
    assert np.count_nonzero(fast.sigma) > 100


def test_every_qp_step_of_the_psm_scenario_is_the_exact_optimum(monkeypatch):
    """(d) for the PSM teleoperation (|LgB| up to 8e4, where a tight Clarabel solve stops short
    by ~6e-6 m): every one of its QP steps meets KKT to 1e-9 and is the enumerated optimum to
    1e-12, and the run stays safe."""
    from rcm_kin.safety import scenarios
    solve, steps = scenarios.solve_cbf_qp, []

    def checked(problem, u_nom, terms, alpha):
        u = solve(problem, u_nom, terms, alpha)
        stationarity, violation, complementarity, least = kkt_residuals(u, u_nom, terms, alpha, problem.u_max)
        assert stationarity <= KKT and violation <= KKT and complementarity <= KKT and least >= 0
        np.testing.assert_allclose(u, enumerated_qp(u_nom, terms, alpha, problem.u_max), rtol=0, atol=1e-12)
        steps.append(active_kind(u, terms, problem.u_max)[0])
        return u

    monkeypatch.setattr(scenarios, "solve_cbf_qp", checked)
    summary = scenarios.psm_run("qp").summary()
    assert summary["violations"] == 0 and len(steps) > 8000 and sum(steps) > 1000

"""Control barrier functions and SOS barrier certificates (issue 7)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.safety.barriers import Ellipsoid, MovingPlane, Slab
from rcm_kin.safety.cbf import barrier_terms, blend_weight, cbf_qp, safety_control
from rcm_kin.safety.scenarios import ellipsoid_run, heart_run, psm_run, slide_run
from rcm_kin.safety.sos import Box, check_by_sampling, find_certificate, thesis_program

# Program 1's two certificates as printed in the thesis (eqs. 9.2 and 9.3)
THESIS_P1 = [{(4,): 373.0249, (3,): 151.3339, (2,): 16.8843, (1,): -6.4509e-6, (0,): -0.061301},
             {(4,): 290.559, (3,): 112.4642, (2,): 12.2165, (0,): -0.044304}]


def test_k0_satisfies_the_decrease_condition_on_random_states():
    """L_f B + L_G B k0 = -sqrt(L_f B^2 + kappa^2 |L_G B|^2) <= 0, with the Lie derivatives of
    random barriers and random control-affine fields."""
    rng = np.random.default_rng(0)
    for _ in range(500):
        barrier = [Ellipsoid(rng.normal(size=3) * 0.05, rng.uniform(0.01, 0.1, 3)), Slab(1, -0.1, 0.05),
                   MovingPlane(0, 2)][rng.integers(3)]
        x, f, G = rng.normal(size=3) * 0.1, rng.normal(size=3), rng.normal(size=(3, 3))
        kappa = rng.uniform(0.01, 2.0)
        terms = barrier_terms(barrier, x, f, G)
        bdot = terms.lf + terms.lg @ safety_control(terms, kappa)
        assert bdot <= 0
        assert bdot == pytest.approx(-np.sqrt(terms.lf**2 + kappa**2 * terms.lg @ terms.lg), rel=1e-9, abs=1e-12)


def test_blend_weight_is_the_c1_bump():
    eps = 0.3
    assert blend_weight(-eps, eps) == 0.0 and blend_weight(-1.0, eps) == 0.0
    assert blend_weight(0.0, eps) == 1.0 and blend_weight(0.5, eps) == 1.0
    h = 1e-7
    for edge in (-eps, 0.0):                                   # slopes vanish at both ends
        assert abs(blend_weight(edge + h, eps) - blend_weight(edge - h, eps)) < 1e-12 + 1e-6 * h
    values = [blend_weight(b, eps) for b in np.linspace(-eps, 0, 50)]
    assert np.all(np.diff(values) > 0)
    with pytest.raises(RcmKinError):
        blend_weight(0.0, 0.0)


def test_qp_is_the_nominal_input_when_safe_and_the_projection_otherwise():
    e = Ellipsoid(np.zeros(3), np.array([0.03, 0.06, 0.03]))
    x = np.array([0.05, 0.0, 0.0])
    terms = barrier_terms(e, x, -x / 0.1, np.eye(3) / 0.1)
    away = np.array([0.09, 0.0, 0.0])
    np.testing.assert_allclose(cbf_qp(away, [terms], 20.0, 0.1), away, rtol=0, atol=1e-15)
    towards = np.array([-0.09, 0.0, 0.0])
    u = cbf_qp(towards, [terms], 20.0, 0.1)
    assert terms.lf + terms.lg @ u <= -20.0 * terms.value + 1e-12          # the constraint holds
    # the single half-space projection, by hand (the box is not active here)
    a, b = terms.lg, -terms.lf - 20.0 * terms.value
    np.testing.assert_allclose(u, towards - max(0.0, (a @ towards - b)) / (a @ a) * a, rtol=0, atol=1e-12)


@pytest.mark.parametrize("filter", ["blend", "qp"])
def test_filter_never_lets_the_barrier_go_positive(filter):
    """Random starts outside the ellipsoid, random waypoints through it: no unsafe sample; the
    same runs unfiltered do enter it (the check can fail)."""
    rng = np.random.default_rng(7)
    entered = 0
    for _ in range(6):
        x0 = rng.uniform(-0.09, 0.09, 3)
        while Ellipsoid(np.zeros(3), np.array([0.03, 0.06, 0.03])).value(x0) > -0.8:
            x0 = rng.uniform(-0.09, 0.09, 3)
        waypoints = rng.uniform(-0.08, 0.08, (4, 3)) * [1.0, 1.0, 1.0]
        waypoints[1] = -x0 * 0.9                                        # a straight line through the centre region
        run = ellipsoid_run(filter, x0=x0, waypoints=waypoints, duration=2.0)
        assert run.summary()["violations"] == 0, (x0, waypoints)
        entered += ellipsoid_run("none", x0=x0, waypoints=waypoints, duration=2.0).summary()["violations"] > 0
    assert entered >= 3


@pytest.mark.parametrize("run", [slide_run, heart_run])
def test_slide_and_heart_scenarios_stay_safe(run):
    assert run("none").summary()["violations"] > 0
    for filter in ("blend", "qp"):
        summary = run(filter).summary()
        assert summary["violations"] == 0 and summary["min_margin"] >= 0


def test_psm_teleoperation_stops_short_of_the_forbidden_region():
    assert psm_run("none").summary()["violations"] > 0
    for filter in ("blend", "qp"):
        summary = psm_run(filter).summary()
        assert summary["violations"] == 0 and summary["min_distance_mm"] > 0


def test_printed_thesis_certificates_pass_the_sampling_checker():
    program = thesis_program("1")
    for B in THESIS_P1:
        assert check_by_sampling(B, program).passed
    # and a certificate that is wrong fails it: the constant raised so B > 0 on part of X0
    wrong = dict(THESIS_P1[0])
    wrong[(0,)] += 0.01
    assert not check_by_sampling(wrong, program).passed


@pytest.mark.parametrize("number", ["1", "3", "4"])
def test_certificates_are_found_and_verified(number):
    certificate = find_certificate(thesis_program(number))
    assert certificate.feasible and check_by_sampling(certificate.B, certificate.program).passed


def test_no_certificate_when_the_initial_set_meets_the_unsafe_set():
    program = thesis_program("3", delta=0.0, error_bound=0.009)
    overlapping = type(program)(**{**vars(program), "X0": Box((-0.02,), (0.03,))})
    assert not find_certificate(overlapping).feasible


def test_safety_cli_contracts(capsys):
    assert main(["safety", "simulate", "slide", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"min_margin", "violations"} <= set(out) and out["violations"] == 0
    assert main(["safety", "certify", "1", "--delta", "0.002", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["feasible"] is True and out["certificate"]["variables"] == ["x"]
    assert out["sampling_check"]["passed"] is True
    assert main(["safety", "simulate", "slide", "--trajectory", "x.csv"]) == 2
    assert capsys.readouterr().err.startswith("error:")


def test_every_barrier_is_a_barrier():
    from rcm_kin.safety.barriers import Barrier

    for barrier in (Ellipsoid(np.zeros(3), np.ones(3)), Slab(0, -1.0, 1.0), MovingPlane(0, 1)):
        assert isinstance(barrier, Barrier)


def test_scenario_decisions_equal_a_qp_built_every_step(monkeypatch):
    """run_linear with its structure built once against the same run with a QP built per step."""
    from rcm_kin.safety import scenarios
    once = scenarios.ellipsoid_run("qp", duration=1.0)
    monkeypatch.setattr(scenarios, "solve_cbf_qp",
                        lambda problem, u, terms, alpha: cbf_qp(u, terms, alpha, problem.u_max))
    every = scenarios.ellipsoid_run("qp", duration=1.0)
    np.testing.assert_array_equal(once.command, every.command)
    np.testing.assert_array_equal(once.state, every.state)
    assert np.count_nonzero(once.sigma) > 10


def test_prebuilt_qp_refuses_other_shapes():
    from rcm_kin.safety.cbf import cbf_qp_problem, solve_cbf_qp
    with pytest.raises(RcmKinError, match="built for 3 inputs and 1 barriers"):
        solve_cbf_qp(cbf_qp_problem(3, 1, 0.1), np.zeros(2), [], 20.0)


@pytest.mark.parametrize("n", [1, 2, 3])
def test_poly_eval_with_its_cache_is_the_plain_sum_bit_for_bit(n):
    """poly_eval takes each power once on the whole grid (kept in its cache): the same floats as
    sum(c * prod(x ** e)) term by term, whatever the exponents and the values."""
    from rcm_kin.safety.sos import poly_eval

    rng = np.random.default_rng(n)
    grids = [rng.normal(size=(4001, n)) * 10.0 ** rng.uniform(-3, 3, size=(4001, n)), rng.normal(size=(3, n))]
    grids += [b.grid(101) for b in (thesis_program("2").X, thesis_program("4").Xu)] if n == 2 else []
    polys = [{tuple(int(v) for v in rng.integers(0, 7, size=n)): float(rng.normal()) for _ in range(12)}
             for _ in range(3)]
    for x in grids:
        cache: dict = {}
        for p in polys:
            plain = sum(float(c) * np.prod(x ** np.array(e), axis=1) for e, c in p.items())
            assert poly_eval(p, x, cache).tobytes() == plain.tobytes()
            assert poly_eval(p, x).tobytes() == plain.tobytes()

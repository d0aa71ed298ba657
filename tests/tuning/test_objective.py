"""The objective (:mod:`rcm_kin.tuning.objective`) on outcomes written by hand, and one controller's
outcomes on the drawn plants against the CLI's own experiment runner."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rcm_kin.simulation.controllers import ThesisController
from rcm_kin.simulation.experiments import run_experiment
from rcm_kin.simulation.loop import tracking_metrics
from rcm_kin.tuning.objective import (
    PENALTY,
    RADIUS_LIMIT,
    SATURATION_SLACK_S,
    Outcomes,
    evaluate,
    ratios,
    saturation_excess,
    score,
    statistics,
)

EXPERIMENTS = ("sine", "target")
N = 7                                  # draws


def outcomes(seed: int, scale: float = 1.0) -> Outcomes:
    rng = np.random.default_rng(seed)
    mx = rng.uniform(0.5, 3.0, (N, 2, 2))
    mean = mx * rng.uniform(0.2, 0.6, (N, 2, 2))
    saturation = np.random.default_rng(100).choice([0.0, 0.01, 0.2], (N, 2, 2))     # the same in every outcome
    return Outcomes(EXPERIMENTS, scale * mx, scale * mean, saturation, np.zeros((N, 2), dtype=bool))


def with_unstable(o: Outcomes, draw: int, experiment: int) -> Outcomes:
    mx, mean, unstable = o.max_error_deg.copy(), o.mean_error_deg.copy(), o.unstable.copy()
    mx[draw, experiment], mean[draw, experiment], unstable[draw, experiment] = np.nan, np.nan, True
    return replace(o, max_error_deg=mx, mean_error_deg=mean, unstable=unstable)


def by_hand(o: Outcomes) -> np.ndarray:
    """(experiment, axis, [p90 max, median mean, worst max]) over the stable runs, one slice at a time."""
    out = np.empty((len(o.experiments), 2, 3))
    for k in range(len(o.experiments)):
        stable = ~o.unstable[:, k]
        for a in range(2):
            mx, mean = o.max_error_deg[stable, k, a], o.mean_error_deg[stable, k, a]
            out[k, a] = np.percentile(mx, 90), np.median(mean), mx.max()
    return out


@pytest.fixture(scope="module")
def baseline() -> Outcomes:
    return outcomes(0)


def test_the_statistics(baseline):
    np.testing.assert_allclose(statistics(baseline), by_hand(baseline), rtol=1e-15)
    design = outcomes(1)
    np.testing.assert_allclose(ratios(design, baseline), by_hand(design) / by_hand(baseline), rtol=1e-14)


def test_the_baselines_unstable_runs_are_left_out(baseline):
    shaky = with_unstable(with_unstable(baseline, 2, 0), 5, 1)
    stats = statistics(shaky)
    assert np.all(np.isfinite(stats))
    np.testing.assert_allclose(stats, by_hand(shaky), rtol=1e-15)
    assert not np.allclose(stats, statistics(baseline))      # the runs left out mattered
    value = score(baseline, shaky, 0.5)
    r = by_hand(baseline) / by_hand(shaky)
    assert value == pytest.approx(r.mean() + r.max(), rel=1e-14)
    assert value < PENALTY


def test_the_same_outcomes_score_two_and_half_the_errors_one(baseline):
    assert score(baseline, baseline, 0.5) == pytest.approx(2.0, rel=1e-15)
    assert score(outcomes(0, scale=0.5), baseline, 0.5) == pytest.approx(1.0, rel=1e-15)
    assert score(outcomes(0, scale=2.0), baseline, 0.5) == pytest.approx(4.0, rel=1e-15)


def test_the_score_is_the_mean_plus_the_worst_ratio(baseline):
    design = outcomes(3)
    r = by_hand(design) / by_hand(baseline)
    assert r.size == 12 and r.max() > r.mean()
    assert score(design, baseline, 0.5) == pytest.approx(r.mean() + r.max(), rel=1e-14)
    better = replace(design, max_error_deg=design.max_error_deg * 0.9)
    assert score(better, baseline, 0.5) < score(design, baseline, 0.5)


def test_an_unstable_run_costs_a_penalty(baseline):
    design = outcomes(0, scale=0.1)                  # far better on every stable run
    one = with_unstable(design, 3, 1)
    two = with_unstable(one, 4, 0)
    assert score(one, baseline, 0.5) >= PENALTY
    assert score(two, baseline, 0.5) > score(one, baseline, 0.5)     # more unstable runs: worse


def test_a_frozen_loop_at_the_radius_limit_costs_a_penalty(baseline):
    design = outcomes(1)
    fine = score(design, baseline, 0.5)
    assert score(design, baseline, np.nextafter(RADIUS_LIMIT, 0)) == fine
    assert score(design, baseline, RADIUS_LIMIT) - fine >= PENALTY
    assert score(design, baseline, 1.2) > score(design, baseline, 1.01) > score(design, baseline, RADIUS_LIMIT)


def test_saturation_beyond_the_baselines_costs_a_penalty(baseline):
    def more(extra: dict) -> Outcomes:
        s = baseline.saturation_s.copy()
        for (i, k, a), seconds in extra.items():
            s[i, k, a] += seconds
        return replace(baseline, saturation_s=s)

    assert saturation_excess(baseline, baseline) == 0.0
    within = more({(0, 0, 0): SATURATION_SLACK_S / 2})
    assert saturation_excess(within, baseline) == 0.0
    assert score(within, baseline, 0.5) == score(baseline, baseline, 0.5)
    # summed over draws per experiment and axis; less saturation elsewhere does not pay for it
    beyond = more({(0, 0, 0): 0.05, (3, 0, 0): 0.05, (1, 1, 1): SATURATION_SLACK_S / 2})
    assert saturation_excess(beyond, baseline) == pytest.approx(0.1 - SATURATION_SLACK_S, rel=1e-12)
    s = beyond.saturation_s.copy()
    s[:, 1, 0] = 0.0                                  # none at all in another experiment and axis
    traded = replace(beyond, saturation_s=s)
    assert baseline.saturation_s[:, 1, 0].sum() > 0.1
    assert saturation_excess(traded, baseline) == pytest.approx(0.1 - SATURATION_SLACK_S, rel=1e-12)
    assert score(beyond, baseline, 0.5) - score(baseline, baseline, 0.5) >= PENALTY


def test_the_summary(baseline):
    shaky = with_unstable(baseline, 2, 0)
    summary = shaky.summary()
    assert set(summary) == {f"{e}.{a}" for e in EXPERIMENTS for a in ("roll", "pitch")}
    pitch = summary["sine.pitch"]
    stable = np.delete(shaky.max_error_deg[:, 0, 1], 2)
    assert pitch["median_max_deg"] == pytest.approx(np.median(stable), rel=1e-15)
    assert pitch["p90_max_deg"] == pytest.approx(np.percentile(stable, 90), rel=1e-15)
    assert pitch["worst_max_deg"] == stable.max()
    assert pitch["worst_mean_deg"] == np.delete(shaky.mean_error_deg[:, 0, 1], 2).max()
    assert pitch["saturation_s"] == pytest.approx(shaky.saturation_s[:, 0, 1].sum(), rel=1e-15)
    assert pitch["unstable_runs"] == 1 and summary["target.roll"]["unstable_runs"] == 0


# -- a controller on the drawn plants ----------------------------------------------------------


@pytest.fixture(scope="module")
def thesis(nominal_draws):
    return evaluate(ThesisController(), nominal_draws)


def test_a_controller_on_the_draws(thesis, nominal_draws):
    assert thesis.experiments == ("sine",)
    assert thesis.max_error_deg.shape == thesis.mean_error_deg.shape == thesis.saturation_s.shape == (2, 1, 2)
    assert not thesis.unstable.any()
    assert np.all(np.isfinite(thesis.max_error_deg)) and np.all(np.isfinite(thesis.mean_error_deg))
    assert np.all(thesis.mean_error_deg < thesis.max_error_deg) and np.all(thesis.saturation_s >= 0)
    assert not np.array_equal(thesis.max_error_deg[0], thesis.max_error_deg[1])     # two plants, two outcomes


def test_the_nominal_draw_is_the_clis_experiment(thesis):
    """The shipped set, the thesis law, the sinusoid: as ``rcm-kin simulate`` runs it."""
    metrics = tracking_metrics(run_experiment("sine", "thesis"), 1.0)
    for a, axis in enumerate(("roll", "pitch")):
        assert thesis.max_error_deg[0, 0, a] == pytest.approx(metrics[axis].max_error_deg, rel=1e-12, abs=1e-12)
        assert thesis.mean_error_deg[0, 0, a] == pytest.approx(metrics[axis].mean_error_deg, rel=1e-12, abs=1e-12)
        assert thesis.saturation_s[0, 0, a] == pytest.approx(metrics[axis].saturation_s, rel=1e-12, abs=1e-12)

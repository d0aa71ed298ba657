"""Robustness draws from a drive file's own uncertainty: the roll's drive train is one of the file's
leave-one-log-out fold sets or its own set (the sets the prediction bands use), its undetermined
parameters uniform over their ranges; without fold sets, the draws are the per-parameter spreads
exactly as before."""

from __future__ import annotations

import json
from dataclasses import fields, replace

import numpy as np
import pytest
from scipy import stats

from rcm_kin import RcmKinError
from rcm_kin.cli import main
from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.dynamics.drive import load_drive_parameters, write_parameters
from rcm_kin.dynamics.drive_uncertainty import DriveUncertainty, FoldSet
from rcm_kin.errors import RcmKinWarning
from rcm_kin.robustness.sampling import (
    CHOICE,
    DEFAULT_RELATIVE_SPREAD,
    draw,
    drive_train_sources,
    sample_seeds,
    uncertain_parameters,
    with_values,
)
from rcm_kin.robustness.task import Study, run_batch

SEED = 11
RANGES = {"presliding_force": (0.9, 5.0),         # under a decade: uniform
          "stribeck_velocity": (1e-3, 1e-1)}      # two decades: log-uniform


@pytest.fixture(scope="module")
def shipped():
    return load_drive_parameters()


def fold_sets(own: AxisFriction) -> tuple[FoldSet, ...]:
    """Three sets as far apart as leave-one-log-out folds are, each unlike the own set."""
    return tuple(FoldSet(f"log_{k}.csv", replace(own, cable_damping=own.cable_damping * (0.7 + 0.2 * k),
                                                  coulomb=own.coulomb * (1.3 - 0.25 * k),
                                                  presliding_force=own.presliding_force * (0.8 + 0.3 * k)))
                 for k in range(3))


@pytest.fixture(scope="module")
def folded(shipped, tmp_path_factory):
    """The shipped set with three roll fold sets, written and read back as a drive file."""
    u = DriveUncertainty(folds={"roll": fold_sets(shipped.drive_train["roll"])})
    return load_drive_parameters(write_parameters(replace(shipped, uncertainty=u),
                                                  tmp_path_factory.mktemp("folds") / "folded.toml"))


FACTORS = {"cable_damping": lambda k: 0.7 + 0.2 * k, "coulomb": lambda k: 1.3 - 0.25 * k,
           "presliding_force": lambda k: 0.8 + 0.3 * k}


def candidates(params) -> list[AxisFriction]:
    """The sets a sample may take: each fold set jackknife-inflated by hand (its factor's logarithm
    about their mean, times sqrt(3 - 1), on the own value), and the own set."""
    own = params.drive_train["roll"]
    out = []
    for k in range(3):
        values = {}
        for name, factor in FACTORS.items():
            logs = np.log([factor(j) for j in range(3)])
            values[name] = getattr(own, name) * float(np.exp(np.sqrt(2.0) * (logs[k] - logs.mean())))
        out.append(replace(own, **values))
    return out + [own]


def test_each_sample_takes_one_of_the_sets_whole(folded):
    uncertain = uncertain_parameters(folded)
    names = [u.name for u in uncertain]
    assert "drive_train.roll" in names
    assert not [n for n in names if n.startswith("drive_train.roll.")]     # no per-parameter spreads on top
    assert {"roll.volts_per_pwm", "pitch.coulomb", "gravity_offsets.roll_link[1]"} <= set(names)   # kept
    sets = candidates(folded)
    seen = []
    for seed in sample_seeds(SEED, 40):
        drawn = with_values(folded, uncertain, draw(uncertain, seed))
        roll = drawn.drive_train["roll"]
        matches = [k for k, s in enumerate(sets)
                   if all(np.isclose(getattr(roll, n), getattr(s, n), rtol=1e-12, atol=0) for n in roll.as_dict())]
        assert len(matches) == 1                                            # exactly one set
        seen.append(matches[0])
        # the smooth model follows the set as identify derives it (extra inertia, viscous, sliding force)
        assert (drawn["roll"].extra_inertia, drawn["roll"].viscous, drawn["roll"].coulomb) == (
            roll.extra_inertia, roll.viscous + roll.motor_viscous,
            roll.coulomb + roll.motor_coulomb + roll.presliding_force)
    assert sorted(set(seen)) == [0, 1, 2, 3]                                # every fold set and the own set
    assert drive_train_sources(uncertain) == {"roll": "fold sets (3, jackknife-inflated) and the own set"}
    nominal = with_values(folded, uncertain, [u.nominal for u in uncertain])
    assert nominal.drive_train == folded.drive_train                        # the nominal choice is the own set


def test_a_sample_is_the_same_whichever_batch_computes_it(folded):
    study = Study(folded, uncertain_parameters(folded), ("p",), "sine", 0.25, survey_points=2)
    seeds = sample_seeds(SEED, 40)
    alone, = run_batch(study, [(5, sample_seeds(SEED, 6)[5])])             # spawn(N)[i] does not depend on N
    _, among = run_batch(study, [(2, seeds[2]), (5, seeds[5])])
    for a, b in ((alone, among), (among, alone)):
        for f in fields(a):
            assert np.array_equal(getattr(a, f.name), getattr(b, f.name), equal_nan=True), f.name
    assert np.array_equal(alone.values, draw(study.uncertain, seeds[5]))


def test_ranges_are_drawn_uniformly_in_the_chosen_set(folded):
    params = replace(folded, uncertainty=replace(folded.uncertainty, ranges={"roll": RANGES}))
    uncertain = uncertain_parameters(params)
    by_name = {u.name: u for u in uncertain}
    assert (by_name["drive_train.roll.presliding_force"].distribution,
            by_name["drive_train.roll.stribeck_velocity"].distribution) == ("uniform", "log-uniform")
    sets = candidates(params)
    drawn = {name: [] for name in RANGES}
    for seed in sample_seeds(SEED, 400):
        roll = with_values(params, uncertain, draw(uncertain, seed)).drive_train["roll"]
        for name, (lo, hi) in RANGES.items():
            assert lo <= getattr(roll, name) <= hi
            drawn[name].append(getattr(roll, name))
        assert any(all(np.isclose(getattr(replace(s, **{n: getattr(roll, n) for n in RANGES}), n), getattr(roll, n),
                              rtol=1e-12, atol=0) for n in roll.as_dict()) for s in sets)   # the rest one set's
    lo, hi = RANGES["presliding_force"]
    assert stats.kstest(drawn["presliding_force"], stats.uniform(lo, hi - lo).cdf).pvalue > 1e-3
    lo, hi = np.log(RANGES["stribeck_velocity"])
    assert stats.kstest(np.log(drawn["stribeck_velocity"]), stats.uniform(lo, hi - lo).cdf).pvalue > 1e-3
    assert drive_train_sources(uncertain)["roll"].endswith("presliding_force, stribeck_velocity")


def old_draw(uncertain, seed) -> np.ndarray:
    """``draw`` as it was before fold sets (frozen here): one standard normal deviate per parameter
    in order; log-normal about the nominal where positive, else normal."""
    z = np.random.default_rng(seed).standard_normal(len(uncertain))
    nominal = np.array([u.nominal for u in uncertain])
    sigma = np.array([u.sigma for u in uncertain])
    positive = np.array([u.positive for u in uncertain], dtype=bool)
    out = nominal + sigma * z
    log_sd = sigma[positive] / nominal[positive]
    out[positive] = nominal[positive] * np.exp(log_sd * z[positive])
    return out


def test_without_fold_sets_the_draws_are_as_before(shipped):
    plain = replace(shipped, uncertainty=DriveUncertainty())
    ranged = replace(shipped, uncertainty=DriveUncertainty(ranges={"roll": RANGES}))   # ranges alone: unused
    uncertain = uncertain_parameters(plain)
    assert uncertain == uncertain_parameters(ranged)
    assert all(u.kind != CHOICE and np.isfinite(u.sigma) for u in uncertain)
    roll = shipped.drive_train["roll"]
    assert {u.name: u.sigma for u in uncertain}["drive_train.roll.coulomb"] == \
        DEFAULT_RELATIVE_SPREAD["drive_train"] * roll.coulomb
    for seed in sample_seeds(SEED, 50):
        assert draw(uncertain, seed).tobytes() == old_draw(uncertain, seed).tobytes()     # bit for bit
    assert drive_train_sources(uncertain) == {"roll": "spreads (default drive_train 0.25)"}


def test_standard_errors_of_a_folded_joint_are_not_used(folded):
    with pytest.warns(RcmKinWarning, match="drive_train.roll.viscous are not used"):
        uncertain = uncertain_parameters(folded, {"drive_train.roll.viscous": (1.3, "jackknife")})
    assert "drive_train.roll.viscous" not in {u.name for u in uncertain}
    stray = replace(folded, drive_train={}, uncertainty=folded.uncertainty)
    with pytest.raises(RcmKinError, match="fold sets of the roll but no \\[drive_train.roll\\]"):
        uncertain_parameters(stray)


def test_the_cli_says_where_the_drive_trains_came_from(folded, capsys):
    assert main(["robustness", "psm", "--controller", "p", "--experiment", "sine", "--samples", "2",
                 "--duration", "0.25", "--workers", "1", "--params", folded.source, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["drive_train_source"] == {"roll": "fold sets (3, jackknife-inflated) and the own set"}
    choice = out["uncertainty"]["drive_train.roll"]
    assert (choice["distribution"], choice["sigma"], choice["range"], choice["nominal"]) == (
        "one of the sets", None, [0.0, 3.0], 3.0)


def test_the_drawn_sets_spread_as_the_jackknife_errors(folded):
    """Over the inflated fold sets, each parameter's logarithm spreads (population standard deviation)
    as the jackknife standard error of the folds, sqrt((n - 1) / n sum (x_k - mean)^2), computed here
    from the fold sets as written; the raw folds spread sqrt(n - 1) times less."""
    sets = candidates(folded)[:3]
    for name in FACTORS:
        folds = np.log([getattr(f.friction, name) for f in folded.uncertainty.folds["roll"]])
        jackknife = np.sqrt((folds.size - 1) / folds.size * np.sum((folds - folds.mean()) ** 2))
        drawn = np.log([getattr(s, name) for s in sets])
        assert np.std(drawn) == pytest.approx(jackknife, rel=1e-9)
        assert np.std(folds) == pytest.approx(jackknife / np.sqrt(2.0), rel=1e-9)


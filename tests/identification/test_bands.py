"""Prediction bands (identification.bands): calibrated on synthetic runs of known spread, ordered,
refusing what they cannot do, and ``rcm-kin predict --band``'s contract."""

from __future__ import annotations

import csv
import json
from dataclasses import replace
from math import radians

import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.dynamics.drive import load_drive_parameters, write_parameters
from rcm_kin.dynamics.drive_uncertainty import DriveUncertainty, FoldSet
from rcm_kin.dynamics.stick_slip import AxisFriction, AxisPlant
from rcm_kin.errors import RcmKinError
from rcm_kin.identification.bands import (
    band_of,
    best_preload,
    best_preloads,
    check_level,
    ensemble,
    prediction_band,
    range_values,
    simulate_members,
    widened,
    widening_score,
)
from rcm_kin.identification.drive_train import AxisLog, predict_log
from rcm_kin.identification.file_bands import drive_file_band

GAIN = -0.05       # N m per PWM count (hardware sign: negative PWM raises the angle)
MASS = 0.4         # kg m^2


def pendulum():
    """A pendulum-like axis: gravity 3 sin q N m, constant inertia, a little back-EMF."""
    grid = np.linspace(-1.0, 1.0, 201)
    return AxisPlant(GAIN, 0.6, 3e-3, grid, 3.0 * np.sin(grid), np.full(grid.size, MASS))


def step(start=0.1, size=-20.0, samples=1000, pose_pitch=0.0) -> AxisLog:
    """A step from rest at ``start`` rad under the PWM holding it, by ``size`` counts, 1 ms samples
    (its measured angle a placeholder: the tests compare simulated runs)."""
    hold = 3.0 * np.sin(start) / GAIN
    pwm = np.r_[hold, np.full(samples - 1, hold + size)]
    return AxisLog("synthetic", "roll", 1e-3, pwm, np.full(samples, start), np.array([start, pose_pitch, 0.08]))


def draw(rng, count: int) -> list[tuple[AxisFriction, float]]:
    """``count`` members of a known distribution: viscous, Coulomb, the presliding spring's stiffness
    and slip force (log-uniform) and its preload, all independent."""
    return [(AxisFriction(viscous=rng.uniform(1.0, 3.0), coulomb=rng.uniform(0.02, 0.12),
                          presliding_stiffness=float(np.exp(rng.uniform(np.log(10.0), np.log(40.0)))),
                          presliding_slope=2.0, presliding_force=float(np.exp(rng.uniform(np.log(0.3), np.log(1.5))))),
             float(rng.uniform(-1.0, 1.0))) for _ in range(count)]


def test_a_90_percent_band_covers_90_percent_of_fresh_runs_of_the_same_distribution():
    """Built from 256 members drawn from a known parameter and preload distribution, the 90 % band
    holds 85-95 % of 400 fresh runs from the same distribution, pointwise on average (from the first
    sample after the step: before it every run is at the same rest). A band at the wrong quantiles
    (e.g. the 25/75 % ones, or the level read as a tail) misses this by far."""
    rng = np.random.default_rng(7)
    plant, log = pendulum(), step()
    band = band_of(simulate_members(draw(rng, 256), plant, log), log, 0.9)
    fresh = simulate_members(draw(rng, 400), plant, log)
    inside = (fresh >= band.lower) & (fresh <= band.upper)
    assert np.ptp(fresh[:, -1]) > radians(1.0)          # the distribution really spreads the runs
    assert 0.85 <= inside[:, 1:].mean() <= 0.95
    half = band_of(simulate_members(draw(rng, 128), plant, log), log, 0.5)
    assert 0.4 <= ((fresh >= half.lower) & (fresh <= half.upper))[:, 1:].mean() <= 0.6


def test_the_band_is_ordered_and_holds_every_member_between_its_extreme_quantiles():
    plant, log = pendulum(), step()
    sets = [AxisFriction(viscous=v, coulomb=0.05, presliding_stiffness=20.0, presliding_force=0.8) for v in (1.5, 2.5)]
    band = prediction_band(sets, plant, log, 0.8, ranges={"presliding_force": (0.4, 1.2)}, preloads=5)
    assert np.all(band.lower <= band.median) and np.all(band.median <= band.upper)
    assert band.members == 2 * 3 * 5
    assert band.sources == {"fold_sets": 2, "own_set": 0, "presliding_force": 3, "preload": 5}
    members = ensemble(sets, {"presliding_force": (0.4, 1.2)}, 5).members
    runs = np.array([predict_log(f, plant, log, preload=p) for f, p in members])
    assert np.all(band.lower >= runs.min(axis=0) - 1e-12) and np.all(band.upper <= runs.max(axis=0) + 1e-12)
    np.testing.assert_allclose(band.median, np.median(runs, axis=0), atol=1e-12)


def test_undetermined_ranges_are_taken_at_their_ends_and_middle_log_spaced_across_decades():
    np.testing.assert_allclose(range_values(1.0, 5.0), [1.0, 3.0, 5.0])
    np.testing.assert_allclose(range_values(0.1, 10.0), [0.1, 1.0, 10.0])
    np.testing.assert_allclose(range_values(-1.0, 1.0), [-1.0, 0.0, 1.0])
    members = ensemble([AxisFriction(), AxisFriction(viscous=1.0)], {"presliding_force": (1.0, 5.0)}, 9, folds=1)
    assert len(members.members) == 2 * 3 * 9
    assert sorted({p for _, p in members.members}) == pytest.approx(np.linspace(-1, 1, 9))
    assert members.sources == {"fold_sets": 1, "own_set": 1, "presliding_force": 3, "preload": 9}


@pytest.mark.parametrize("level", [0.0, 1.0, -0.5, 1.5, float("nan")])
def test_a_level_outside_0_1_is_refused(level):
    with pytest.raises(RcmKinError, match="strictly between 0 and 1"):
        check_level(level)


def test_the_scores_come_from_the_measured_angle():
    """Coverage, final angle and width at the end against a measured angle placed by hand."""
    plant, log = pendulum(), step(samples=400)
    band = prediction_band([AxisFriction(viscous=2.0, presliding_stiffness=20.0, presliding_force=0.8)], plant, log,
                           0.9, preloads=5)
    rows = np.vstack([band.lower, band.upper])          # two rows: a band at any level lies between them
    middle = replace(log, measured=0.5 * (band.lower + band.upper))
    shifted = band_of(rows, middle, 0.99)
    assert shifted.coverage == 1.0 and shifted.final_inside
    outside = replace(log, measured=np.r_[middle.measured[:200], band.upper[200:] + 0.1])
    missed = band_of(rows, outside, 0.99)
    assert missed.coverage == pytest.approx(200 / 400, abs=1e-9) and not missed.final_inside   # from sample 0
    travel = outside.measured[-1] - outside.measured[0]
    assert missed.end_width_over_travel == pytest.approx(abs(missed.upper[-1] - missed.lower[-1]) / abs(travel))


def test_a_record_outside_the_calibrated_poses_is_extrapolated():
    plant = pendulum()
    sets = [AxisFriction(viscous=2.0, presliding_stiffness=20.0, presliding_force=0.8)]
    hull = {"roll": (-1.0, 1.0), "pitch": (-0.2, 0.2)}
    inside = prediction_band(sets, plant, step(pose_pitch=0.1), 0.9, preloads=3, hull=hull)
    assert not inside.extrapolated and inside.note == ""
    outside = prediction_band(sets, plant, step(pose_pitch=0.25), 0.9, preloads=3, hull=hull)
    assert outside.extrapolated and "pitch 14.32 deg outside" in outside.note and "not widened" in outside.note
    assert outside.as_dict()["extrapolated"] is True
    unchecked = prediction_band(sets, plant, step(), 0.9, preloads=3)
    assert not unchecked.extrapolated and "not checked" in unchecked.note


def test_a_file_without_fold_sets_names_the_command_that_writes_them():
    params = replace(load_drive_parameters(), uncertainty=DriveUncertainty())
    with pytest.raises(RcmKinError, match=r"^no leave-one-log-out parameter sets in .*psm_drive.toml: run rcm-kin "
                                          r"identify --cv$"):
        drive_file_band(params, step(), pendulum())


def fold_file(tmp_path):
    """The shipped parameters with three fold sets around the shipped roll drive train, a range for the
    slip force and a hull."""
    params = load_drive_parameters()
    own = params.drive_train["roll"]
    folds = tuple(FoldSet(f"log{k}.csv", replace(own, viscous=own.viscous * s, extra_inertia=own.extra_inertia * s))
                  for k, s in enumerate((0.8, 1.0, 1.25)))
    u = DriveUncertainty(folds={"roll": folds}, ranges={"roll": {"presliding_force": (1.0, 2.0)}},
                         hull={"roll": (radians(-15.1), radians(19.9)), "pitch": (radians(-16.6), radians(14.9))})
    return write_parameters(replace(params, uncertainty=u), tmp_path / "folds.toml")


def step_log(path):
    """A synthetic open-loop roll step log (the telemetry CSV format)."""
    t = np.arange(1600) * 0.0025
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["__time", "/t/roll/position", "/t/roll/velocity", "/t/pitch/position", "/t/pitch/velocity"])
        for ti in t:
            w.writerow([ti, 4.0 * (1 - np.exp(-(ti - 1.0) / 0.2)) if ti >= 1.0 else 0.0, -30.0 if ti >= 1.0 else -5.0,
                        0, 0])
    return path


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_predict_band_contract(tmp_path, capsys):
    log, params = step_log(tmp_path / "step.csv"), fold_file(tmp_path)
    code, out, err = run(capsys, "predict", "psm", log, "--joint", "roll", "--params", params, "--band", "0.9",
                         "--plot", tmp_path / "band.png", "--json")
    assert code == 0, err
    result = json.loads(out)
    assert {"fit_percent", "final_error_deg", "time", "measured", "predicted", "band", "written"} <= set(result)
    band = result["band"]
    assert {"level", "lower", "upper", "median", "coverage", "final_inside", "end_width_over_travel", "members",
            "sources", "extrapolated"} <= set(band)
    assert band["level"] == 0.9 and band["members"] == 4 * 3 * 9
    assert band["sources"] == {"fold_sets": 3, "own_set": 1, "presliding_force": 3, "preload": 9}
    assert band["undetermined"] == {"presliding_force": [1.0, 1.5, 2.0]}
    assert len(band["lower"]) == len(band["upper"]) == len(band["median"]) == len(result["time"])
    assert np.all(np.array(band["lower"]) <= np.array(band["upper"]))
    assert (tmp_path / "band.png").stat().st_size > 0
    code, out, err = run(capsys, "predict", "psm", log, "--joint", "roll", "--params", params, "--band", "0.9")
    assert code == 0 and "90% band of 108 members" in out and "width at the end" in out and "inside" in out


@pytest.mark.parametrize("level", ["0", "1", "nan", "x", "-0.2"])
def test_predict_band_refuses_a_level_outside_0_1_in_one_line(tmp_path, capsys, level):
    code, out, err = run(capsys, "predict", "psm", step_log(tmp_path / "step.csv"), "--joint", "roll", "--band", level)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("error: --band: needs a level strictly between 0 and 1")


def test_predict_band_without_folds_is_one_line(tmp_path, capsys):
    bare = write_parameters(replace(load_drive_parameters(), uncertainty=DriveUncertainty()), tmp_path / "bare.toml")
    code, out, err = run(capsys, "predict", "psm", step_log(tmp_path / "step.csv"), "--joint", "roll", "--band", "0.9",
                         "--params", bare)
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("error: no leave-one-log-out parameter sets in ") and "run rcm-kin identify --cv" in err


def test_band_on_a_shared_roll_step_smoke(shared_data, tmp_path):
    """On a measured roll step with a fold file around the shipped set (not fitted: a smoke test; the
    numbers the issue asks for are judged on the re-identified file)."""
    from rcm_kin.identification.file_bands import predict_band

    path = shared_data / "psm-sysid" / "roll-step" / "roll_step_response_roll_-15_pitch_0.csv"
    log, predicted, check, band = predict_band(load_drive_parameters(fold_file(tmp_path)), path, "roll", 0.9)
    assert band.lower.shape == predicted.shape == log.measured.shape
    assert np.all(band.lower <= band.median) and np.all(band.median <= band.upper)
    assert 0.0 <= band.coverage <= 1.0 and band.start > 0 and np.isfinite(band.median_fit)
    assert not band.extrapolated


@pytest.mark.parametrize("preload", [-0.2, 0.0, 0.35, 0.6])
def test_a_logs_best_preload_is_the_one_it_was_recorded_with(preload):
    """A log simulated from a rest carrying a known preload, its step (1 N m) loading the spring past
    its slip force from every one of these preloads (below about -0.25 it would not slip, and the
    preload would not show: a spring that only deflects moves the same from any preload, its force
    and the gravity shift cancelling): :func:`best_preload` finds it (to the search tolerance's
    order), and :func:`best_preloads` lists one per step log, leaving out a log outside the
    calibrated poses."""
    plant = pendulum()
    truth = AxisFriction(viscous=2.0, coulomb=0.05, presliding_stiffness=20.0, presliding_force=0.8)
    log = step(size=-20.0, samples=1500)
    log = replace(log, measured=predict_log(truth, plant, log, preload=preload))
    assert best_preload(truth, plant, log) == pytest.approx(preload, abs=5e-3)
    far = replace(step(size=-20.0, samples=1500, pose_pitch=0.3), measured=log.measured)
    hull = {"pitch": (-0.2, 0.2)}
    assert best_preloads(truth, [plant, plant], [log, far], hull) == pytest.approx((preload,), abs=5e-3)
    assert best_preloads(truth, [plant], [far], hull) == ()


def test_an_ensemble_takes_the_preloads_it_is_given_and_refuses_others():
    sets = [AxisFriction(), AxisFriction(viscous=1.0)]
    members = ensemble(sets, None, preload_values=(-0.2, 0.1, 0.3))
    assert [p for _, p in members.members] == pytest.approx([-0.2, 0.1, 0.3] * 2)
    assert members.sources["preload"] == 3
    for bad in ((0.2, 1.5), (float("nan"),)):
        with pytest.raises(RcmKinError, match=r"fractions of the slip force in \[-1, 1\]"):
            ensemble(sets, None, preload_values=bad)
    none_known = ensemble(sets, None, 5, preload_values=())           # no log showed one: evenly over [-1, 1]
    assert sorted({p for _, p in none_known.members}) == pytest.approx(np.linspace(-1, 1, 5))


def test_a_calibrated_band_scores_only_the_other_logs_under_their_inner_sets(monkeypatch):
    """``calibrated_bands`` on three logs: band k is built from fold k and its inner sets on log k,
    then each other log j is scored under inner[k][j] alone (never under fold k or on log k), and
    the band is widened by those scores; a log outside the calibrated poses is neither scored nor
    widened, and one without any score left is returned as built."""
    import rcm_kin.identification.bands as bands

    plant = pendulum()
    truth = AxisFriction(viscous=2.0, coulomb=0.05, presliding_stiffness=20.0, presliding_force=0.8)
    steps = ((step(size=-20.0, samples=600), 0.2), (step(0.2, -18.0, 600), -0.3), (step(-0.1, 22.0, 600), 0.0))
    logs = [replace(g, name=f"log{k}", measured=predict_log(truth, plant, g, preload=p) + 0.002 * k)
            for k, (g, p) in enumerate(steps)]
    folds = [replace(truth, viscous=1.9 + 0.1 * k) for k in range(3)]
    inner = [[replace(truth, viscous=1.5 + k + 0.1 * j) for j in range(3) if j != k] for k in range(3)]
    calls, real = [], bands.prediction_band

    def recording(sets, plant, log, *args, **kwargs):
        calls.append(([s.viscous for s in sets], log.name))
        return real(sets, plant, log, *args, **kwargs)

    monkeypatch.setattr(bands, "prediction_band", recording)
    out, own = bands.calibrated_bands(folds, inner, [plant] * 3, logs, 0.9)
    assert len(calls) == 3 * 3
    for k in range(3):
        base, *scored = calls[3 * k: 3 * k + 3]
        assert base == ([folds[k].viscous] + [s.viscous for s in inner[k]], f"log{k}")
        others = [j for j in range(3) if j != k]
        assert scored == [([inner[k][i].viscous], f"log{j}") for i, j in enumerate(others)]
        assert out[k].widened
    assert {name for name, _ in own} == {"log0", "log1", "log2"}
    calls.clear()
    hull = {"pitch": (-0.2, 0.2)}
    far = [logs[0], replace(logs[1], pose=np.array([0.2, 0.5, 0.08])),
           replace(logs[2], pose=np.array([0.0, 0.5, 0.08]))]
    out, own = bands.calibrated_bands(folds, inner, [plant] * 3, far, 0.9, hull=hull)
    assert not out[0].widened and out[1].extrapolated and not out[1].widened and [n for n, _ in own] == ["log0"]


def test_a_widening_score_is_the_distance_outside_in_median_travels():
    """A band whose edges sit on its median, the measured angle 0.1 rad above it on the last 30 of 100
    scored samples: at level 0.8 the 80th-percentile distance outside is 0.1 rad (30 % are out), in
    units of the median's 0.5 rad travel a score of 0.2; widened by that score the band holds at
    least 80 % of the samples, by a score of 0 it is unchanged and still misses 30 %."""
    time = np.arange(100) * 1e-3
    median = np.linspace(0.0, 0.5, 100)
    measured = median + np.r_[np.zeros(70), np.full(30, 0.1)]
    band = band_of(np.vstack([median, median]), AxisLog("x", "roll", 1e-3, np.zeros(100), measured,
                                                        np.zeros(3)), 0.8)
    assert band.start == 0 and np.allclose(band.time, time)
    assert widening_score(band) == pytest.approx(0.1 / 0.5, rel=1e-9)
    wide = widened(band, [widening_score(band)] * 9)
    assert wide.widened and wide.coverage >= 0.8 and band.coverage == pytest.approx(0.7)
    assert widened(band, [0.0] * 9).coverage == pytest.approx(0.7)
    np.testing.assert_allclose(wide.upper - band.upper, 0.1)

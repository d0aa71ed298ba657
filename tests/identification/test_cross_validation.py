"""The fit with its folds on a process pool, the inner folds and the undetermined ranges."""

from dataclasses import replace

import numpy as np

from rcm_kin.dynamics.axis_friction import AxisFriction
from rcm_kin.identification.cross_validation import fit_with_cv, undetermined_ranges
from rcm_kin.identification.drive_train import leave_one_out, search_for

TRUTH = AxisFriction(extra_inertia=0.4, viscous=6.0, coulomb=0.3, presliding_stiffness=20.0, presliding_slope=2.0,
                     presliding_force=1.5)


def test_two_processes_give_the_serial_results_and_no_fold_sees_its_log(steps):
    """On two processes the fit, folds and inner folds are those of one process (same seeds), the
    folds those of the serial leave_one_out; changing log 0's data leaves fold 0 and its inner
    folds exactly as they were (nothing of log 0 enters them) while the fit on all logs moves."""
    plant, logs = steps(TRUTH)
    search = search_for(("viscous", "presliding"))
    serial = fit_with_cv(search, [plant] * 3, logs, 0, (8, 8), cv=True, inner=True, workers=1)
    pooled = fit_with_cv(search, [plant] * 3, logs, 0, (8, 8), cv=True, inner=True, workers=2)
    assert pooled.friction == serial.friction and pooled.folds == serial.folds and pooled.inner == serial.inner
    assert np.array_equal(pooled.standard_errors, serial.standard_errors, equal_nan=True)
    assert tuple(leave_one_out(search, [plant] * 3, logs, generations=8)[1]) == serial.folds
    assert [len(i) for i in serial.inner] == [2, 2, 2]
    odd = replace(logs[0], measured=logs[0].measured[0] + 2.0 * (logs[0].measured - logs[0].measured[0]))
    changed = fit_with_cv(search, [plant] * 3, [odd] + logs[1:], 0, (8, 8), cv=True, inner=True, workers=1)
    assert changed.folds[0] == serial.folds[0] and changed.inner[0] == serial.inner[0]
    assert changed.friction != serial.friction


def test_an_undetermined_parameter_spans_its_range_and_a_determined_one_does_not(steps):
    """A slip force above anything the steps load the spring with leaves the cost flat up to
    the bound (5 N m): its range reaches it; the viscous friction, which every step feels, keeps a
    narrow range around the truth."""
    truth = replace(TRUTH, presliding_force=4.0)
    plant, logs = steps(truth)
    ranges = undetermined_ranges(truth, [plant] * 3, logs, ["presliding_force", "viscous"])
    lo, hi = ranges["presliding_force"]
    assert hi == 5.0 and lo <= 4.0
    lo, hi = ranges["viscous"]
    assert lo <= 6.0 <= hi and hi - lo < 6.0


def test_a_left_out_band_does_not_move_with_its_own_log(monkeypatch, steps):
    """``identify_joint --cv`` scores a band per left-out log; the band of log 0 (its lower and upper
    edges) is built from nothing fitted on log 0 (only its first rest and its PWM, where every
    prediction of it starts), so changing log 0's measured angle after its start leaves it as it
    was while its scores (against the new angle) change; the preloads the fit lists are one per log
    and reach the file's ``[uncertainty.preloads]``."""
    from rcm_kin.identification import identify as module

    monkeypatch.setattr(module, "GENERATIONS", (6, 6))
    plant, logs = steps(TRUTH)
    first = module.identify_joint("roll", logs, [plant] * 3, cv=True, terms=("viscous", "presliding"), workers=1)
    odd = replace(logs[0], measured=np.r_[logs[0].measured[0], logs[0].measured[1:] + 0.01])
    second = module.identify_joint("roll", [odd] + logs[1:], [plant] * 3, cv=True, terms=("viscous", "presliding"),
                                   workers=1)
    a, b = first.cv_bands[0], second.cv_bands[0]
    np.testing.assert_array_equal(a.lower, b.lower)
    np.testing.assert_array_equal(a.upper, b.upper)
    assert a.coverage != b.coverage or a.median_fit != b.median_fit
    assert a.widened and len(first.discrepancy) == 3 and all(d >= 0 for d in first.discrepancy.values())
    assert [band.name for band in first.cv_bands] == [c.name for c in first.cross_validation]
    assert a.sources["fold_sets"] == 1 + 2 and a.sources["preload"] == 2     # fold + 2 inner sets; 2 other logs
    assert set(first.preloads) <= {"step 0", "step 1", "step 2"}
    assert all(-1.0 <= p <= 1.0 for p in first.preloads.values())
    payload = module.Identification({"roll": first}, (), module.load_drive_parameters()).as_dict()
    assert set(payload["cross_validation_band"]["roll"]) == {"step 0", "step 1", "step 2"}
    assert payload["preloads"]["roll"] == first.preloads and payload["discrepancy"]["roll"] == first.discrepancy
    written = module.with_uncertainty(module.DriveUncertainty(), {"roll": first})
    assert written.preloads.get("roll", ()) == tuple(first.preloads.values())
    assert written.discrepancy["roll"] == tuple(first.discrepancy.values())
    stale = module.DriveUncertainty(preloads={"roll": (0.5,)}, discrepancy={"roll": (9.0,)}, ranges={"roll": {}})
    plain = replace(first, folds=(), preloads={}, discrepancy={}, cv_bands=())
    assert not module.with_uncertainty(stale, {"roll": plain}).discrepancy       # nothing kept of the old model

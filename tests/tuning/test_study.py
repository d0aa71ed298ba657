"""The study's criteria and choice on hand-made outcomes (numbers written here, not computed by
the code under test), and its refusals."""

from __future__ import annotations

import numpy as np
import pytest

from rcm_kin.errors import RcmKinError
from rcm_kin.tuning.objective import Outcomes
from rcm_kin.tuning.study import SCHEDULE_MARGIN, Judged, choose, criteria, design_study


def outcomes(max_error, mean_error, saturation=0.0, unstable=False) -> Outcomes:
    """Four draws, one experiment ("sine"), both axes, the given errors on every draw but the last,
    which is 0.1 deg worse (the worst draw)."""
    mx = np.full((4, 1, 2), float(max_error))
    mx[-1] += 0.1
    unstable_runs = np.zeros((4, 1), dtype=bool)
    unstable_runs[0] = unstable
    if unstable:
        mx[0] = np.nan
    return Outcomes(("sine",), mx, np.full((4, 1, 2), float(mean_error)), np.full((4, 1, 2), float(saturation) / 8),
                    unstable_runs)


def with_worst(o: Outcomes, worst: float) -> Outcomes:
    o.max_error_deg[-1] = worst
    return o


THESIS = Judged(outcomes(0.3, 0.13), np.nan, 2.0, 2.0)


def judged(o: Outcomes, radius: float = 0.99) -> Judged:
    return Judged(o, radius, 0.0, 0.0)


def test_a_design_better_everywhere_meets_every_criterion():
    assert all(criteria(judged(outcomes(0.05, 0.02)), THESIS).values())


@pytest.mark.parametrize("design, failed", [
    (judged(with_worst(outcomes(0.31, 0.02), 0.35)), "median_at_or_below_thesis"),   # median max 0.31 > 0.30
    (judged(outcomes(0.05, 0.14)), "median_at_or_below_thesis"),          # median mean 0.14 > 0.13
    (judged(outcomes(0.05, 0.02), radius=1.0), "frozen_loop_stable"),
    (judged(outcomes(0.05, 0.02, saturation=1.0)), "saturation_no_more"),
    (judged(outcomes(0.05, 0.02, unstable=True)), "no_unstable_run"),
])
def test_each_criterion_fails_on_its_own(design, failed):
    met = criteria(design, THESIS)
    assert not met[failed]
    assert all(v for k, v in met.items() if k != failed)


def test_the_worst_draw_is_judged_on_its_own():
    design = outcomes(0.05, 0.02)
    design.max_error_deg[-1] = 0.41              # the thesis's worst is 0.40
    met = criteria(judged(design), THESIS)
    assert not met["worst_no_worse"] and met["median_at_or_below_thesis"]


def test_the_schedule_is_chosen_only_by_its_margin_on_the_tuning_draws():
    fixed = 0.300
    assert choose({"fixed": fixed, "scheduled": fixed * (1 - SCHEDULE_MARGIN) - 1e-9}) == "scheduled"
    assert choose({"fixed": fixed, "scheduled": fixed * (1 - SCHEDULE_MARGIN) + 1e-6}) == "fixed"
    assert choose({"fixed": fixed, "scheduled": fixed}) == "fixed"
    assert choose({"fixed": 0.3, "scheduled": 0.29}, margin=0.0) == "scheduled"


@pytest.mark.parametrize("kwargs, parameter", [
    ({"seed": 3, "check_seed": 3}, "check_seed"),
    ({"samples": 8, "tune_samples": 9}, "tune_samples"),
    ({"points": 40}, "points"),
])
def test_bad_study_requests_are_refused_before_any_work(params, kwargs, parameter):
    with pytest.raises(RcmKinError) as error:
        design_study(params, **kwargs)
    assert error.value.parameter == parameter

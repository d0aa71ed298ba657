"""The report's pieces (what its process pool runs) give the sections the whole functions give,
with the numbers of the readable reference code: the compiled closed loop in the tracking
experiments, the schedule designed once per worker, the SOS sampling check computed once."""

from __future__ import annotations

import numpy as np
import pytest

from rcm_kin.errors import RcmKinError


@pytest.fixture(scope="module")
def nominal_schedule():
    from rcm_kin.simulation.experiments import psm_schedule

    return psm_schedule()


def test_the_nominal_schedule_is_the_schedule_sections(nominal_schedule, tmp_path):
    """The pieces that take ``psm_schedule()`` in another worker use the schedule section's own
    design, number for number (the schedule designed anew here, not taken from the cache)."""
    from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG, schedule_gains
    from rcm_kin.dynamics.state_space import driven_dynamics
    from rcm_kin.model import load_robot

    anew = schedule_gains(driven_dynamics(load_robot("psm"), coulomb=False), THESIS_ROLL_DEG, THESIS_PITCH_DEG)
    for name in ("k_roll", "k_pitch", "u_hold", "ff_pitch", "A", "B", "A_cl"):
        assert np.array_equal(getattr(anew, name), getattr(nominal_schedule, name)), name


def test_tracking_rows_are_the_reference_loops(nominal_schedule, tmp_path):
    """The tracking piece runs the compiled loop; its table is the one of the readable reference
    loop (`simulate` with the readable plant and controllers, from the steady hold of the first
    pose: the model's holding PWM there), cell for cell."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm
    from rcm_kin.model import load_robot
    from rcm_kin.report.sections.tracking import CONTROLLERS, _rows, tracking_experiment
    from rcm_kin.simulation.controllers import Hold, make_controller
    from rcm_kin.simulation.experiments import experiment_reference, psm_plant
    from rcm_kin.simulation.firmware import FirmwareSettings
    from rcm_kin.simulation.loop import firmware_units, simulate

    part = tracking_experiment(tmp_path, nominal_schedule, "sine", duration=1.0, animate=False)
    settings, params = FirmwareSettings(), load_drive_parameters()
    plant = psm_plant(params, settings.period)                           # readable, not compiled
    reference = experiment_reference("sine", settings.period, 1.0)
    start = reference.position[0]
    hold = Hold(firmware_units(start), holding_pwm(driven_dynamics(load_robot("psm"), params), start))
    rows = [tuple(row) for name in CONTROLLERS
            for row in _rows("sine", simulate(plant.step, make_controller(name, nominal_schedule), reference,
                                              settings, initial=plant.initial, hold=hold))]
    assert part.rows == tuple(rows)
    assert part.runs.animation is None and len(part.runs.runs) == len(CONTROLLERS)


def test_safety_pieces_make_the_whole_section(tmp_path):
    """As the report splits them: the scenarios with a barrier figure in one piece, the PSM's in
    another, the checks in a third, give the section of one call; two pieces that each drew a
    barrier figure are refused (each figure holds only its own scenarios)."""
    from rcm_kin.report.sections.safety import safety_checks, safety_from_parts, safety_section, scenario_runs

    options = dict(chains=("psm",), certificates=False)
    for folder in ("whole", "parts", "other"):
        (tmp_path / folder).mkdir()
    whole = safety_section(tmp_path / "whole", scenarios=("slide", "heart", "psm"), filters=("none",), **options)
    parts = [scenario_runs(tmp_path / "parts", ("slide", "heart"), ("none",)),
             scenario_runs(tmp_path / "other", ("psm",), ("none",))]
    pieced = safety_from_parts(parts, safety_checks(**options))
    assert pieced == whole
    assert [row[0] for row in pieced.scenarios.rows] == ["slide", "heart", "psm"]
    assert pieced.figure == "safety_barriers.png" and pieced.psm_no_go_mm is not None
    split = [scenario_runs(tmp_path / "parts", ("slide",), ("none",)),
             scenario_runs(tmp_path / "other", ("heart",), ("none",))]
    with pytest.raises(RcmKinError, match="one part"):
        safety_from_parts(split, safety_checks(**options))


def test_a_certificate_carries_its_sampling_check():
    """The report takes the check `find_certificate` made; it is `check_by_sampling` of the certificate."""
    pytest.importorskip("cvxpy")
    from rcm_kin.safety.sos import check_by_sampling, find_certificate, thesis_program

    program = thesis_program("1")
    c = find_certificate(program)
    assert c.B and c.check == check_by_sampling(c.B, program)
    assert c.feasible == c.check.passed


def _warns(text):
    import warnings

    from rcm_kin.errors import CompilerFallbackWarning

    warnings.warn(text, CompilerFallbackWarning)
    return text


def test_a_pieces_warnings_reach_the_caller():
    """A piece runs in a forked worker, where the caller's record of warnings does not reach: its
    warnings come back with its result and are raised again in the caller."""
    import warnings

    from rcm_kin.errors import CompilerFallbackWarning
    from rcm_kin.report import Job, run_jobs

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = run_jobs([Job("a", _warns, ("from a worker",)), Job("b", _warns, ("from another",))], 2)
    assert {r.value for r in results.values()} == {"from a worker", "from another"}
    assert sorted(str(w.message) for w in caught if w.category is CompilerFallbackWarning) == [
        "from a worker", "from another"]

"""The structure variants: the thesis law as a state-feedback law is the thesis controller (a
declared twin), and each design variant removes exactly its part."""

from __future__ import annotations

import numpy as np
import pytest

from rcm_kin.simulation.controllers import ThesisController
from rcm_kin.simulation.experiments import closed_loop, experiment_reference, psm_plant_and_schedule, start_hold
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.thesis import K_PITCH, K_ROLL
from rcm_kin.tuning.structures import structure_variants, table_gains, thesis_as_state_feedback

VALUES = {"roll_kp": 300.0, "roll_kd": -5.0, "pitch_kp": 150.0, "pitch_kd": -1.0, "pitch_ki": 300.0,
          "roll_friction_pwm": 12.0, "pitch_friction_pwm": 9.0, "friction_ramp_deg_s": 3.0, "pitch_feedforward": 1.0}


@pytest.mark.parametrize("experiment", ["sine", "target"])
@pytest.mark.parametrize("fast", [True, False], ids=["compiled", "readable"])
def test_the_thesis_law_as_state_feedback_is_the_thesis_controller(experiment, fast):
    plant, base = psm_plant_and_schedule(fast=fast)
    settings = FirmwareSettings()
    reference = experiment_reference(experiment, settings.period, 2.0 if experiment == "sine" else None)
    hold = start_hold(reference)
    twin, _ = thesis_as_state_feedback(base)
    a = closed_loop(plant, ThesisController(), reference, settings, hold=hold, fast=fast)
    b = closed_loop(plant, twin, reference, settings, hold=hold, fast=fast)
    np.testing.assert_array_equal(a.command, b.command)
    np.testing.assert_array_equal(a.measured, b.measured)


def test_the_thesis_kd_variants_scale_only_kd():
    _, base = psm_plant_and_schedule()
    for scale in (0.0, -1.0):
        _, schedule = thesis_as_state_feedback(base, scale)
        np.testing.assert_array_equal(schedule.k_roll[..., 0], K_ROLL[..., 0])
        np.testing.assert_array_equal(schedule.k_roll[..., 1], scale * K_ROLL[..., 1])
        np.testing.assert_array_equal(schedule.k_pitch[..., [0, 2]], K_PITCH[..., [0, 2]])
        np.testing.assert_array_equal(schedule.k_pitch[..., 1], scale * K_PITCH[..., 1])
        gains = table_gains(schedule, np.array([0.0, 20.0]), np.array([0.0, -15.0]))
        np.testing.assert_allclose(gains[:, 1], scale * np.array([K_ROLL[1, 1, 1], K_ROLL[0, 2, 1]]), rtol=1e-12,
                                   atol=1e-15)


def test_each_design_variant_removes_its_part():
    _, base = psm_plant_and_schedule()
    variants = structure_variants(base, VALUES)
    full = variants["design without gravity feedforward"][0]
    assert not full.gravity and full.track_velocity and full.friction
    assert not variants["design damping the measured velocity"][0].track_velocity
    assert variants["design without friction compensation"][1].friction.pwm == (0.0, 0.0)
    assert variants["design without the roll's friction compensation"][1].friction.pwm == (0.0, 9.0)
    assert np.all(variants["design without the pitch feedforward"][1].ff_pitch == 0)
    assert np.all(variants["design pitch Ki at its least (1)"][1].k_pitch[..., 2] == 1.0)
    np.testing.assert_array_equal(variants["design without the pitch feedforward"][1].k_roll,
                                  variants["design without friction compensation"][1].k_roll)

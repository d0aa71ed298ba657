"""The design spaces (:mod:`rcm_kin.tuning.design`): bounds and their reasons, the unit box, the
affine schedule against the firmware's bilinear interpolation, and the tuned gain schedule."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from rcm_kin.control.friction import FrictionCompensation
from rcm_kin.control.gain_schedule import GainSchedule, closed_loop_matrix, scheduled_gains
from rcm_kin.control.linearization import linearize_grid
from rcm_kin.errors import RcmKinError
from rcm_kin.firmware_rules import bilinear
from rcm_kin.hardware import ENCODER_COUNT, FIRMWARE_PERIOD, PWM_LIMIT, ROLL_FILTER
from rcm_kin.tuning.design import PWM_PER_COUNT, DesignSpace, gain_tables, pose_gains, tuned_schedule

ROLL_GRID = np.array([-20.0, 0.0, 20.0])      # the thesis grid, written out
PITCH_GRID = np.array([-15.0, 0.0, 15.0])
LOG = {"roll_kp", "pitch_kp", "pitch_ki", "friction_ramp_deg_s"}
SLOPES = ("roll_kp_roll_slope", "roll_kp_pitch_slope", "pitch_kp_roll_slope", "pitch_kp_pitch_slope")


def bounds(space: DesignSpace) -> dict:
    return {p.name: p for p in space.parameters}


def random_design(seed: int, kind: str = "scheduled") -> dict[str, float]:
    space = DesignSpace(kind)
    return space.values(np.random.default_rng(seed).random(len(space.parameters)))


def by_hand(values: dict[str, float], roll: float, pitch: float) -> np.ndarray:
    """The five gains at a pose of the thesis grid: Kp scaled by ``1 + s_r r / 20 + s_p p / 15``."""
    scale = {a: 1 + values.get(f"{a}_kp_roll_slope", 0.0) * roll / 20
             + values.get(f"{a}_kp_pitch_slope", 0.0) * pitch / 15 for a in ("roll", "pitch")}
    return np.array([values["roll_kp"] * scale["roll"], values["roll_kd"], values["pitch_kp"] * scale["pitch"],
                     values["pitch_kd"], values["pitch_ki"]])


@pytest.fixture(scope="module")
def base(smooth_model):
    """A schedule on the thesis grid with the model's own linear models and made-up tables (what a
    tuned schedule keeps of its base: grid, models, holding table; the designed one costs seconds)."""
    P, R = np.meshgrid(PITCH_GRID, ROLL_GRID, indexing="ij")
    poses = np.column_stack([np.radians(R.ravel()), np.radians(P.ravel()), np.full(R.size, 0.080)])
    grid = linearize_grid(smooth_model, poses, compile=False)
    rng = np.random.default_rng(9)
    A, B = grid.A.reshape(3, 3, 6, 6), grid.B.reshape(3, 3, 6, 3)
    k_roll, k_pitch = rng.uniform(1, 100, (3, 3, 2)), rng.uniform(1, 100, (3, 3, 3))
    A_cl = np.array([[closed_loop_matrix(A[j, i], B[j, i], k_roll[j, i], k_pitch[j, i]) for i in range(3)]
                     for j in range(3)])
    return GainSchedule(ROLL_GRID, PITCH_GRID, 0.080, k_roll, k_pitch, rng.uniform(-50, 50, (3, 3, 2)),
                        rng.uniform(0.1, 1, (3, 3, 2)), A, B, A_cl, friction=FrictionCompensation((5.0, 6.0), 3.0))


def test_the_spaces():
    fixed, scheduled = DesignSpace("fixed"), DesignSpace("scheduled")
    assert fixed.names == ("roll_kp", "roll_kd", "pitch_kp", "pitch_kd", "pitch_ki", "roll_friction_pwm",
                           "pitch_friction_pwm", "friction_ramp_deg_s", "pitch_feedforward")
    assert scheduled.names == fixed.names + SLOPES
    assert DesignSpace().kind == "scheduled"
    for p in scheduled.parameters:
        assert p.low < p.high and p.reason and p.unit
        assert p.log == (p.name in LOG)
        assert not p.log or p.low > 0


@pytest.mark.parametrize("kind", ["fixed", "scheduled"])
def test_the_unit_box_round_trips(kind):
    space = DesignSpace(kind)
    rng = np.random.default_rng(0)
    for _ in range(5):
        x = rng.random(len(space.parameters))
        values = space.values(x)
        assert tuple(values) == space.names
        np.testing.assert_allclose(space.unit(values), x, rtol=0, atol=1e-12)
        again = space.values(space.unit(values))
        assert again == pytest.approx(values, rel=1e-12, abs=1e-12)


def test_the_box_ends_are_the_bounds_and_log_parameters_are_geometric():
    for p in DesignSpace("scheduled").parameters:
        assert p.from_unit(0.0) == pytest.approx(p.low, rel=1e-14, abs=1e-14)
        assert p.from_unit(1.0) == pytest.approx(p.high, rel=1e-14, abs=1e-14)
        middle = np.sqrt(p.low * p.high) if p.log else (p.low + p.high) / 2
        assert p.from_unit(0.5) == pytest.approx(middle, rel=1e-12, abs=1e-14)
        if p.log:      # equal steps in the box are equal ratios
            ratio = p.from_unit(0.5) / p.from_unit(0.25)
            assert p.from_unit(0.75) / p.from_unit(0.5) == pytest.approx(ratio, rel=1e-12)
        below = p.low / 2 if p.log else p.low - 1.0
        assert p.to_unit(below) == 0.0 and p.to_unit(p.high * 2 + 1.0) == 1.0      # clipped to the box


def test_the_box_is_clipped_and_a_bad_point_refused():
    space = DesignSpace("fixed")
    n = len(space.parameters)
    assert space.values(np.full(n, 2.0)) == space.values(np.ones(n))
    for bad in (np.zeros(n - 1), np.r_[np.zeros(n - 1), np.nan], np.zeros((1, n))):
        with pytest.raises(RcmKinError) as error:
            space.values(bad)
        assert error.value.parameter == "unit"


def test_missing_slopes_are_zero():
    fixed = random_design(1, "fixed")
    scheduled = DesignSpace("scheduled").values(DesignSpace("scheduled").unit(fixed))
    assert [scheduled[s] for s in SLOPES] == [0.0] * 4
    assert {k: scheduled[k] for k in fixed} == pytest.approx(fixed, rel=1e-12)


def test_the_gain_bounds_are_one_encoder_count_of_pwm():
    """Kp: one count of position error; Kd: one count of position change over one period, the roll's
    through its velocity filter ``vf = a vf + (1 - a) v``, from rest."""
    p = bounds(DesignSpace("fixed"))
    assert PWM_PER_COUNT == pytest.approx(0.1 * PWM_LIMIT[0])
    assert p["roll_kp"].high * ENCODER_COUNT[0] == pytest.approx(PWM_PER_COUNT, rel=1e-12)
    assert p["pitch_kp"].high * ENCODER_COUNT[1] == pytest.approx(PWM_PER_COUNT, rel=1e-12)
    roll_velocity = ROLL_FILTER * 0.0 + (1 - ROLL_FILTER) * ENCODER_COUNT[0] / FIRMWARE_PERIOD
    pitch_velocity = ENCODER_COUNT[1] / FIRMWARE_PERIOD
    assert -p["roll_kd"].low * roll_velocity == pytest.approx(PWM_PER_COUNT, rel=1e-12)
    assert -p["pitch_kd"].low * pitch_velocity == pytest.approx(PWM_PER_COUNT, rel=1e-12)
    assert p["roll_kd"].high == 0.0 and p["pitch_kd"].high == 0.0     # damping only (the hardware sign)


def test_an_unknown_space_is_refused():
    with pytest.raises(RcmKinError) as error:
        DesignSpace("both")
    assert error.value.parameter == "kind"


def test_the_tables_are_the_affine_design_at_the_grid():
    values = random_design(2)
    k_roll, k_pitch = gain_tables(values, ROLL_GRID, PITCH_GRID)
    assert k_roll.shape == (3, 3, 2) and k_pitch.shape == (3, 3, 3)
    for j, pitch in enumerate(PITCH_GRID):            # tables [pitch][roll], as the firmware's
        for i, roll in enumerate(ROLL_GRID):
            np.testing.assert_allclose(np.r_[k_roll[j, i], k_pitch[j, i]], by_hand(values, roll, pitch), rtol=1e-14)


def test_pose_gains_are_the_firmwares_bilinear_tables():
    """Inside the grid and outside it (the firmware clamps to the edge)."""
    rng = np.random.default_rng(3)
    for seed in (4, 5):
        values = random_design(seed)
        k_roll, k_pitch = gain_tables(values, ROLL_GRID, PITCH_GRID)
        roll, pitch = rng.uniform(-45, 45, 40), rng.uniform(-35, 35, 40)
        roll[:4], pitch[:4] = [-20, 20, 0, 30], [-15, 15, 0, -30]
        want = np.array([np.r_[bilinear(ROLL_GRID, PITCH_GRID, k_roll, r, p),
                               bilinear(ROLL_GRID, PITCH_GRID, k_pitch, r, p)] for r, p in zip(roll, pitch)])
        assert np.any(np.abs(roll) > 20) and np.any(np.abs(pitch) < 15)
        np.testing.assert_allclose(pose_gains(values, roll, pitch), want, rtol=1e-12, atol=1e-12)


def test_the_tuned_schedule(base):
    values = random_design(6)
    tuned = tuned_schedule(base, values)
    for j, pitch in enumerate(base.pitch_deg):
        for i, roll in enumerate(base.roll_deg):
            gains = by_hand(values, roll, pitch)
            np.testing.assert_allclose(tuned.k_roll[j, i], gains[:2], rtol=1e-14)
            np.testing.assert_allclose(tuned.k_pitch[j, i], gains[2:], rtol=1e-14)
            np.testing.assert_allclose(tuned.A_cl[j, i], closed_loop_matrix(base.A[j, i], base.B[j, i], gains[:2],
                                                                            gains[2:]), rtol=1e-12, atol=1e-12)
    assert tuned.friction == FrictionCompensation((values["roll_friction_pwm"], values["pitch_friction_pwm"]),
                                                  values["friction_ramp_deg_s"])
    np.testing.assert_allclose(tuned.ff_pitch, base.ff_pitch * values["pitch_feedforward"], rtol=1e-15)
    for field in ("roll_deg", "pitch_deg", "u_hold", "A", "B"):
        assert np.array_equal(getattr(tuned, field), getattr(base, field)), field
    assert tuned.insertion == base.insertion and tuned.weights == base.weights
    assert not np.array_equal(tuned.k_roll, base.k_roll)
    rng = np.random.default_rng(7)         # what the firmware interpolates is what the loops are judged at
    for r, p in zip(rng.uniform(-30, 30, 10), rng.uniform(-25, 25, 10)):
        np.testing.assert_allclose(np.r_[scheduled_gains(tuned, r, p)], pose_gains(values, [r], [p])[0], rtol=1e-12)


def test_the_designed_schedule_is_left_alone(base):
    before = {f.name: np.copy(getattr(base, f.name)) for f in dataclasses.fields(base)
              if isinstance(getattr(base, f.name), np.ndarray)}
    tuned_schedule(base, random_design(8))
    assert all(np.array_equal(getattr(base, name), value) for name, value in before.items())


def test_a_log_parameter_below_zero_clips_to_the_box():
    roll_kp = bounds(DesignSpace("fixed"))["roll_kp"]
    assert roll_kp.to_unit(-5.0) == 0.0


def test_a_tuned_design_is_written_on_the_thesis_grid_only(base):
    """pose_gains clamps at the thesis grid's edges; on another grid the firmware's tables would
    interpolate other gains than the stability check judged, so another grid is refused."""
    other = dataclasses.replace(base, roll_deg=np.array([-30.0, 0.0, 30.0]))
    with pytest.raises(RcmKinError, match="thesis grid") as error:
        tuned_schedule(other, random_design(8))
    assert error.value.parameter == "base"

"""The drawn plants (:mod:`rcm_kin.tuning.draws`): the loop family is a twin of the firmware loop
matrix it was derived from, the draws are the robustness study's seeds, kept only where the
measured holds allow them, and a subset is the same loops on a coarser grid."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np
import pytest
from scipy.optimize import brentq

from rcm_kin.control.linearization import linearize_grid
from rcm_kin.control.stability import firmware_loop_matrix
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import FIRMWARE_PERIOD, HOME_INSERTION
from rcm_kin.robustness.sampling import draw, uncertain_parameters, with_values
from rcm_kin.robustness.task import roll_pitch_modes
from rcm_kin.simulation.experiments import exact_key, experiment_reference
from rcm_kin.statics.holding_band import conformal_half_width, residuals_of
from rcm_kin.tuning.draws import build_draws, loop_family

ROLLS = np.array([-20.0, 5.0, 17.0])       # a grid of unequal sides: a transposed pose order would show
PITCHES = np.array([-12.0, 9.0])
SEED = 5                                   # its first draws: some kept, some ruled out by the holds
LEVEL = 0.9                                # the holding band's level (the drive file's holds support it)


def poses_of(roll_deg, pitch_deg) -> np.ndarray:
    return np.column_stack([np.radians(roll_deg), np.radians(pitch_deg), np.full(np.size(roll_deg), HOME_INSERTION)])


def direct_loops(model, family, gains) -> np.ndarray:
    """The firmware loop matrix at each of the family's poses, straight from the linear models."""
    grid = linearize_grid(model, poses_of(family.roll_deg, family.pitch_deg), compile=False)
    gains = np.broadcast_to(gains, (len(grid.A), 5))
    return np.array([firmware_loop_matrix(A, B, k[:2], k[2:], FIRMWARE_PERIOD)
                     for A, B, k in zip(grid.A, grid.B, gains)])


def direct_radius(Phi: np.ndarray, ki: float) -> float:
    """As :func:`rcm_kin.robustness.task.loop_margins` judges a loop: without integral action the
    error integral's state (a mode exactly at 1) is sliced off before the roll/pitch modes are taken."""
    keep = slice(None) if ki else slice(0, 9)
    return float(np.abs(roll_pitch_modes(Phi[keep, keep])).max())


def random_gains(rng, m: int) -> np.ndarray:
    """(m, 5) gains over the design space's span (roll Kp, Kd; pitch Kp, Kd, Ki; firmware units)."""
    return np.column_stack([rng.uniform(10, 1100, m), rng.uniform(-25, 0, m), rng.uniform(10, 740, m),
                            rng.uniform(-3, 0, m), rng.uniform(1, 3000, m)])


@pytest.fixture(scope="module")
def family(smooth_model):
    return loop_family(smooth_model, ROLLS, PITCHES, HOME_INSERTION, FIRMWARE_PERIOD)


# -- the loop family ---------------------------------------------------------------------------


def test_the_family_covers_the_grid_once(family):
    assert family.F0.shape == (6, 10, 10) and family.F.shape == (5, 6, 10, 10)
    assert sorted(zip(family.roll_deg, family.pitch_deg)) == sorted(itertools.product(ROLLS, PITCHES))


@pytest.mark.parametrize("case", ["one set", "per pose", "no integral"])
def test_the_family_is_the_firmware_loop_matrix(smooth_model, family, case):
    rng = np.random.default_rng({"one set": 1, "per pose": 2, "no integral": 3}[case])
    for _ in range(3):
        gains = random_gains(rng, 6)
        if case == "one set":
            gains = gains[0]
        if case == "no integral":
            gains[:, 4] = 0.0
        want = direct_loops(smooth_model, family, gains)
        np.testing.assert_allclose(family.matrices(gains), want, rtol=1e-12, atol=1e-12)
        ki = np.broadcast_to(gains, (6, 5))[:, 4]
        radius = [direct_radius(Phi, k) for Phi, k in zip(want, ki)]
        np.testing.assert_allclose(family.spectral_radius(gains), radius, rtol=0, atol=1e-10)


def test_a_radius_above_one_is_reported(smooth_model, family):
    """Gains no loop holds (pitch Kp far too low against gravity): the family says unstable too."""
    gains = np.array([100.0, -1.0, 0.0, -1.0, 0.0])
    want = [direct_radius(Phi, 0.0) for Phi in direct_loops(smooth_model, family, gains)]
    assert max(want) > 1.0
    np.testing.assert_allclose(family.spectral_radius(gains), want, rtol=0, atol=1e-10)


def test_without_integral_only_the_integrator_is_left_out(smooth_model):
    """A real pitch mode just outside the unit circle (P pitch gain at the edge of stability)."""
    fam = loop_family(smooth_model, np.array([0.0]), np.array([0.0]), HOME_INSERTION, FIRMWARE_PERIOD)

    def excess(kp):
        return direct_radius(direct_loops(smooth_model, fam, [100.0, -1.0, kp, -1.0, 0.0])[0], 0.0) - (1 + 3e-6)

    kp = brentq(excess, 1.0, 5.0, xtol=1e-14)
    gains = np.array([100.0, -1.0, kp, -1.0, 0.0])
    assert fam.spectral_radius(gains)[0] == pytest.approx(1 + 3e-6, abs=1e-9)


# -- the draws ---------------------------------------------------------------------------------


def same(a, b) -> bool:
    return exact_key(a) == exact_key(b)


def holding_pwms(psm, p, poses) -> np.ndarray:
    """Roll and pitch holding PWM (n, 2) of the set ``p``'s smooth model at ``poses``."""
    model = driven_dynamics(psm, p, coulomb=False)
    return np.array([holding_pwm(model, q)[:2] for q in poses])


def build(*args, **kwargs):
    """:func:`build_draws` with a stand-in for the compiled plant (0.6 s of C compiler a draw, and
    nothing these tests read): a record of what it was built from."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("rcm_kin.tuning.draws.sample_plant", lambda p, period: {"params": p, "period": period})
        return build_draws(*args, **kwargs)


@pytest.fixture(scope="module")
def consistent_with_holds(psm, params, thesis_poses):
    """``drawn -> bool``: the drawn set's roll and pitch holding PWM at the thesis grid within the
    measured band (level 0.9 of the file's left-out residuals) of the nominal set's."""
    residuals = residuals_of(params)
    width = np.array([conformal_half_width(residuals[j], LEVEL) for j in ("roll", "pitch")])
    nominal = holding_pwms(psm, params, thesis_poses)
    return lambda drawn: bool(np.all(np.abs(holding_pwms(psm, drawn, thesis_poses) - nominal) <= width))


def drawn_set(params, index: int, seed: int = SEED):
    """Draw ``index`` of ``SeedSequence(seed)``, as the robustness study draws it."""
    uncertain = uncertain_parameters(params)
    return with_values(params, uncertain, draw(uncertain, np.random.SeedSequence(seed).spawn(index + 1)[index]))


@pytest.fixture(scope="module")
def drawn(params):
    return build(params, 3, SEED, points=5, experiments=("sine",))


def test_the_kept_draws_are_the_seeds_the_holds_allow(params, drawn, consistent_with_holds):
    indexes = [d.index for d in drawn.draws]
    assert len(drawn) == 3 and indexes == sorted(indexes)
    assert drawn.rejected > 0                       # the seed is chosen so that the check bites
    for d in drawn.draws:
        assert same(d.params, drawn_set(params, d.index))
        assert consistent_with_holds(d.params)
        assert d.plant["params"] is d.params and d.plant["period"] == FIRMWARE_PERIOD
    skipped = [i for i in range(indexes[-1]) if i not in indexes]
    assert drawn.rejected == len(skipped)
    for i in skipped:
        assert not consistent_with_holds(drawn_set(params, i))


def test_without_the_check_the_first_seeds_are_taken(params, consistent_with_holds):
    loose = build(params, 2, SEED, points=2, experiments=("sine",), consistent=False)
    assert [d.index for d in loose.draws] == [0, 1] and loose.rejected == 0
    for d in loose.draws:
        assert same(d.params, drawn_set(params, d.index))
    assert not all(consistent_with_holds(d.params) for d in loose.draws)


def test_a_seed_gives_the_same_draws(params, drawn):
    again = build(params, 2, SEED, points=2, experiments=("sine",))
    assert [d.index for d in again.draws] == [d.index for d in drawn.draws[:2]]
    assert all(same(a.params, b.params) for a, b in zip(again.draws, drawn.draws))
    other = build(params, 1, SEED + 1, points=2, experiments=("sine",), consistent=False)
    assert other.draws[0].index == 0 and same(other.draws[0].params, drawn_set(params, 0, SEED + 1))
    assert not same(other.draws[0].params, drawn_set(params, 0))


def test_nominal_first_is_the_set_itself(params, nominal_draws):
    first = nominal_draws.draws[0]
    assert first.params is params and first.index == 0
    assert not same(nominal_draws.draws[1].params, params)


def test_each_draw_starts_from_its_own_hold(psm, drawn):
    reference = experiment_reference("sine", FIRMWARE_PERIOD)
    assert set(drawn.references) == {"sine"}
    np.testing.assert_array_equal(drawn.references["sine"].position, reference.position)
    for d in drawn.draws:
        want = holding_pwms(psm, d.params, [reference.position[0]])[0]
        np.testing.assert_allclose(d.holds["sine"].pwm[:2], want, rtol=1e-12, atol=1e-12)


def test_a_draws_loops_are_its_own_models(psm, drawn):
    d = drawn.draws[-1]
    model = driven_dynamics(psm, d.params, coulomb=False)
    gains = random_gains(np.random.default_rng(4), 1)[0]
    np.testing.assert_allclose(d.loops.matrices(gains), direct_loops(model, d.loops, gains), rtol=1e-12, atol=1e-12)
    np.testing.assert_array_equal(np.unique(d.loops.roll_deg), np.linspace(-20, 20, 5))
    np.testing.assert_array_equal(np.unique(d.loops.pitch_deg), np.linspace(-15, 15, 5))


def test_a_subset_is_the_first_draws_on_a_coarser_grid(psm, drawn):
    sub = drawn.subset(2, 3)
    assert len(sub) == 2 and sub.points == 3 and sub.seed == drawn.seed
    for d, full in zip(sub.draws, drawn.draws):
        assert d.index == full.index and d.params is full.params
        fresh = loop_family(driven_dynamics(psm, d.params, coulomb=False), np.array([-20.0, 0.0, 20.0]),
                            np.array([-15.0, 0.0, 15.0]), HOME_INSERTION, FIRMWARE_PERIOD)
        for field in dataclasses.fields(fresh):
            np.testing.assert_allclose(getattr(d.loops, field.name), getattr(fresh, field.name), rtol=1e-12, atol=1e-12)
    whole = drawn.subset(3, 5)
    assert all(np.array_equal(a.loops.F, b.loops.F) for a, b in zip(whole.draws, drawn.draws))
    corners = drawn.subset(1, 2).draws[0].loops
    assert sorted(zip(corners.roll_deg, corners.pitch_deg)) == sorted(itertools.product((-20, 20), (-15, 15)))


@pytest.mark.parametrize(("samples", "points"), [(0, 3), (4, 3), (2, 4), (2, 1)])
def test_a_subset_that_is_not_one_is_refused(drawn, samples, points):
    with pytest.raises(RcmKinError):
        drawn.subset(samples, points)


@pytest.mark.parametrize(("kwargs", "parameter"), [
    ({"samples": 0}, "samples"), ({"samples": 4097}, "samples"), ({"points": 1}, "points"),
    ({"points": 202}, "points"), ({"experiments": ("step",)}, "experiments"), ({"experiments": ()}, "experiments"),
])
def test_bad_arguments_are_refused(params, kwargs, parameter):
    options = {"samples": 1, "seed": 0, "points": 2} | kwargs
    with pytest.raises(RcmKinError) as error:
        build(params, **options)
    assert error.value.parameter == parameter


def test_holds_nothing_agrees_with_are_refused(params):
    """A holding band of zero width: no drawn set agrees with the holds, and the draws say so."""
    zero = {j: np.zeros_like(r) for j, r in params.uncertainty.holding_residuals.items()}
    tight = dataclasses.replace(params, uncertainty=dataclasses.replace(params.uncertainty, holding_residuals=zero))
    with pytest.raises(RcmKinError) as error:
        build(tight, 1, SEED, points=2, experiments=("sine",))
    assert error.value.parameter == "params"
    kept = build(tight, 1, SEED, points=2, experiments=("sine",), nominal_first=True)
    assert kept.draws[0].params is tight and kept.rejected == 0

"""The multi-element (Maxwell-slip, Iwan) presliding spring against the analytic Masing loop, the
presliding preload of the rest state, and the whole simulation against a plain-Python step."""

import math
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np
import pytest

from rcm_kin.dynamics.axis_friction import SUBSTEP
from rcm_kin.dynamics.stick_slip import (
    MAX_ELEMENTS,
    STATE_SIZE,
    AxisFriction,
    AxisPlant,
    force_unit,
    rest_state,
    simulate_axis,
    slip_elements,
)
from rcm_kin.errors import ParameterFileError, RcmKinError

K_TOTAL, SLIP = 40.0, 1.2     # N m/rad, N m: the whole spring's stiffness and saturation force


def element_slips(n: int) -> np.ndarray:
    """F_i = F_p 2 i / (N (N + 1)), i = 1..N (the distribution the model promises)."""
    return np.array([SLIP * 2.0 * i / (n * (n + 1)) for i in range(1, n + 1)])


def virgin(d: float, n: int) -> float:
    """The virgin curve f_v(d) = sign(d) sum_i min(k_i |d|, F_i), k_i = K / N."""
    return math.copysign(sum(min(K_TOTAL / n * abs(d), f) for f in element_slips(n)), d)


def masing(path: np.ndarray, n: int) -> np.ndarray:
    """The force along ``path`` (starting relaxed at 0) by Masing's rules: the virgin curve first,
    then after each reversal at (x_r, f_r) the branch f_r + 2 f_v((x - x_r) / 2)."""
    out = np.empty(path.size)
    x_r, f_r, first = 0.0, 0.0, True
    for k, x in enumerate(path):
        if k >= 2 and (path[k - 1] - path[k - 2]) * (x - path[k - 1]) < 0:    # a reversal at path[k - 1]
            x_r, f_r, first = path[k - 1], out[k - 1], False
        out[k] = virgin(x, n) if first else f_r + 2.0 * virgin((x - x_r) / 2.0, n)
    return out


def legs(*corners, points=4001) -> np.ndarray:
    """A displacement path through ``corners`` in straight legs (each corner sampled exactly)."""
    parts = [np.linspace(a, b, points)[1:] for a, b in zip(corners[:-1], corners[1:])]
    return np.r_[corners[0], np.concatenate(parts)]


def driven(path: np.ndarray, n: int) -> np.ndarray:
    """The model's spring force along ``path``: its slip update (the kernels' own) at each sample."""
    anchors = np.zeros(MAX_ELEMENTS)
    unit = force_unit(SLIP, n)
    return np.array([slip_elements(x, anchors, K_TOTAL / n, unit, n) for x in path])


@pytest.mark.parametrize("n", [1, 2, 3, 4])
@pytest.mark.parametrize("amplitude", [0.5 * SLIP / K_TOTAL, 3.0 * SLIP / K_TOTAL])   # part of / all the elements slip
def test_the_slip_follows_the_masing_loop(n, amplitude):
    """Driven 0 -> +X -> -X -> +X, the spring's force is the virgin curve, then the Masing branches
    f_r -+ 2 f_v((x_r - x) / 2) after each reversal (to 1e-12 N m)."""
    X = amplitude
    path = legs(0.0, X, -X, X)
    np.testing.assert_allclose(driven(path, n), masing(path, n), rtol=0, atol=1e-12)


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_the_loop_dissipates_the_iwan_area(n):
    """The closed loop +X -> -X -> +X dissipates sum_i 4 F_i (X - F_i / k_i) over the elements that
    slip (X > F_i / k_i; a rectangle of 2 F_i by 2 (X - F_i / k_i) each); the trapezoid rule errs by
    at most k dx^2 / 8 at each slip onset."""
    X = 1.7 * SLIP / K_TOTAL           # the last element slips for N >= 2, not the first ones' share
    path = legs(0.0, X, -X, X, points=20001)
    force = driven(path, n)
    start = 20000                       # the loop from +X on
    x, f = path[start:], force[start:]
    area = float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x)))
    k = K_TOTAL / n
    expected = sum(4.0 * F * (X - F / k) for F in element_slips(n) if X > F / k)
    assert area == pytest.approx(expected, rel=1e-6)
    assert expected > 0


def test_more_elements_soften_the_spring_gradually():
    """Same initial stiffness K and saturation force F_p: N = 1 is linear up to F_p at F_p / K, then
    flat (one cliff); N = 4 bends at each element's slip (slopes K, 3K/4, K/2, K/4, then 0) and
    reaches F_p at 2 N / (N + 1) F_p / K (its last element, K / N stiff, slips at 2 F_p / (N + 1))."""
    d = np.linspace(0.0, 2.0 * SLIP / K_TOTAL, 401)
    one, four = driven(d, 1), driven(d, 4)
    assert np.all(four <= one + 1e-15) and one[-1] == pytest.approx(SLIP, rel=1e-14)
    assert four[-1] == pytest.approx(SLIP, rel=1e-14)
    assert four[d < 1.6 * SLIP / K_TOTAL - 1e-12].max() < SLIP * (1 - 1e-6)
    slope = np.diff(four) / np.diff(d)
    assert set(np.round(slope / K_TOTAL, 6)) >= {0.0, 0.25, 0.5, 0.75, 1.0}   # (samples across a bend between)
    assert slope[0] == pytest.approx(K_TOTAL) and slope[-1] == pytest.approx(0.0, abs=1e-9)


def linear_plant(gain=0.1, tilt=2.0) -> AxisPlant:
    """Gravity ``tilt q`` (linear, so np.interp is exact), unit inertia."""
    grid = np.linspace(-1.0, 1.0, 21)
    return AxisPlant(gain, 0.0, 0.0, grid, tilt * grid, np.ones(grid.size))


@pytest.mark.parametrize("n", [1, 2, 3, 4])
@pytest.mark.parametrize("preload", [-1.0, -0.55, -0.1, 0.0, 0.35, 0.8, 1.0])
@pytest.mark.parametrize("pwm", [0.0, 5.0, -30.0])
def test_the_rest_carries_the_load_and_the_preload(n, preload, pwm):
    """At rest the spring's total force is clip(load + preload F_p, -F_p, F_p) (load = the motor
    torque less gravity), every element within its slip force, the unsaturated ones equally
    stretched (the virgin curve), the saturated ones at their bound; unused anchors at q."""
    friction = AxisFriction(presliding_stiffness=30.0, presliding_slope=1.5, presliding_force=SLIP,
                            presliding_elements=float(n))
    plant, angle = linear_plant(), 0.2
    state = rest_state(friction, plant, angle, pwm, preload=preload)
    assert state.shape == (STATE_SIZE,)
    q = state[2]
    k = 30.0 * np.exp(1.5 * q) / n
    load = 0.1 * pwm - 2.0 * q
    expected = min(max(load + preload * SLIP, -SLIP), SLIP)
    elements = k * (q - state[4:4 + n])
    assert np.sum(elements) == pytest.approx(expected, abs=1e-12)
    slips = element_slips(n)
    assert np.all(np.abs(elements) <= slips + 1e-12)
    elastic = np.abs(elements) < slips - 1e-12
    if elastic.any():
        np.testing.assert_allclose(q - state[4:4 + n][elastic], q - state[4 + int(np.argmax(elastic))], atol=1e-15)
    assert np.all(state[4 + n:] == q)


def test_no_preload_and_one_element_is_the_single_spring_rest():
    """preload 0, N = 1: the one anchor q - clip(load, -F_p, F_p) / k_p(q), exactly (today's rest)."""
    friction = AxisFriction(presliding_stiffness=30.0, presliding_slope=1.5, presliding_force=SLIP)
    for pwm in (0.0, 5.0, -30.0, 400.0):
        state = rest_state(friction, linear_plant(), 0.2, pwm)
        q = state[2]
        load = 0.1 * pwm - np.interp(q, linear_plant().grid, linear_plant().gravity)
        assert state[4] == q - np.clip(load, -SLIP, SLIP) / (30.0 * np.exp(1.5 * q))
        assert list(state[:4]) == [0.2, 0.0, 0.2, 0.0]


@pytest.mark.parametrize("preload", [1.5, -1.01, float("nan")])
def test_a_preload_outside_the_slip_force_is_refused(preload):
    friction = AxisFriction(presliding_stiffness=30.0, presliding_force=SLIP)
    with pytest.raises(RcmKinError, match="preload"):
        rest_state(friction, linear_plant(), 0.2, 0.0, preload=preload)


@pytest.mark.parametrize("elements", [0.0, 2.5, 5.0, float("nan")])
def test_the_element_count_is_a_whole_number_up_to_the_state(elements):
    with pytest.raises(RcmKinError, match="presliding_elements"):
        AxisFriction(presliding_elements=elements)


@pytest.mark.parametrize("value, message", [("2.5", "whole number"), ("5.0", "outside"), ("0", "outside")])
def test_a_drive_file_with_a_bad_element_count_is_one_line(tmp_path, value, message):
    from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, load_drive_parameters

    text = DEFAULT_PARAMETERS.read_text()
    roll = text.index("\n[drive_train.roll]\n")
    assert "presliding_elements = 1.0" in text[roll:]
    text = text[:roll] + text[roll:].replace("presliding_elements = 1.0", f"presliding_elements = {value}", 1)
    path = tmp_path / "drive.toml"
    path.write_text(text)
    with pytest.raises(ParameterFileError, match=message) as raised:
        load_drive_parameters(path)
    assert "\n" not in str(raised.value) and raised.value.key == "presliding_elements"
    path.write_text(text.replace(f"presliding_elements = {value}", "presliding_elements = 3"))
    assert load_drive_parameters(path).drive_train["roll"].presliding_elements == 3.0


# --- the whole simulation against an independent plain-Python step --------------------------------

def plain_friction(v, J, h, F, B, static, coulomb, stribeck):
    """Moreau's implicit friction step, as the module notes state it."""
    p = J * v + h * F
    static = max(static, coulomb)
    if v == 0.0:
        if abs(p) <= h * static:
            return 0.0
        return (p - h * coulomb * np.sign(p)) / (J + h * B)
    f = coulomb + (static - coulomb) * math.exp(-(v / stribeck) ** 2)
    new = (p - h * f * np.sign(v)) / (J + h * B)
    return 0.0 if new * v <= 0.0 else new


def plain_run(fr: AxisFriction, plant: AxisPlant, pwm, period, state):
    """The drive train of the module notes stepped in plain Python: the rigid or two-mass
    (4 Gauss-Seidel sweeps) implicit step, N Iwan elements slipping at F_p 2 i / (N (N + 1))."""
    n, out = int(fr.presliding_elements), []
    substeps = max(1, int(math.ceil(period / SUBSTEP - 1e-9)))
    h = period / substeps
    slips = element_slips(n) * fr.presliding_force / SLIP
    x = list(state)
    for u in pwm:
        for _ in range(substeps):
            theta, w, q, v = x[:4]
            g = float(np.interp(q, plant.grid, plant.gravity))
            M = float(np.interp(q, plant.grid, plant.inertia))
            kp = fr.presliding_stiffness * math.exp(fr.presliding_slope * q) if fr.presliding_stiffness > 0 else 0.0
            spring = sum(kp / n * (q - z) for z in x[4:4 + n])
            if fr.cable_stiffness > 0:
                stretch, coupling = fr.cable_stiffness * (theta - q), fr.cable_damping + h * fr.cable_stiffness
                w1, v1 = w, v
                for _ in range(4):
                    w1 = plain_friction(w, plant.rotor_inertia, h, plant.input_gain * u - stretch + coupling * v1,
                                        plant.back_emf + fr.motor_viscous + coupling, fr.motor_coulomb,
                                        fr.motor_coulomb, 1.0)
                    v1 = plain_friction(v, M + fr.extra_inertia, h, stretch + coupling * w1 - g - spring,
                                        fr.viscous + coupling + h * kp, fr.static, fr.coulomb, fr.stribeck_velocity)
                w, v, theta = w1, v1, theta + h * w1
            else:
                v = plain_friction(v, M + fr.extra_inertia + plant.rotor_inertia, h,
                                   plant.input_gain * u - g - spring,
                                   fr.viscous + fr.motor_viscous + plant.back_emf + h * kp,
                                   fr.static + fr.motor_coulomb, fr.coulomb + fr.motor_coulomb, fr.stribeck_velocity)
                w = v
            q = q + h * v
            theta = q if fr.cable_stiffness <= 0 else theta
            for i in range(n):
                k = kp / n
                if k > 0 and abs(k * (q - x[4 + i])) > slips[i]:
                    x[4 + i] = q - math.copysign(slips[i], q - x[4 + i]) / k
            x[:4] = theta, w, q, v
        out.append(x[0])
    return np.array(out), np.array(x)


GRID = np.linspace(-1.0, 1.0, 201)
PLANT = AxisPlant(0.1, 0.6, 3e-3, GRID, 3.0 * np.sin(GRID), 0.5 + 0.1 * np.cos(GRID))
CASES = {
    "rigid": AxisFriction(extra_inertia=0.1, viscous=2.0, coulomb=0.3, static=0.5, stribeck_velocity=0.02,
                          presliding_stiffness=30.0, presliding_slope=1.0, presliding_force=0.6,
                          motor_coulomb=0.05, motor_viscous=0.1),
    "two_mass": AxisFriction(extra_inertia=0.1, viscous=2.0, coulomb=0.3, static=0.5, stribeck_velocity=0.02,
                             presliding_stiffness=30.0, presliding_slope=1.0, presliding_force=0.6,
                             cable_stiffness=400.0, cable_damping=0.5, motor_coulomb=0.05, motor_viscous=0.1),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_the_kernel_is_the_plain_python_step(case, n):
    """0.6 s of random held PWM from a preloaded rest: the compiled kernel's angle and final state
    are the plain-Python step's (to 1e-12 rad and rad/s; N = 1 is today's single spring); the
    spring slips on the way (the anchors move)."""
    fr = AxisFriction(**{**CASES[case].as_dict(), "presliding_elements": float(n)})
    rng = np.random.default_rng(n)
    pwm = np.repeat(rng.uniform(-60.0, 60.0, 12), 50)
    start = rest_state(fr, PLANT, 0.1, 3.0 * np.sin(0.1) / 0.1, preload=0.4)
    state = start.copy()
    angle = simulate_axis(fr, PLANT, pwm, 1e-3, state)
    plain_angle, plain_state = plain_run(fr, PLANT, pwm, 1e-3, start)
    np.testing.assert_allclose(angle, plain_angle, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state, plain_state, rtol=0, atol=1e-12)
    assert np.all(state[4:4 + n] != start[4:4 + n]) and np.all(state[4 + n:] == start[4 + n:])


def test_a_state_of_the_wrong_size_is_refused():
    with pytest.raises(RcmKinError, match=str(STATE_SIZE)):
        simulate_axis(AxisFriction(), linear_plant(), np.zeros(3), 1e-3, np.zeros(5))

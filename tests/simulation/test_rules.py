"""Each firmware rule of the compiled kernel (the C of :mod:`rcm_kin.simulation.kernel`) against
its one plain statement (:mod:`rcm_kin.firmware_rules`) on a few hundred seeded random inputs, the
clamping and saturation edges among them: a failure names the rule; the kernel's stick-slip axis
against the model's numba kernel (:func:`rcm_kin.dynamics.stick_slip.advance`) on random states.
The stick-slip axis's closed loop compiles the statements themselves
(:mod:`rcm_kin.dynamics.stick_slip`): held to them too."""

from __future__ import annotations

import functools
import hashlib
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from rcm_kin import firmware_rules as rules
from rcm_kin.dynamics import axis_friction, stick_slip
from rcm_kin.dynamics.axis_friction import MAX_ELEMENTS, STATE_SIZE, AxisFriction, substep_count
from rcm_kin.hardware import INSERTION_KP
from rcm_kin.simulation import kernel, kernel_forms

CASES = 400
needs_compiler = pytest.mark.skipif(shutil.which(os.environ.get("CC") or "cc") is None,
                                    reason="no C compiler (CC hidden): no compiled kernel")


def _grid(rng, n) -> np.ndarray:
    """An increasing grid of n points (degrees), unevenly spaced."""
    return np.cumsum(rng.uniform(0.5, 20.0, n)) - rng.uniform(0, 40)


@needs_compiler
def test_bilinear_twin_equals_the_rule():
    """Poses inside, on the grid points and beyond every edge (clamped), grids of 2 to 5 points."""
    rng = np.random.default_rng(11)
    for case in range(CASES):
        roll, pitch = _grid(rng, rng.integers(2, 6)), _grid(rng, rng.integers(2, 6))
        table = rng.normal(0, 100, (pitch.size, roll.size, rng.integers(1, 8)))
        if case % 4 == 0:                                   # on a grid point
            r, p = rng.choice(roll), rng.choice(pitch)
        elif case % 4 == 1:                                 # beyond an edge
            r = roll[0] - rng.uniform(0, 50) if rng.random() < 0.5 else roll[-1] + rng.uniform(0, 50)
            p = pitch[0] - rng.uniform(0, 50) if rng.random() < 0.5 else pitch[-1] + rng.uniform(0, 50)
        else:
            r, p = rng.uniform(roll[0] - 5, roll[-1] + 5), rng.uniform(pitch[0] - 5, pitch[-1] + 5)
        out = np.empty(table.shape[-1])
        kernel.bilinear(roll, pitch, table, r, p, out)
        np.testing.assert_array_equal(out, rules.bilinear(roll, pitch, table, r, p),
                                      err_msg=f"bilinear, case {case}")
    edge = np.empty(1)
    kernel.bilinear(np.array([0.0, 1.0]), np.array([0.0, 1.0]), np.arange(4.0).reshape(2, 2, 1), 9.0, -9.0, edge)
    assert edge[0] == 1.0                                   # clamped to roll 1, pitch 0


def _law(pid, with_ff, c1, c2, k, ff, E):
    """The integral laws of the controllers, as the readable ones write them."""
    if pid:
        return -(c1 + k * E + c2)
    u = -(c1 + c2 + k * E)
    return u + ff if with_ff else u


@needs_compiler
@pytest.mark.parametrize("pid", [False, True])
def test_conditional_integral_twin_equals_the_rule(pid):
    """The PID's law and the pitch's (with and without feedforward), commands inside the limit,
    beyond it pushed further out (the integral held) and beyond it pulled back (integrated)."""
    rng = np.random.default_rng(12 + pid)
    held = integrated = 0
    for case in range(CASES):
        with_ff = (not pid) and case % 2 == 1
        c1, c2, k = rng.normal(0, 80), rng.normal(0, 30), rng.uniform(0.01, 200)
        ff = rng.normal(0, 40) if with_ff else 0.0
        integral, error, period = rng.normal(0, 1), rng.normal(0, 5), rng.choice([1 / 400, 1 / 200, 0.01])
        limit = rng.choice([rng.uniform(1, 300), 150.0])

        law = functools.partial(_law, pid, with_ff, c1, c2, k, ff)
        if case % 5 == 0:                                   # the new command exactly at the limit
            limit = abs(law(integral + error * period))
        expected = rules.conditional_integral(integral, error, period, law, limit)
        got = kernel.conditional_integral(integral, error, period, limit, pid, with_ff, c1, c2, k, ff)
        assert got == expected, f"conditional_integral, case {case}: {got} != {expected}"
        held += expected[1] == integral and error != 0
        integrated += expected[1] != integral
    assert held > 20 and integrated > 20                    # both branches were exercised


@needs_compiler
def test_quantise_twin_equals_the_rule():
    """Whole counts of the firmware's resolutions, exact axes (count 0), noise counts, positions at
    half a count (round half to even)."""
    rng = np.random.default_rng(13)
    for case in range(CASES):
        count = rng.choice([0.009, 0.0135, 3e-5, 0.0, 1.0], 3)
        position = rng.uniform(-90, 90, 3)
        if case % 4 == 0:
            position = (rng.integers(-1000, 1000, 3) + 0.5) * count
        noise = np.round(rng.normal(0, 2, 3)) if case % 2 else np.zeros(3)
        out = np.empty(3)
        kernel.quantise(position, count, noise, out)
        np.testing.assert_array_equal(out, rules.quantise_axes(position, count, noise),
                                      err_msg=f"quantise, case {case}")


@needs_compiler
def test_velocity_estimate_twin_equals_the_rule():
    rng = np.random.default_rng(14)
    for case in range(CASES):
        measured, previous, filtered = rng.normal(0, 30, 3), rng.normal(0, 30, 3), rng.normal(0, 100, 3)
        period, a = rng.choice([1 / 400, 1 / 200, 0.01]), rng.choice([0.0, 0.9, rng.uniform(0, 1)])
        expected = rules.velocity_estimate(measured, previous, filtered, period, a)
        kernel.velocity_estimate(measured, previous, filtered, period, a)     # in place
        np.testing.assert_array_equal(filtered, expected, err_msg=f"velocity_estimate, case {case}")


@needs_compiler
@pytest.mark.parametrize("whole_counts", [False, True])
def test_saturate_twin_equals_the_rule(whole_counts):
    """Commands inside, at and beyond the limits, negative fractions (truncated toward zero)."""
    rng = np.random.default_rng(15 + whole_counts)
    for case in range(CASES):
        limit = rng.choice([100.0, 150.0, rng.uniform(1, 255)], 3)
        command = rng.normal(0, 150, 3)
        if case % 4 == 0:
            command = limit * rng.choice([-1.0, 1.0], 3)
        elif case % 4 == 1:
            command = rng.uniform(-1, 1, 3)
        out = np.empty(3)
        kernel.saturate(command, limit, whole_counts, out)
        np.testing.assert_array_equal(out, rules.saturate(command, limit, whole_counts),
                                      err_msg=f"saturate, case {case}")
        assert np.all(np.abs(out) <= limit)


@needs_compiler
def test_friction_feedforward_twin_equals_the_schedule_rule():
    """The sliding-friction feedforward of the friction-compensated controller, per axis, at
    reference velocities from rest to far beyond the ramp (tanh saturated), both signs. Within
    2 units in the last place, not to the bit: the kernel's tanh is the C library's, NumPy's its
    own vectorised one (they differ by 1 ulp at some arguments)."""
    from rcm_kin.control.friction import FrictionCompensation

    rng = np.random.default_rng(16)
    for case in range(CASES):
        amplitude, ramp = rng.uniform(0, 60, 2), rng.uniform(0.1, 20)
        rdot = rng.normal(0, 10 ** rng.uniform(-3, 3), 2) if case % 5 else np.zeros(2)
        expected = FrictionCompensation(amplitude, ramp).feedforward(rdot)
        got = [kernel.friction_feedforward(amplitude[i], ramp, rdot[i]) for i in range(2)]
        try:
            np.testing.assert_array_max_ulp(np.array(got), expected, maxulp=2)
        except AssertionError as exc:
            raise AssertionError(f"friction_feedforward, case {case}: {exc}") from None


@needs_compiler
def test_the_p_laws_twins_equal_the_rules():
    """The roll and pitch P law ``-Kp e`` and the insertion's ``Kp (r - y)``, to the bit."""
    rng = np.random.default_rng(17)
    for case in range(CASES):
        kp, error = rng.uniform(0, 300), rng.normal(0, 20)
        assert kernel.p_command(kp, error) == rules.p_command(kp, error), f"p_command, case {case}"
        reference, measured = rng.uniform(0.02, 0.2), rng.uniform(0.02, 0.2)
        kp = rng.choice([INSERTION_KP, rng.uniform(1e3, 1e5)])
        got = kernel.insertion_command(reference, measured, kp)
        assert got == rules.insertion_command(reference, measured, kp), f"insertion_command, case {case}"
    assert rules.insertion_command(0.081, 0.080, INSERTION_KP) == INSERTION_KP * (0.081 - 0.080)


def test_the_stick_slip_axis_compiles_the_rules_themselves():
    """Counts from a starting angle (the origin) and saturation, compiled by numba from the one
    statement: equal to the statement on scalars, and the readable loop's axes equal to it with
    the origin at zero."""
    rng = np.random.default_rng(18)
    for case in range(CASES):
        count = rng.choice([np.radians(0.009), np.radians(0.0135), 0.0])
        position, origin = rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5) if case % 2 else 0.0
        if case % 4 == 0 and count:
            position = origin + (rng.integers(-1000, 1000) + 0.5) * count      # half a count: to even
        assert stick_slip._quantise(position, count, 0.0, origin) == rules.quantise(position, count, 0.0, origin), \
            f"quantise with an origin, case {case}"
        command, limit = rng.normal(0, 150), rng.uniform(1, 255)
        assert stick_slip._saturate(command, limit, False) == rules.saturate(command, limit), f"saturate, case {case}"
        assert stick_slip._saturate(command, limit, True) == rules.saturate(command, limit, True)
    count = np.array([0.009, 0.0135, 3e-5])
    position = rng.uniform(-90, 90, 3)
    np.testing.assert_array_equal(rules.quantise_axes(position, count, np.zeros(3)),
                                  [rules.quantise(p, c) for p, c in zip(position, count)])
    assert rules.quantise(0.3004, 0.001, origin=0.1002) == 0.1002 + 200 * 0.001       # counted from the origin


def _random_axis(rng, case) -> tuple[np.ndarray, tuple, np.ndarray]:
    """A friction vector (rigid or two-mass drive, with or without stiction and presliding, 1 to
    MAX_ELEMENTS elements), the drive's (k_u, k_emf, J_m, gravity, inertia, pwm) and a state, its
    velocities at rest (exactly 0) in a third of the cases."""
    presliding = case % 3 != 0
    friction = AxisFriction(
        extra_inertia=rng.uniform(0, 2e-3), viscous=rng.uniform(0, 0.05), coulomb=rng.uniform(0, 0.4),
        static=rng.uniform(0, 0.6) if case % 2 else 0.0, stribeck_velocity=rng.uniform(0.002, 0.2),
        presliding_stiffness=rng.uniform(1, 80) if presliding else 0.0, presliding_slope=rng.uniform(-1, 1),
        presliding_force=rng.uniform(0, 0.3), cable_stiffness=rng.uniform(10, 1e4) if case % 4 < 2 else 0.0,
        cable_damping=rng.uniform(0, 0.1), motor_coulomb=rng.uniform(0, 0.1), motor_viscous=rng.uniform(0, 0.01),
        presliding_elements=float(rng.integers(1, MAX_ELEMENTS + 1)))
    drive = (rng.uniform(1e-3, 1e-2), rng.uniform(0, 0.05), rng.uniform(1e-4, 3e-3), rng.normal(0, 0.3),
             rng.uniform(1e-3, 5e-2), rng.uniform(-255, 255))
    state = rng.normal(0, 0.3, STATE_SIZE)
    state[4:] = state[2] + rng.normal(0, 2e-3, MAX_ELEMENTS)
    if case % 3 == 1:
        state[1] = state[3] = 0.0
    return friction.vector(), drive, state


@needs_compiler
def test_stick_slip_advance_twin_equals_the_numba_kernel():
    """The kernel's drive-train axis against ``stick_slip.advance`` over five periods from random
    states, every term of the model on and off: to the bit (both call the C library's ``exp``)."""
    rng = np.random.default_rng(19)
    for case in range(CASES):
        th, drive, state = _random_axis(rng, case)
        period = rng.choice([1 / 400, 1e-3, 0.01])
        substeps = substep_count(period)
        numba, c = state.copy(), state.copy()
        for _ in range(5):
            stick_slip.advance(th, *drive, numba, period, substeps)
            kernel.advance(th, *drive, c, period, substeps)
            np.testing.assert_array_equal(c, numba, err_msg=f"advance, case {case}")
    assert kernel.defines()["RK_COUPLING_SWEEPS"] == stick_slip.COUPLING_SWEEPS


def test_the_kernel_takes_the_python_constants_and_is_keyed_on_them(monkeypatch):
    """The C copies no number of the Python modules: the stick-slip state's layout, the law kinds
    and the plant kinds are ``#define`` lines written before it, part of the text the library is
    built and keyed from, so a changed constant builds a new library."""
    text = kernel.source()
    assert "#define RK_" not in kernel.C_SOURCE.read_text()
    expected = {"RK_STATE_SIZE": STATE_SIZE, "RK_MAX_ELEMENTS": MAX_ELEMENTS, "RK_THESIS": kernel_forms.THESIS,
                "RK_COUPLING_SWEEPS": axis_friction.COUPLING_SWEEPS, "RK_P": kernel_forms.P, "RK_PID": kernel_forms.PID,
                "RK_STATE_FEEDBACK": kernel_forms.STATE_FEEDBACK, "RK_DRIVE_TRAIN": kernel.DRIVE_TRAIN,
                "RK_SMOOTH": kernel.SMOOTH}
    assert kernel.defines() == expected
    for name, value in expected.items():
        assert f"#define {name} {value}\n" in text
    monkeypatch.setattr(axis_friction, "COUPLING_SWEEPS", axis_friction.COUPLING_SWEEPS + 1)
    assert kernel.library_key(kernel.source(), ["cc"]) != kernel.library_key(text, ["cc"])
    assert kernel.library_key(text, ["cc"]) != kernel.library_key(text, ["clang"])


@needs_compiler
def test_a_fresh_simulation_loads_no_numba():
    """The compiled closed loop runs without numba (nor SciPy, the gain schedule read from its cache):
    a fresh process that runs an experiment twice has neither loaded; the readable plant's step
    loads the numba model when it runs."""
    code = ("import sys; from rcm_kin.simulation import run_experiment; from rcm_kin.simulation.experiments import "
            "psm_plant_and_schedule; r = run_experiment('sine', 'scheduled', duration=0.5); "
            "print(r.engine, 'numba' in sys.modules, 'scipy' in sys.modules); "
            "plant = psm_plant_and_schedule()[0]; plant.step(plant.initial([0, 0, 0.1]), [0, 0, 0]); "
            "print('numba' in sys.modules)")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
            for _ in range(2)]                   # the first may design and cache the schedule (SciPy)
    assert runs[0][:2] == ["compiled", "False"]
    assert runs[1] == ["compiled", "False", "False", "True"]


@needs_compiler
def test_the_kernel_library_is_cached_checked_and_rebuilt_once(tmp_path, monkeypatch):
    """The kernel goes to the compiled-function cache with its checksum file, is loaded from it by a
    new process (here: a cleared memo), and one damaged there is deleted and built anew with one
    warning (:func:`rcm_kin.symbolic.compiled.build_library`)."""
    from rcm_kin.errors import RcmKinWarning

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setattr(kernel, "_LOADED", {})
    assert kernel.available()
    (built,) = (tmp_path / "rcm-kin" / "casadi").glob("rcm_kin_loop_*.so")
    assert built.with_name(built.name + ".sha256").read_text().split()[1] == kernel.library_key(
        kernel.source(), [os.environ.get("CC") or "cc"])
    damaged = built.with_name("damaged")
    damaged.write_bytes(built.read_bytes()[:1000])                  # truncated (by another process: this one
    damaged.replace(built)                                          # has the library mapped)
    monkeypatch.setattr(kernel, "_LOADED", {})
    with pytest.warns(RcmKinWarning, match="does not match its SHA-256") as caught:
        library = kernel.library()
    assert len(caught) == 1 and library.rk_p_command(2.0, 3.0) == -6.0
    recorded = built.with_name(built.name + ".sha256").read_text().split()[0]      # the rebuilt file itself:
    assert hashlib.sha256(built.read_bytes()).hexdigest() == recorded              # dlopen reuses the old map

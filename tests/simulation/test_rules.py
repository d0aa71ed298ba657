"""Each firmware rule of the compiled kernel (:mod:`rcm_kin.simulation.kernel`) against its one
plain statement (:mod:`rcm_kin.firmware_rules`) on a few hundred seeded random inputs, the
clamping and saturation edges among them: a failure names the rule. The stick-slip axis's
closed loop compiles the statements themselves (:mod:`rcm_kin.dynamics.stick_slip`): held to
them too."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from rcm_kin import firmware_rules as rules
from rcm_kin.dynamics import stick_slip
from rcm_kin.hardware import INSERTION_KP
from rcm_kin.simulation import kernel

CASES = 400


def _grid(rng, n) -> np.ndarray:
    """An increasing grid of n points (degrees), unevenly spaced."""
    return np.cumsum(rng.uniform(0.5, 20.0, n)) - rng.uniform(0, 40)


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


def test_velocity_estimate_twin_equals_the_rule():
    rng = np.random.default_rng(14)
    for case in range(CASES):
        measured, previous, filtered = rng.normal(0, 30, 3), rng.normal(0, 30, 3), rng.normal(0, 100, 3)
        period, a = rng.choice([1 / 400, 1 / 200, 0.01]), rng.choice([0.0, 0.9, rng.uniform(0, 1)])
        expected = rules.velocity_estimate(measured, previous, filtered, period, a)
        kernel.velocity_estimate(measured, previous, filtered, period, a)     # in place
        np.testing.assert_array_equal(filtered, expected, err_msg=f"velocity_estimate, case {case}")


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


def test_the_cached_kernels_are_keyed_on_the_sources_they_inline():
    """A cached kernel is keyed on its own file only (numba's cache): one that freezes another
    module's constant (the law kinds of kernel_forms) or inlines its code (the stick-slip model,
    the rules) is built in a closure over a hash of those sources, and no top-level kernel reads
    such a constant."""
    import hashlib
    import inspect
    from pathlib import Path

    from rcm_kin import firmware_rules
    from rcm_kin.simulation import kernel_forms

    sources = hashlib.sha256(b"".join(Path(m.__file__).read_bytes()
                                      for m in (stick_slip, kernel_forms, firmware_rules))).hexdigest()
    assert kernel.SOURCES == sources
    for fn in (kernel.command, kernel.gain_scheduled, kernel.plant_step, kernel.plant_steps, kernel.run):
        keys = [c.cell_contents for c in fn.py_func.__closure__ if isinstance(c.cell_contents, str)]
        assert keys == [sources], fn.py_func.__name__
    keys = [c.cell_contents for c in stick_slip._run_closed.py_func.__closure__ if isinstance(c.cell_contents, str)]
    assert keys == [hashlib.sha256(Path(firmware_rules.__file__).read_bytes()).hexdigest()]
    kinds = {"P", "PID", "STATE_FEEDBACK", "THESIS", "INSERTION_KP", "FIRMWARE_SCALE"}
    for name, fn in inspect.getmembers(kernel, lambda f: hasattr(f, "py_func")):
        if fn.py_func.__closure__ is None:                  # a top-level kernel, cached on kernel.py alone
            assert not kinds & set(fn.py_func.__code__.co_names), f"{name} freezes another module's constant"

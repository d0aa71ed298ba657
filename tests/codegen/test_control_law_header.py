"""gain_schedule.h's ``rcm_control_law`` runs the simulator's law: compiled with the strict flags and
fed what the simulated firmware saw, tick for tick, it sends the commands of
:class:`~rcm_kin.simulation.controllers.StateFeedbackController` and carries its pitch integral."""

from __future__ import annotations

import ctypes
import itertools
import json
import os
import shutil
import subprocess
from dataclasses import dataclass, field, replace

import numpy as np
import pytest

from rcm_kin.codegen.firmware_export import gains_payload, header_text, write_gain_schedule
from rcm_kin.control.friction import FrictionCompensation
from rcm_kin.control.schedule_file import read_schedule_file
from rcm_kin.firmware_rules import velocity_estimate
from rcm_kin.simulation.controllers import Sample, StateFeedbackController
from rcm_kin.simulation.experiments import (
    closed_loop,
    experiment_reference,
    psm_plant_and_schedule,
    psm_schedule,
    start_hold,
)
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import firmware_units

STRICT = ["-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror"]
COMPILER = shutil.which(os.environ.get("CC") or "cc")
needs_compiler = pytest.mark.skipif(COMPILER is None, reason="no C compiler (CC hidden): the fallback run")
FLAGS = ("scheduled", "gravity", "track_velocity", "friction")
DURATION = 2.0                                         # s of the sinusoid (after the loop's 1 s settle)

HARNESS = r"""
#include "gain_schedule.h"

int law_tick(const double *y, const double *v, const double *r, const double *rdot, const double *racc,
             double period, double limit, double *integral, double *pwm)
{
    return rcm_control_law(y, v, r, rdot, racc, period, limit, integral, pwm);
}
"""


def compiled_law(schedule, folder, scheduled=True, track_velocity=True, gravity=True, friction=True):
    """``law_tick`` of the header written for these options, compiled with the strict flags."""
    folder.mkdir(parents=True, exist_ok=True)
    write_gain_schedule(schedule, folder, gravity_feedforward=gravity, friction_feedforward=friction,
                        scheduled=scheduled, track_velocity=track_velocity)
    (folder / "harness.c").write_text(HARNESS)
    library = folder / "law.so"
    run = subprocess.run([COMPILER, *STRICT, "-O2", "-fPIC", "-shared", str(folder / "harness.c"), "-o",
                          str(library), "-lm"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    function = ctypes.CDLL(str(library)).law_tick
    pointer = ctypes.POINTER(ctypes.c_double)
    function.argtypes = [pointer] * 5 + [ctypes.c_double, ctypes.c_double, pointer, pointer]
    function.restype = ctypes.c_int
    return function


def c_tick(function, sample: Sample, integral: float):
    """``(pwm (2,), integral, held)`` of one C tick on ``sample`` from the pitch integral ``integral``."""
    pointer = ctypes.POINTER(ctypes.c_double)
    arrays = [np.ascontiguousarray(a[:2], dtype=float) for a in (
        sample.position, sample.velocity, sample.reference, sample.reference_velocity,
        sample.reference_acceleration)]
    state, pwm = ctypes.c_double(integral), np.full(2, np.nan)
    held = function(*(a.ctypes.data_as(pointer) for a in arrays), sample.period, float(sample.pwm_limit[1]),
                    ctypes.byref(state), pwm.ctypes.data_as(pointer))
    return pwm, state.value, held


@dataclass(frozen=True)
class Recorder:
    """A controller that runs ``law`` and keeps every (sample, memory before, command, memory after)."""

    law: StateFeedbackController
    log: list = field(default_factory=list)

    @property
    def name(self) -> str:
        return self.law.name

    def initial_memory(self, hold=None):
        return self.law.initial_memory(hold)

    def command(self, memory, sample):
        u, after = self.law.command(memory, sample)
        self.log.append((sample, memory.copy(), u.copy(), after.copy()))
        return u, after


def modified_schedule(schedule):
    """Stiff constant gains and a larger friction compensation: every branch of the law, and a
    pitch that saturates."""
    return replace(schedule, k_roll=np.broadcast_to([300.0, -5.0], schedule.k_roll.shape).copy(),
                   k_pitch=np.broadcast_to([150.0, -1.0, 300.0], schedule.k_pitch.shape).copy(),
                   friction=FrictionCompensation((12.0, 9.0), 3.0))


def run_both(tmp_path, schedule, scheduled, settings):
    """The closed loop (readable engine, sinusoid) of the matching controller, recorded, and the C
    law fed the run tick for tick (the same commands, integrals and anti-windup ticks). Returns the
    ticks (settle included) on which the anti-windup held the integral."""
    plant, _ = psm_plant_and_schedule(fast=False)
    reference = experiment_reference("sine", settings.period, DURATION)
    hold = start_hold(reference)
    law = StateFeedbackController(schedule, scheduled=scheduled, gravity=True, track_velocity=True, friction=True)
    recorder = Recorder(law)
    result = closed_loop(plant, recorder, reference, settings, hold=hold, fast=False)
    n = result.time.size
    settle = len(recorder.log) - n
    assert settle == round(1.0 / settings.period)                   # the loop's 1 s settle before tick 0
    np.testing.assert_array_equal(np.array([u for _, _, u, _ in recorder.log[settle:]]), result.command)

    # what tick k >= 0 saw, rebuilt from the logged run: the measured angles, the velocity estimate
    # of them (from the last settle reading and its estimate), the reference and its derivatives
    first, last = recorder.log[settle][0], recorder.log[settle - 1][0]
    previous, filtered = last.position, last.velocity
    rdot, racc = firmware_units(reference.velocity), firmware_units(reference.acceleration)
    rebuilt = []
    for k in range(n):
        filtered = velocity_estimate(result.measured[k], previous, filtered, settings.period, settings.roll_filter)
        rebuilt.append(Sample(result.measured[k], filtered, result.reference[k], rdot[k], racc[k], settings.period,
                              settings.pwm_limit))
        previous = result.measured[k]
    for (sample, *_), again in zip(recorder.log[settle:], rebuilt):
        for name in ("position", "velocity", "reference", "reference_velocity", "reference_acceleration"):
            np.testing.assert_array_equal(getattr(again, name), getattr(sample, name), err_msg=name)
    np.testing.assert_array_equal(first.position, result.measured[0])

    function = compiled_law(schedule, tmp_path / f"law_{scheduled}", scheduled=scheduled)
    integral = float(law.initial_memory(hold.within(settings.pwm_limit))[0])
    assert integral == recorder.log[0][1][0]
    samples = [s for s, *_ in recorder.log[:settle]] + rebuilt      # the settle as the firmware saw it, then the run
    python_held, c_held, commands = [], [], []
    for k, (sample, (_, before, u, after)) in enumerate(zip(samples, recorder.log)):
        pwm, integral, held = c_tick(function, sample, integral)
        commands.append(pwm)
        np.testing.assert_allclose(pwm, u[:2], rtol=0, atol=1e-9, err_msg=f"tick {k - settle}")
        np.testing.assert_allclose(integral, after[0], rtol=0, atol=1e-9, err_msg=f"integral, tick {k - settle}")
        c_held.append(bool(held))
        python_held.append(after[0] == before[0] and sample.reference[1] != sample.position[1])
    np.testing.assert_allclose(np.array(commands[settle:]), result.command[:, :2], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(c_held, python_held)
    return np.array(c_held)


@needs_compiler
@pytest.mark.parametrize("scheduled", [True, False], ids=["scheduled", "fixed"])
def test_c_law_runs_the_simulated_loop_tick_for_tick(tmp_path, scheduled):
    """The shipped schedule with both feedforwards: the C command of every tick (settle included)
    equals the simulator's to 1e-9 counts and its integral the controller's memory."""
    run_both(tmp_path, psm_schedule(), scheduled, FirmwareSettings())


@needs_compiler
def test_c_law_runs_the_shipped_tuned_design_tick_for_tick(tmp_path):
    """The shipped tuned design (urdf/psm_tuned/gains.json, read back as the simulator reads it):
    the exported header reproduces the tuned law tick for tick."""
    loaded = read_schedule_file()
    assert loaded.flags == {"scheduled": True, "gravity": True, "track_velocity": True, "friction": True}
    run_both(tmp_path, loaded.schedule, True, FirmwareSettings())


@needs_compiler
@pytest.mark.parametrize("scheduled", [True, False], ids=["scheduled", "fixed"])
def test_c_law_holds_the_integral_where_the_simulator_does(tmp_path, scheduled):
    """Stiff gains and a pitch limit of 110 counts: the pitch saturates, the conditional
    anti-windup holds the integral on the same ticks in C as in the simulator."""
    settings = FirmwareSettings(pwm_limit=np.array([100.0, 110.0, 100.0]))
    held = run_both(tmp_path, modified_schedule(psm_schedule()), scheduled, settings)
    assert held.sum() >= 5, "the anti-windup branch was not exercised"


@needs_compiler
@pytest.mark.parametrize("options", list(itertools.product([False, True], repeat=4)),
                         ids=lambda o: "-".join(f for f, on in zip(FLAGS, o) if on) or "none")
def test_every_option_of_the_c_law_on_random_samples(tmp_path, options):
    """Each of the 16 headers (scheduled, gravity, track_velocity, friction) against the matching
    controller on random firmware samples, poses inside and outside the grid, anti-windup or not."""
    flags = dict(zip(FLAGS, options))
    schedule = modified_schedule(psm_schedule())
    function = compiled_law(schedule, tmp_path, scheduled=flags["scheduled"], track_velocity=flags["track_velocity"],
                            gravity=flags["gravity"], friction=flags["friction"])
    law = StateFeedbackController(schedule, **flags)
    rng = np.random.default_rng(7)
    held = 0
    for _ in range(300):
        sample = Sample(np.r_[rng.uniform(-40, 40, 2), 0.08], np.r_[rng.uniform(-30, 30, 2), 0.0],
                        np.r_[rng.uniform(-25, 25, 2), 0.08], np.r_[rng.uniform(-20, 20, 2), 0.0],
                        np.r_[rng.uniform(-50, 50, 2), 0.0], 0.0025, np.array([100.0, rng.uniform(20, 400), 100.0]))
        memory = np.array([rng.uniform(-2, 2)])
        u, after = law.command(memory, sample)
        pwm, integral, c_held = c_tick(function, sample, float(memory[0]))
        np.testing.assert_allclose(pwm, u[:2], rtol=1e-13, atol=1e-9)
        np.testing.assert_allclose(integral, after[0], rtol=0, atol=1e-12)
        assert bool(c_held) == (after[0] == memory[0])
        held += c_held
    assert 0 < held < 300                                       # both branches


@pytest.mark.parametrize("options", list(itertools.product([False, True], repeat=4)),
                         ids=lambda o: "-".join(f for f, on in zip(FLAGS, o) if on) or "none")
def test_gains_json_and_header_state_the_law(tmp_path, options):
    """gains.json's "controller" entry and the header's RCM_LAW_* defines carry the same options;
    gravity and friction follow the exported feedforwards; the contract keys stay."""
    flags = dict(zip(FLAGS, options))
    schedule = psm_schedule()
    write_gain_schedule(schedule, tmp_path, gravity_feedforward=flags["gravity"],
                        friction_feedforward=flags["friction"], scheduled=flags["scheduled"],
                        track_velocity=flags["track_velocity"])
    payload = json.loads((tmp_path / "gains.json").read_text())
    entry = payload["controller"]
    assert {k: entry[k] for k in FLAGS} == flags and entry["function"] == "rcm_control_law"
    assert ("w = v - rdot" in entry["law"]) == flags["track_velocity"]
    assert ("u_hold(r)" in entry["law"]) == flags["gravity"] and ("tanh" in entry["law"]) == flags["friction"]
    assert ("at the measured pose" in entry["law"]) == flags["scheduled"]
    assert {"roll_deg", "pitch_deg", "k_roll", "k_pitch", "points", "law", "units"} <= set(payload)
    assert ("u_hold" in payload) == flags["gravity"] and ("friction_feedforward" in payload) == flags["friction"]
    text = (tmp_path / "gain_schedule.h").read_text()
    assert text == header_text(schedule, flags["gravity"], flags["friction"], flags["scheduled"],
                               flags["track_velocity"])
    for name, on in flags.items():
        assert text.count(f"#define RCM_LAW_{name.upper()} {int(on)}\n") == 1
    assert text.count("static inline int rcm_control_law(") == 1
    assert ("rcm_holding_pwm(reference_deg" in text) == flags["gravity"]


def test_defaults_keep_the_existing_calls():
    """The old calls write what they did, plus the law: scheduled, velocity error, no feedforwards."""
    schedule = psm_schedule()
    entry = gains_payload(schedule)["controller"]
    assert {k: entry[k] for k in FLAGS} == {"scheduled": True, "gravity": False, "track_velocity": True,
                                            "friction": False}
    text = header_text(schedule, True)
    assert "#define RCM_LAW_SCHEDULED 1" in text and "#define RCM_LAW_GRAVITY 1" in text
    assert "#define RCM_LAW_FRICTION 0" in text and "math.h" not in text

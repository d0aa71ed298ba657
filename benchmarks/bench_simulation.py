"""Simulated seconds per wall-clock second of the 400 Hz closed loop (PSM plant, encoder/PWM
quantisation, firmware velocity estimate), and the cost of one plant period, same run:

- the shipped plant, :class:`~rcm_kin.simulation.plant.DriveTrainPlant`: the CasADi mass
  matrix and bias once per period, three stick-slip axes advanced by numba (4 substeps; in the
  compiled engine by the kernel's C twin);
- the smooth model as before the drive trains: ``period_map(driven_dynamics(psm, params).forward,
  period)`` (CasADi RK4, 4 substeps), also run in the closed loop (the drive trains stripped
  from the shipped parameters, so ``run_experiment`` builds the smooth plant);
- the plain Pinocchio call a user would write for one period: 4 substeps of semi-implicit
  Euler on the reduced model (the closed chain as mimic joints), ``pin.crba`` +
  ``pin.nonLinearEffects`` and a 3 x 3 solve with the drive's terms (``pin.aba`` does not take
  mimic joints in Pinocchio 4; the gravity offsets of the drive parameters are left out), and
  for scale ``pin.aba`` on the open tree (no loop closure: a cost floor, not the same physics).

    python benchmarks/bench_simulation.py
Targets: at least 10 simulated seconds per wall-clock second for every controller (the report's
experiments and a parameter sweep stay interactive on 2 cores); issue 16: 200 on the shipped
plant's fast engine, the whole loop in one compiled kernel (:mod:`rcm_kin.simulation.compiled_loop`),
measured here in the same run as the readable reference loop (``loop.simulate`` of the readable
controller classes on ``DriveTrainPlant``), which is also its fallback without a C compiler; each
controller's compiled run is checked against the readable one tick for tick (issue 24).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import best_of, per_call, report  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.state_space import drive_constants, driven_dynamics  # noqa: E402
from rcm_kin.hardware import FIRMWARE_PERIOD, PWM_LIMIT  # noqa: E402
from rcm_kin.model.reduced import tree_configuration  # noqa: E402
from rcm_kin.simulation.controllers import CONTROLLERS, Sample, make_controller  # noqa: E402
from rcm_kin.simulation.experiments import experiment_reference, psm_plant_and_schedule, run_experiment, start_hold  # noqa: E402
from rcm_kin.simulation.loop import simulate  # noqa: E402
from rcm_kin.simulation.plant import period_map  # noqa: E402

SUBSTEPS = 4


def pinocchio_period(robot, params, period: float = FIRMWARE_PERIOD, substeps: int = SUBSTEPS):
    """``(q, v, u) -> (q, v)`` over one period: semi-implicit Euler on the reduced model,
    the driven joints moving and the instrument joints held (reduced q = actuated q)."""
    model, data = robot.reduced, robot.reduced.createData()
    i = robot.reduced_q_actuated[:3]
    d = drive_constants(params)
    h = period / substeps

    def step(q, v, u):
        q, v = q.copy(), v.copy()
        for _ in range(substeps):
            M = pin.crba(model, data, q, pin.Convention.WORLD)[np.ix_(i, i)]
            M = np.triu(M) + np.triu(M, 1).T + np.diag(d.reflected_inertia)
            tau = d.input_gain * u - d.damping * v[i] - d.coulomb * np.tanh(v[i] / d.coulomb_velocity)
            v[i] += h * np.linalg.solve(M, tau - pin.nonLinearEffects(model, data, q, v)[i])
            q[i] += h * v[i]
        return q, v
    return step


def aba_period(robot, params, period: float = FIRMWARE_PERIOD, substeps: int = SUBSTEPS):
    """The same loop with ``pin.aba`` on the open tree (loops not closed): cost only."""
    model, data = robot.tree, robot.tree.createData()
    i = robot.tree_q_actuated[:3]
    d = drive_constants(params)
    h = period / substeps

    def step(q, v, u):
        q, v = q.copy(), v.copy()
        for _ in range(substeps):
            tau = np.zeros(model.nv)
            tau[i] = d.input_gain * u - d.damping * v[i] - d.coulomb * np.tanh(v[i] / d.coulomb_velocity)
            v += h * pin.aba(model, data, q, v, tau)
            q = pin.integrate(model, q, h * v)
        return q, v
    return step


def main() -> None:
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    psm, params = load_robot("psm"), load_drive_parameters()
    smooth_params = replace(params, drive_train={})                  # the smooth model, as before
    plant, schedule = psm_plant_and_schedule()
    position, u = np.array([0.1, -0.1, 0.08]), np.array([-20.0, -80.0, 5.0])
    x = plant.initial(position)
    smooth = period_map(driven_dynamics(psm, params).forward, FIRMWARE_PERIOD, SUBSTEPS)
    xs = np.r_[position, np.zeros(3)]
    plain = pinocchio_period(psm, params)
    q_red, v_red = psm.to_reduced(np.r_[position, np.zeros(psm.nq - 3)]), np.zeros(psm.reduced.nv)
    tree_aba = aba_period(psm, params)
    q_tree = tree_configuration(psm, np.r_[position, np.zeros(psm.nq - 3)])
    v_tree = np.zeros(psm.tree.nv)
    sample = Sample(np.array([5.0, -5.0, 0.08]), np.array([1.0, 2.0, 0.0]), np.array([6.0, -4.0, 0.08]),
                    np.zeros(3), np.zeros(3), FIRMWARE_PERIOD, PWM_LIMIT)
    scheduled = make_controller("scheduled-gravity", schedule)
    memory = scheduled.initial_memory()
    shipped = per_call(lambda: plant.step(x, u), 2000)
    rows = [(f"plant: one 2.5 ms period, {type(plant).__name__} (numba stick-slip + CasADi M/bias)", shipped),
            ("plant: one period, smooth period_map (CasADi RK4 x4)", per_call(lambda: smooth(xs, u), 2000)),
            ("plant: one period, plain Pinocchio crba + nle + solve, Euler x4 (reduced)",
             per_call(lambda: plain(q_red, v_red, u), 2000)),
            ("plant: one period, plain pin.aba, Euler x4 (open tree, cost only)",
             per_call(lambda: tree_aba(q_tree, v_tree, u), 2000)),
            ("controller: scheduled-gravity, one tick", per_call(lambda: scheduled.command(memory, sample), 2000))]
    report(rows)
    print("ratio to the shipped plant's period: " + ", ".join(
        f"{label} {seconds / shipped:.2f}" for label, (_, seconds) in zip(("smooth RK4", "Pinocchio", "open-tree ABA"),
                                                                          rows[1:4])))
    compiled_plant, _ = psm_plant_and_schedule(fast=True)
    compiled_smooth = psm_plant_and_schedule(smooth_params, fast=True)[0]
    report([(f"compiled engine: one plant period, {type(compiled_plant).__name__}.step (C kernel + C M/bias, "
             "from Python)", per_call(lambda: compiled_plant.step(x, u), 2000)),
            (f"compiled engine: one smooth period, {type(compiled_smooth).__name__}.step (C RK4, from Python)",
             per_call(lambda: compiled_smooth.step(xs, u), 2000))])
    closed_loop(plant, schedule, smooth_params)


def tick_for_tick(compiled, readable) -> bool:
    """Whether two runs agree tick for tick: the readings and sent PWM identical, the positions
    within 1e-9 rad (m), the commands within 1e-9 counts (as tests/simulation hold them)."""
    return bool(np.array_equal(compiled.measured, readable.measured) and np.array_equal(compiled.pwm, readable.pwm)
                and np.allclose(compiled.position[:, :2], readable.position[:, :2], rtol=0, atol=np.degrees(1e-9))
                and np.allclose(compiled.position[:, 2], readable.position[:, 2], rtol=0, atol=1e-9)
                and np.allclose(compiled.command, readable.command, rtol=0, atol=1e-9))


def closed_loop(plant, schedule, smooth_params, duration: float = 6.0) -> None:
    """Real-time factor (simulated s per wall s) per controller, the sine experiment, same run:
    the compiled loop (``run_experiment``, default) and the readable reference loop on the shipped
    drive-train plant, and whether they agree tick for tick; the smooth plant's compiled loop and
    reference loop (``run_experiment(fast=False)``)."""
    simulated = duration + 1.0                                        # + 1 s settling
    reference = experiment_reference("sine", FIRMWARE_PERIOD, duration)
    print(f"\nclosed loop, sine {duration:g} s + 1 s settling at 400 Hz: simulated s per wall s (best of 3); "
          "target >= 200 for the compiled loop")
    header = (f"{'controller':18}  {'compiled loop':>13}  {'reference':>10}  {'compiled/ref':>12}  {'us/tick':>7}  "
              f"{'tick for tick':>13}  {'smooth compiled':>15}  {'smooth ref':>10}")
    print(header)
    worst = worst_smooth = float("inf")
    equal = True
    hold = start_hold(reference)                    # every run from the steady hold, as run_experiment
    for name in CONTROLLERS:
        law = make_controller(name, schedule)
        runs = {
            "compiled": lambda: run_experiment("sine", name, duration=duration),
            "reference": lambda: simulate(plant.step, law, reference, initial=plant.initial, hold=hold),
            "smooth compiled": lambda: run_experiment("sine", name, duration=duration, params=smooth_params),
            "smooth ref": lambda: run_experiment("sine", name, duration=duration, params=smooth_params, fast=False),
        }
        run_experiment("sine", name, duration=0.2)                               # warm-up (builds, loads)
        run_experiment("sine", name, duration=0.2, params=smooth_params)
        run_experiment("sine", name, duration=0.2, params=smooth_params, fast=False)
        factor = {key: simulated / best_of(run) for key, run in runs.items()}
        compiled = runs["compiled"]()
        same = compiled.engine == "compiled" and tick_for_tick(compiled, runs["reference"]())
        equal = equal and same
        worst = min(worst, factor["compiled"])
        print(f"{name:18}  {factor['compiled']:11.0f} x  {factor['reference']:8.1f} x  "
              f"{factor['compiled'] / factor['reference']:10.0f} x  {1e6 * FIRMWARE_PERIOD / factor['compiled']:7.2f}"
              f"  {'equal' if same else 'DIFFERS':>13}  {factor['smooth compiled']:13.0f} x  "
              f"{factor['smooth ref']:8.1f} x")
        worst_smooth = min(worst_smooth, factor["smooth compiled"])
    print(f"slowest compiled loop on the shipped plant: {worst:.0f} x real time "
          f"({'meets' if worst >= 200 else 'MISSES'} the 200 x target); on the smooth model {worst_smooth:.0f} x; "
          f"compiled and readable loops {'equal tick for tick' if equal else 'DIFFER'} for every controller")


if __name__ == "__main__":
    main()

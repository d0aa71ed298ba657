"""Simulated seconds per wall-clock second of the 400 Hz closed loop (PSM plant, encoder/PWM
quantisation, firmware velocity estimate), and the cost of one plant period, same run:

- the shipped plant, :class:`~rcm_kin.simulation.plant.DriveTrainPlant`: the CasADi mass
  matrix and bias once per period, three stick-slip axes advanced by numba (4 substeps);
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
plant's fast path, which is the whole loop in one compiled kernel
(:mod:`rcm_kin.simulation.compiled_loop`), measured here in the same run as the plain reference
loop (``loop.simulate`` of the readable controller classes on ``DriveTrainPlant``) and the
per-tick fast path it falls back to without a C compiler (:mod:`rcm_kin.simulation.fast_path`).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from common import best_of, per_call, report  # noqa: E402

from rcm_kin import load_robot  # noqa: E402
from rcm_kin.model.reduced import tree_configuration  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.state_space import drive_constants, driven_dynamics  # noqa: E402
from rcm_kin.hardware import FIRMWARE_PERIOD, PWM_LIMIT  # noqa: E402
from rcm_kin.simulation.controllers import CONTROLLERS, Sample, make_controller  # noqa: E402
from rcm_kin.simulation.experiments import (experiment_reference, psm_plant_and_schedule, run_experiment,  # noqa: E402
                                            start_hold)
from rcm_kin.simulation.fast_path import compiled_period_map, fast_controller, fast_plant  # noqa: E402
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
    per_tick_plant = fast_plant(plant)
    fast_smooth = compiled_period_map(smooth)
    fast_scheduled = fast_controller(scheduled)
    report([(f"fast path: one plant period, {type(compiled_plant).__name__}.step (numba + C M/bias, from Python)",
             per_call(lambda: compiled_plant.step(x, u), 2000)),
            ("per-tick fast path: drive-train plant period (compiled M/bias, buffered calls)",
             per_call(lambda: per_tick_plant.step(x, u), 2000)),
            ("fast path: smooth period_map compiled, buffered call", per_call(lambda: fast_smooth(xs, u), 2000)),
            ("per-tick fast path: scheduled-gravity tick on stacked tables",
             per_call(lambda: fast_scheduled.command(memory, sample), 2000))])
    closed_loop(plant, per_tick_plant, schedule, smooth_params)



def closed_loop(plant, per_tick_plant, schedule, smooth_params, duration: float = 6.0) -> None:
    """Real-time factor (simulated s per wall s) per controller, the sine experiment, same run:
    the compiled loop (``run_experiment``, default), the per-tick fast path (its fallback) and
    the plain reference loop on the shipped drive-train plant; the smooth plant's compiled loop
    and reference loop (``run_experiment(fast=False)``)."""
    simulated = duration + 1.0                                        # + 1 s settling
    reference = experiment_reference("sine", FIRMWARE_PERIOD, duration)
    print(f"\nclosed loop, sine {duration:g} s + 1 s settling at 400 Hz: simulated s per wall s (best of 3); "
          "target >= 200 for the compiled loop")
    header = (f"{'controller':18}  {'compiled loop':>13}  {'per-tick fast':>13}  {'reference':>10}  "
              f"{'compiled/ref':>12}  {'us/tick':>7}  {'smooth compiled':>15}  {'smooth ref':>10}")
    print(header)
    worst = worst_smooth = float("inf")
    hold = start_hold(reference)                    # every run from the steady hold, as run_experiment
    for name in CONTROLLERS:
        law = make_controller(name, schedule)
        runs = {
            "compiled": lambda: run_experiment("sine", name, duration=duration),
            "per-tick": lambda: simulate(per_tick_plant.step, fast_controller(law), reference,
                                         initial=per_tick_plant.initial, hold=hold),
            "reference": lambda: simulate(plant.step, law, reference, initial=plant.initial, hold=hold),
            "smooth compiled": lambda: run_experiment("sine", name, duration=duration, params=smooth_params),
            "smooth ref": lambda: run_experiment("sine", name, duration=duration, params=smooth_params, fast=False),
        }
        run_experiment("sine", name, duration=0.2)                               # warm-up (builds, loads)
        run_experiment("sine", name, duration=0.2, params=smooth_params)
        run_experiment("sine", name, duration=0.2, params=smooth_params, fast=False)
        factor = {key: simulated / best_of(run) for key, run in runs.items()}
        worst = min(worst, factor["compiled"])
        print(f"{name:18}  {factor['compiled']:11.0f} x  {factor['per-tick']:11.1f} x  {factor['reference']:8.1f} x  "
              f"{factor['compiled'] / factor['reference']:10.0f} x  {1e6 * FIRMWARE_PERIOD / factor['compiled']:7.2f}"
              f"  {factor['smooth compiled']:13.0f} x  {factor['smooth ref']:8.1f} x")
        worst_smooth = min(worst_smooth, factor["smooth compiled"])
    print(f"slowest compiled loop on the shipped plant: {worst:.0f} x real time "
          f"({'meets' if worst >= 200 else 'MISSES'} the 200 x target); on the smooth model {worst_smooth:.0f} x")


if __name__ == "__main__":
    main()

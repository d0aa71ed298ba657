"""Cost of the roll drive-train identification: the whole ``identify`` on the shared logs, and
one model evaluation on the six roll-step logs next to the smooth model's CasADi RK4 in a Python
loop over the same simulated time, same run.

    python benchmarks/bench_identification.py [--data DIR] [--repeats N] [--no-cv]
Target (issue): the whole identify of the roll on the shared logs, cross-validation included (its
inner folds and left-out bands too), under 3 minutes on 2 cores. The fit and its folds run on a pool
of two processes; the model evaluations the main process makes are counted and timed by wrapping
``drive_train.residuals`` (a counter, negligible next to a 3 ms evaluation; the pool's own are not
seen). After the cross-validated run, per step log: ``predict_band`` (the file's band, what
``predict --band`` computes) beside ``predict_file`` (the plain point prediction), in-process, best
of 3, with the identified set and its folds.

One model evaluation is ``residuals`` (``identification/drive_train.py``): the six step logs simulated
by the numba stick-slip model (1 ms PWM samples, 4 substeps of 0.25 ms each) with the shipped
``[drive_train.roll]``. Beside it, for the same simulated time in Python loops, all three axes, at the
logs' 1 ms (same step, 0.25 ms) and at the firmware's 2.5 ms: the plain library call a user would write
(Pinocchio's ``crba`` and ``nonLinearEffects`` on the reduced closed chain, semi-implicit Euler, 4
substeps; ``bench_simulation.pinocchio_period``) and our smooth model's
``period_map(driven_dynamics(psm, params).forward, period)`` (CasADi RK4, 4 substeps). Without the data
the identify timing is skipped and the model evaluation runs on synthetic steps at the same operating
points.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from bench_simulation import pinocchio_period  # noqa: E402
from common import best_of, per_call  # noqa: E402

import rcm_kin.identification.drive_train as drive_train  # noqa: E402
from rcm_kin import load_robot  # noqa: E402
from rcm_kin.dynamics.drive import load_drive_parameters  # noqa: E402
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm  # noqa: E402
from rcm_kin.dynamics.stick_slip import axis_plant  # noqa: E402
from rcm_kin.hardware import FIRMWARE_PERIOD, HOME_INSERTION  # noqa: E402
from rcm_kin.identification.file_bands import predict_band  # noqa: E402
from rcm_kin.identification.identify import base_model, identify, predict_file  # noqa: E402
from rcm_kin.identification.log_catalog import catalog  # noqa: E402
from rcm_kin.simulation.plant import period_map  # noqa: E402

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"     # ../shared/data, as the tests
TARGET = 180.0     # s: identify --cv on 2 cores (issue)
OPERATING_POINTS = [(-15, -15), (-15, 0), (0, -15), (0, 0), (15, 0), (15, 15)]   # deg, the roll-step logs


def roll_step_logs(data: Path | None):
    """The six roll-step logs (``catalog`` + ``axis_log``), or synthetic steps if there is no data."""
    if data is not None:
        entries = [e for e in catalog([data], ("roll",)) if e.kind == "step"]
        if entries:
            return [drive_train.axis_log(e.path, "roll") for e in entries], "the shared roll-step logs"
    model = driven_dynamics(load_robot("psm"), load_drive_parameters(), coulomb=False)
    logs = []
    for roll, pitch in OPERATING_POINTS:
        pose = np.array([np.radians(roll), np.radians(pitch), HOME_INSERTION])
        hold = float(holding_pwm(model, pose)[0])
        n = int(round(drive_train.AFTER_STEP / drive_train.PERIOD)) + 1
        pwm = np.r_[hold, np.full(n - 1, 2.0 * hold - 10.0)]
        measured = pose[0] + np.linspace(0.0, np.radians(5.0), n)        # any moving angle (a spread)
        logs.append(drive_train.AxisLog(f"synthetic_{roll}_{pitch}", "roll", drive_train.PERIOD, pwm, measured, pose))
    return logs, "synthetic steps (no data)"


def model_evaluation(data: Path | None) -> None:
    psm, params = load_robot("psm"), load_drive_parameters()
    logs, source = roll_step_logs(data)
    model = base_model(params)
    plants = [axis_plant(model, "roll", log.pose) for log in logs]
    friction = params.drive_train["roll"]
    simulated = sum((log.pwm.size - 1) * log.period for log in logs)

    start = time.perf_counter()
    drive_train.residuals(friction, plants, logs)                  # numba: cache load (or compile)
    first = time.perf_counter() - start
    evaluation = per_call(lambda: drive_train.residuals(friction, plants, logs), 20)

    smooth = driven_dynamics(psm, params)                           # the shipped smooth model
    rows = [(f"residuals(): stick-slip (numba), {len(logs)} logs, h 0.25 ms", evaluation)]
    for period in (drive_train.PERIOD, FIRMWARE_PERIOD):
        step = period_map(smooth.forward, period)                   # RK4, 4 substeps per period
        runs = []
        for log in logs:
            hold = holding_pwm(smooth, log.pose)
            n = int(round((log.pwm.size - 1) * log.period / period))
            pwm = log.pwm[(np.arange(n) * period / log.period + 1e-9).astype(int)]   # held, as recorded
            runs.append((np.r_[log.pose, np.zeros(3)], [np.array([u, hold[1], hold[2]]) for u in pwm]))

        def loop():
            for x0, inputs in runs:
                x, out = x0, np.empty(len(inputs))
                for k, u in enumerate(inputs):
                    x = step(x, u)
                    out[k] = float(x[0])
        rows.append((f"period_map RK4 x4 (CasADi), {period * 1e3:g} ms period, Python loop",
                     per_call(loop, 1, repeats=3)))

    # the plain library call: Pinocchio (crba + nonLinearEffects on the reduced closed chain, the
    # drive's smooth friction) stepped in a Python loop, 4 substeps per period, same simulated time
    for period in (drive_train.PERIOD, FIRMWARE_PERIOD):
        step = pinocchio_period(psm, params, period)
        runs = []
        for log in logs:
            hold = holding_pwm(smooth, log.pose)
            n = int(round((log.pwm.size - 1) * log.period / period))
            pwm = log.pwm[(np.arange(n) * period / log.period + 1e-9).astype(int)]
            q0 = psm.to_reduced(np.r_[log.pose, np.zeros(psm.nq - 3)])
            runs.append((q0, [np.array([u, hold[1], hold[2]]) for u in pwm]))

        def pinocchio_loop():
            for q0, inputs in runs:
                q, v = q0, np.zeros(psm.reduced.nv)
                for u in inputs:
                    q, v = step(q, v, u)
        rows.append((f"Pinocchio crba/nle x4, {period * 1e3:g} ms period, Python loop",
                     per_call(pinocchio_loop, 1, repeats=3)))

    print(f"one model evaluation on {len(logs)} logs ({source}), {simulated:.2f} simulated s in all:")
    width = max(len(name) for name, _ in rows)
    print(f"{'':{width}}  {'per call':>10}  {'per sim. s':>10}  {'sim. s/wall s':>13}  {'x residuals':>11}")
    for name, seconds in rows:
        print(f"{name:{width}}  {seconds * 1e3:7.1f} ms  {seconds / simulated * 1e3:7.2f} ms  "
              f"{simulated / seconds:13.0f}  {seconds / evaluation:11.1f}")
    print(f"(first residuals() call in this process, numba cache load: {first * 1e3:.0f} ms)")


def identification(data: Path, repeats: int, cv_runs: tuple[bool, ...]) -> None:
    plain = drive_train.residuals
    counter = {"calls": 0, "logs": 0, "seconds": 0.0}

    def counted(friction, plants, logs):
        start = time.perf_counter()
        try:
            return plain(friction, plants, logs)
        finally:
            counter["calls"] += 1
            counter["logs"] += len(logs)
            counter["seconds"] += time.perf_counter() - start

    drive_train.residuals = counted                                # fit_friction looks it up here
    try:
        print(f"\nidentify({str(data)!r}, joints=('roll',)) on {os.cpu_count()} cores, best of {repeats}:")
        for cv in cv_runs:
            best, seen = float("inf"), None
            for _ in range(repeats):
                counter.update(calls=0, logs=0, seconds=0.0)
                start = time.perf_counter()
                result = identify([data], joints=("roll",), cv=cv)
                wall = time.perf_counter() - start
                if wall < best:
                    best, seen = wall, dict(counter)
            roll = result.joints["roll"]
            checks = roll.cross_validation if cv else roll.fits
            fit = np.mean([c.fit_percent for c in checks])
            verdict = "meets" if best < TARGET else "MISSES"
            counted = (f"{seen['calls']} model evaluations in this process ({seen['logs']} log simulations) took "
                       f"{seen['seconds']:.1f} s = {100 * seen['seconds'] / best:.0f} % of it" if seen["calls"]
                       else "the model evaluations ran in the pool's processes (not counted)")
            print(f"  cv={cv!s:5}: {best:6.1f} s wall ({verdict} the {TARGET / 60:g} min target); {counted}; mean "
                  f"{'leave-one-out' if cv else 'in-sample'} fit {fit:.1f} % (every roll log)")
    finally:
        drive_train.residuals = plain
    if cv_runs[-1]:
        bands(result.params, data)


def bands(params, data: Path) -> None:
    """Per step log: the point prediction and the 90 % band of ``params`` (with its folds), seconds."""
    entries = [e for e in catalog([data], ("roll",)) if e.kind == "step"]
    predict_band(params, entries[0].path, "roll", 0.9)              # numba cache load, once
    print("\nper log, in-process best of 3: predict_file (point) / predict_band (0.9 band), seconds")
    for e in entries:
        point = best_of(lambda: predict_file(params, e.path, "roll"), 3)
        banded = best_of(lambda: predict_band(params, e.path, "roll", 0.9), 3)
        band = predict_band(params, e.path, "roll", 0.9)[3]
        print(f"  {e.path.name:44} {point:6.3f} s  {banded:6.3f} s  ({banded / point:4.1f}x, {band.members} members)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help=f"the measured logs (default {DATA})")
    parser.add_argument("--repeats", type=int, default=1, help="identify runs per setting, best taken (1-2)")
    parser.add_argument("--no-cv", action="store_true", help="skip the cross-validated identify (~100 s)")
    args = parser.parse_args()
    data = args.data if args.data.is_dir() else None
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    model_evaluation(data)
    if data is None:
        print(f"\nidentify timing skipped: no measured logs at {args.data} (pass --data DIR)")
        return
    identification(data, max(1, args.repeats), (False,) if args.no_cv else (False, True))


if __name__ == "__main__":
    main()

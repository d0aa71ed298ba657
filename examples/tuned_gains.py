"""Tune the PSM firmware's gains by simulation over the model's uncertainty, and flash them.

    python examples/tuned_gains.py [OUT_DIR]   (writes gains.json, gain_schedule.h there; default: a temporary folder)

A small version of ``rcm-kin schedule psm --tune``: a few plants drawn from what the identification
does not know, one gain set searched for a few generations against the thesis law on the same
plants, the result judged beside the thesis law and the shipped tuned design, and exported as the
header the microcontroller includes. The full study (64 + 64 draws, about 7 minutes) is the command.
"""

import sys
import tempfile
from pathlib import Path

from rcm_kin.codegen import write_gain_schedule
from rcm_kin.control import schedule_gains
from rcm_kin.dynamics import driven_dynamics, load_drive_parameters
from rcm_kin.model import load_robot
from rcm_kin.simulation import make_controller, run_experiment, tracking_metrics
from rcm_kin.tuning import DesignSpace, build_draws, evaluate, tune, tuned_controller, tuned_schedule

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="tuned_gains_"))
out.mkdir(parents=True, exist_ok=True)

# the shipped calibration and its LQR/LQI schedule on the thesis grid (the grid, linear models and
# holding table the tuned tables are written into)
params = load_drive_parameters()
base = schedule_gains(driven_dynamics(load_robot("psm"), params, coulomb=False), [-20, 0, 20], [-15, 0, 15])

# four plants drawn from the identified uncertainty, each with its 400 Hz frozen loops on 5 x 5 poses
draws = build_draws(params, samples=4, seed=0, points=5)
print(f"{len(draws)} drawn plants ({draws.rejected} drawn sets skipped: the measured holds rule them out)")

# one gain set, three generations of differential evolution against the thesis law on these plants
search = tune(base, draws, DesignSpace("fixed"), seed=0, budget_s=60, generations=3)
values = search.best.values
print("tuned:", ", ".join(f"{k} {v:.4g}" for k, v in values.items()))
print(f"score {search.best.score:.3f} (the thesis law's tracking scores 2; lower is better), "
      f"frozen-loop radius {search.best.radius:.4f}")

# judged beside the thesis law on the same plants
laws = {"thesis law": make_controller("thesis"), "this tuning": tuned_controller(tuned_schedule(base, values))}
for name, law in laws.items():
    summary = evaluate(law, draws).summary()
    print(f"{name:22}" + "  ".join(f"{key} {s['median_max_deg']:.3f}" for key, s in summary.items())
          + "  (median max error from 1 s, deg)")

# what the microcontroller includes: the tables, the law (rcm_control_law) and both feedforwards
files = write_gain_schedule(tuned_schedule(base, values), out, gravity_feedforward=True, friction_feedforward=True)
print("wrote", ", ".join(str(f) for f in files))

# the file runs in the simulator as the firmware would run it (here on the nominal robot), beside
# the shipped design of the full study (urdf/psm_tuned, the default of the "tuned" controller)
for name, gains in (("this tuning", out / "gains.json"), ("shipped tuned design", None)):
    roll = tracking_metrics(run_experiment("sine", "tuned", gains=gains), 1.0)["roll"]
    print(f"{name:22}nominal sine roll max {roll.max_error_deg:.3f} deg, mean {roll.mean_error_deg:.3f} deg")

"""The thesis's tracking experiments (Ch. 5) on the model: every controller on the sinusoid and
on target following, error statistics beside the thesis's measured ones, and the plots of
Figs 5.2-5.11.

    python analysis/tracking_experiments.py --out analysis/output [--data ../shared/data]

With ``--data`` the recorded MTM trajectory is used for target following and the runs are
repeated with the roll's grey-box parameters fitted to the roll-step logs.
"""

from __future__ import annotations

import argparse
import csv
from dataclasses import replace
from pathlib import Path

from rcm_kin.dynamics.drive import load_drive_parameters
from rcm_kin.identification.figures import greybox_figure
from rcm_kin.identification.greybox import fit_greybox, step_logs, write_greybox_parameters
from rcm_kin.plotting import error_comparison_figure, tracking_figure
from rcm_kin.simulation.controllers import CONTROLLERS, make_controller
from rcm_kin.simulation.experiments import experiment_reference, psm_plant_and_schedule, start_hold
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import simulate, tracking_metrics
from rcm_kin.thesis import SINE_TRACKING_ERROR_DEG

FIRMWARE_VELOCITY = "scheduled, firmware v"    # the thesis law: Kd on the measured velocity


def controllers(schedule) -> list:
    out = [make_controller(name, schedule) for name in CONTROLLERS]
    out.append(replace(make_controller("scheduled", schedule), track_velocity=False, name=FIRMWARE_VELOCITY))
    return out


def run_all(params, trajectory, label: str, out: Path) -> list[dict]:
    settings = FirmwareSettings()
    plant, schedule = psm_plant_and_schedule(params, settings.period)
    rows = []
    for experiment in ("sine", "target"):
        reference = experiment_reference(experiment, settings.period, trajectory=trajectory)
        hold = start_hold(reference, params)
        results = [simulate(plant.step, c, reference, settings, initial=plant.initial, hold=hold)
                   for c in controllers(schedule)]
        for r in results:
            tag = r.controller.replace(" ", "_").replace(",", "")
            tracking_figure(r, out / f"{label}_{experiment}_{tag}.png", title=f"{experiment}, {r.controller}:")
            settled = tracking_metrics(r, skip=0.5)
            for axis, m in tracking_metrics(r).items():
                # thesis Sec. 5.2.1, sinusoid: (max, mean) absolute error (deg), measured on the robot
                thesis = SINE_TRACKING_ERROR_DEG.get((r.controller, axis)) if experiment == "sine" else None
                rows.append({"parameters": label, "experiment": experiment, "controller": r.controller,
                             "axis": axis, **{k: round(v, 4) for k, v in vars(m).items()},
                             "max_error_after_0.5s": round(settled[axis].max_error_deg, 4),
                             "mean_error_after_0.5s": round(settled[axis].mean_error_deg, 4),
                             "thesis_max_deg": thesis[0] if thesis else "",
                             "thesis_mean_deg": thesis[1] if thesis else ""})
        pair = [r for r in results if r.controller in ("p", "scheduled-gravity")]
        error_comparison_figure(pair, out / f"{label}_{experiment}_p_vs_scheduled.png", title=f"{experiment}:")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--out", default="analysis/output", help="output folder")
    parser.add_argument("--data", help="the shared data folder (measured logs, MTM trajectory)")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    params = load_drive_parameters()
    trajectory = Path(args.data) / "mtm_target_trajectory.csv" if args.data else None
    rows = run_all(params, trajectory, "shipped", out)
    if args.data:
        logs = step_logs(sorted((Path(args.data) / "psm-sysid" / "roll-step").glob("*.csv")), "roll")
        fit = fit_greybox(params, "roll", logs)
        write_greybox_parameters(fit, out / "roll_greybox.toml")
        greybox_figure(fit, out / "roll_greybox.png")
        rows += run_all(fit.params, trajectory, "greybox", out)
    with (out / "tracking_metrics.csv").open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    for r in rows:
        if r["experiment"] == "sine" or r["controller"] in ("p", "scheduled-gravity"):
            print(f"{r['parameters']:8} {r['experiment']:6} {r['controller']:22} {r['axis']:5} "
                  f"max {r['max_error_deg']:.3f} "
                  f"mean {r['mean_error_deg']:.3f} (after 0.5 s {r['max_error_after_0.5s']:.3f}/"
                  f"{r['mean_error_after_0.5s']:.3f}) RMS {r['rms_error_deg']:.3f} deg, PWM RMS {r['rms_pwm']:.1f}, "
                  f"sat {r['saturation_s']:.3f} s  thesis {r['thesis_max_deg']}/{r['thesis_mean_deg']}")
    print(f"wrote {out}/tracking_metrics.csv and the figures")


if __name__ == "__main__":
    main()

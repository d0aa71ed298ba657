"""``simulate``: the thesis's closed-loop tracking experiments on the simulated PSM."""

from __future__ import annotations

from rcm_kin.cli.common import (
    RAW,
    add_json,
    add_params,
    count,
    emit,
    finite,
    floats,
    path_text,
    progress_wanted,
    psm_robot,
    require_psm,
)
from rcm_kin.cli.outputs import FOLDER_FORCE, new_folder
from rcm_kin.hardware import FIRMWARE_PERIOD, P_GAINS, PWM_LIMIT
from rcm_kin.simulation.controllers import CONTROLLERS, TUNED

RATE = 1.0 / FIRMWARE_PERIOD        # Hz
EPILOG_SIMULATE = ("examples: rcm-kin simulate psm --experiment sine --controller scheduled --json\n"
                   "          rcm-kin simulate psm --experiment target --controller p --plot figures   "
                   "(bundled trajectory)\n"
                   "          rcm-kin simulate psm --experiment target --trajectory mtm_target_trajectory.csv")


def add_simulate(sub) -> None:
    p = sub.add_parser("simulate", help=f"closed-loop {RATE:g} Hz simulation of the thesis tracking experiments",
                       parents=[psm_robot()], epilog=EPILOG_SIMULATE, formatter_class=RAW)
    p.add_argument("--experiment", required=True, choices=("sine", "step", "target"),
                   help="sine: roll 20 deg / pitch 15 deg, 3 s period; step: 10 deg at 0.5 s; "
                        "target: MTM trajectory through teleoperation and IK")
    p.add_argument("--controller", required=True, choices=CONTROLLERS + (TUNED,),
                   help=f"p: Kp {P_GAINS[0]:g}/{P_GAINS[1]:g} PWM/deg; pid: thesis Table 3.4; lqr-fixed: model "
                        "LQR/LQI at (0,0); scheduled: gain-scheduled LQR/LQI + feedforward; scheduled-gravity: plus "
                        "holding PWM; scheduled-friction: plus the sliding-friction compensation on the reference "
                        "velocity; thesis: the thesis's flashed gain tables and law (Tables 4.4-4.8); tuned: the "
                        "state-feedback law with the tables of --gains (default: the shipped design of schedule psm "
                        "--tune)")
    p.add_argument("--gains", type=path_text, metavar="GAINS_JSON",
                   help="--controller tuned: the gains.json of rcm-kin schedule psm [--tune] to run (its tables, "
                        "feedforwards and law options; default: the shipped tuned design)")
    p.add_argument("--duration", type=finite(0, 1e4, "s", open_lo=True),
                   help="simulated seconds (default: sine 6, step 3, target: recording; at most 200,000 controller "
                        "periods)")
    p.add_argument("--trajectory", type=path_text,
                   help="MTM recording CSV (unix_time,x,y,z in m) for --experiment target "
                        "(default: the bundled figure-eight)")
    p.add_argument("--rate", type=finite(1, 1e5, "Hz"), default=RATE,
                   help=f"controller rate in Hz (1 to 100000, default {RATE:g})")
    p.add_argument("--pwm-limit", nargs=3, metavar=("ROLL", "PITCH", "INS"),
                   help=f"PWM saturation in counts (default {' '.join(f'{v:g}' for v in PWM_LIMIT)})")
    p.add_argument("--skip", type=finite(0, unit="s"), default=0.0,
                   help="leave the first S seconds out of the statistics (default 0; the sinusoid starts at "
                        "full speed)")
    p.add_argument("--noise-counts", type=finite(0, 1e4, "counts"), default=0.0,
                   help="encoder noise std in counts (default 0)")
    p.add_argument("--seed", type=count(0, 2**32 - 1), default=0, help="random seed of the encoder noise (default 0)")
    add_params(p)
    p.add_argument("--plot", metavar="DIR", type=path_text, help="write reference/measured/error plots (PNG) into DIR")
    p.add_argument("--force", action="store_true", help=FOLDER_FORCE)
    add_json(p, '{"roll": {"max_error_deg", "mean_error_deg", "rms_error_deg", ...}, "pitch": {...}}')
    p.set_defaults(func=cmd_simulate)


def cmd_simulate(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.simulation.experiments import run_experiment
    from rcm_kin.simulation.firmware import FirmwareSettings
    from rcm_kin.simulation.loop import tracking_metrics

    require_psm(args, "the tracking experiments run on the PSM's driven joints, not '{robot}'")
    limits = {"pwm_limit": floats(args.pwm_limit, "--pwm-limit")} if args.pwm_limit else {}
    settings = FirmwareSettings(period=1.0 / args.rate, noise_counts=args.noise_counts, **limits)
    result = run_experiment(args.experiment, args.controller, args.duration, load_drive_parameters(args.params),
                            settings, args.trajectory, seed=args.seed,
                            progress=progress_wanted(args), gains=args.gains)
    metrics = tracking_metrics(result, args.skip)
    payload = {axis: vars(m) for axis, m in metrics.items()}
    lines = [f"{args.experiment} with {args.controller}, {result.time[-1]:.2f} s at {args.rate:g} Hz:"] + [
        f"{axis:5}  max {m.max_error_deg:.3f}  mean {m.mean_error_deg:.3f}  RMS {m.rms_error_deg:.3f} deg;  "
        f"PWM RMS {m.rms_pwm:.1f}, saturated {m.saturation_s:.3f} s" for axis, m in metrics.items()]
    if args.plot:
        from rcm_kin.plotting import tracking_figure

        path = tracking_figure(result, new_folder(args.plot, args.force) / f"{args.experiment}_{args.controller}.png",
                               title=f"{args.experiment}, {args.controller}:")
        lines.append(f"wrote {path}")
    emit(args, payload, "\n".join(lines))

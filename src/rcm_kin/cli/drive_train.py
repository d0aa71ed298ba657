"""``identify``, ``predict``: the stick-slip drive trains from measured logs, and what they predict."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import RAW, add_json, add_params, emit, psm_robot, require_psm
from rcm_kin.errors import RcmKinError

EPILOG_IDENTIFY = ("example: rcm-kin identify psm ../shared/data --out identified.toml --cv\n"
                   "         rcm-kin predict psm roll_step_response_roll_0_pitch_0.csv --joint roll "
                   "--params identified.toml")
EPILOG_PREDICT = ("example: rcm-kin predict psm roll_step_response_roll_0_pitch_0.csv --joint roll --plot roll.png "
                  "--json\n(positions in deg, time in s; the model is driven by the log's recorded PWM, "
                  "no refitting)")


def add_identify(sub) -> None:
    p = sub.add_parser("identify", help="identify the drive trains (stick-slip friction, inertia) from logs",
                       parents=[psm_robot()], epilog=EPILOG_IDENTIFY, formatter_class=RAW)
    p.add_argument("logs", nargs="+", metavar="DIR_OR_FILE", help="telemetry CSV logs, or folders searched for them")
    p.add_argument("--out", required=True, help="drive parameter TOML to write (the --params set with the "
                                                "identified drive trains)")
    p.add_argument("--joint", nargs="+", choices=("roll", "pitch"), default=["roll", "pitch"],
                   help="joints to identify (default: roll pitch)")
    p.add_argument("--cv", action="store_true", help="leave-one-log-out cross-validation (slower)")
    p.add_argument("--seed", type=int, default=0, help="seed of the evolutionary search (default 0)")
    p.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    add_params(p, "starting drive parameter TOML (default: the shipped set)")
    add_json(p, '{"parameters", "standard_errors", "jackknife_standard_errors", "logs", "fits", '
                '"cross_validation", "skipped", "written"}')
    p.set_defaults(func=cmd_identify)


def add_predict(sub) -> None:
    p = sub.add_parser("predict", help="simulate a log from its recorded PWM with the identified model",
                       parents=[psm_robot()], epilog=EPILOG_PREDICT, formatter_class=RAW)
    p.add_argument("log", metavar="LOG", help="telemetry CSV (position = measured deg, velocity = PWM)")
    p.add_argument("--joint", required=True, choices=("roll", "pitch"))
    add_params(p, "drive parameter TOML with [drive_train.<joint>] (default: the shipped set)")
    p.add_argument("--plot", metavar="FILE", help="PNG of measured and predicted angle, stick phases shaded")
    add_json(p, '{"fit_percent", "final_error_deg", "time" (s), "measured" (deg), "predicted" (deg)}')
    p.set_defaults(func=cmd_predict)


def cmd_identify(args) -> None:
    from pathlib import Path

    from rcm_kin.dynamics.drive import load_drive_parameters, write_parameters
    from rcm_kin.identification.identify import identify

    require_psm(args, "identify models the PSM's drive trains, not the {robot}")
    out = Path(args.out)
    if out.exists() and not args.force:
        raise RcmKinError(f"{out} exists: choose another --out or add --force")
    result = identify(args.logs, load_drive_parameters(args.params), tuple(dict.fromkeys(args.joint)), args.cv,
                      args.seed, progress=not args.json)
    header = ["Drive parameters with drive trains identified by rcm-kin identify from:"]
    header += [f"  {j}: {', '.join(r.logs)}" for j, r in result.joints.items()]
    payload = result.as_dict()
    payload["written"] = str(write_parameters(result.params, out, "\n".join(header)))
    emit(args, payload, "\n".join(_identify_lines(result) + [f"wrote {out}"]))


def _identify_lines(result) -> list[str]:
    lines = []
    for joint, r in result.joints.items():
        lines.append(f"{joint}: {len(r.fits)} records from {len(r.logs)} logs")
        lines += [f"  {name:22} {getattr(r.friction, name):.5g} +- {r.standard_errors[name]:.2g} (local)"
                  + (f", +- {r.jackknife_errors[name]:.2g} (over the folds)" if r.jackknife_errors else "")
                  for name in r.standard_errors]
        if r.cross_validation:
            lines.append("  leave-one-log-out: fit %, final travel measured / error (deg), stick time s")
            lines += [f"  {c.name:44} {c.fit_percent:7.1f}  {c.travel_deg:+.2f} / {c.final_error_deg:+.2f}  "
                      f"{c.stick_time:.2f} (model {c.predicted_stick_time:.2f})" for c in r.cross_validation]
    lines += [f"skipped {e.path.name} ({e.joint}): {e.reason}" for e in result.skipped]
    return lines


def cmd_predict(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.identification.drive_train import check_log, predict_log, whole_log
    from rcm_kin.identification.identify import base_model
    from rcm_kin.dynamics.stick_slip import axis_plant

    require_psm(args, "predict uses the PSM's drive trains, not the {robot}")
    params = load_drive_parameters(args.params)
    if args.joint not in params.drive_train:
        raise RcmKinError(f"{params.source} has no [drive_train.{args.joint}]: identify one first "
                          "(rcm-kin identify psm LOGS --out FILE.toml) and pass it with --params")
    log = whole_log(args.log, args.joint)
    predicted = predict_log(params.drive_train[args.joint], axis_plant(base_model(params), args.joint, log.pose), log)
    check = check_log(log.name, log.measured, predicted, log.period)
    payload = {"fit_percent": check.fit_percent, "final_error_deg": check.final_error_deg,
               "time": log.time.tolist(), "measured": np.degrees(log.measured).tolist(),
               "predicted": np.degrees(predicted).tolist()}
    lines = [f"{log.name}, {args.joint}: fit {check.fit_percent:.1f} % (NRMSE), final angle measured "
             f"{np.degrees(log.measured[-1]):.3f} deg, predicted {np.degrees(predicted[-1]):.3f} deg "
             f"(error {check.final_error_deg:+.3f})"]
    if args.plot:
        from rcm_kin.report.figures import prediction_figure

        path = prediction_figure(log.time, np.degrees(log.measured), np.degrees(predicted), args.plot,
                                 f"{log.name}, {args.joint}: fit {check.fit_percent:.1f} %")
        payload["written"] = str(path)
        lines.append(f"wrote {path}")
    emit(args, payload, "\n".join(lines))

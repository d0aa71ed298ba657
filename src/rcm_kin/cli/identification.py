"""``sysid``, ``greybox``: transfer functions and physical parameters from measured telemetry."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rcm_kin.cli.common import RAW, add_json, add_params, count, driven_model, emit, floats, path_text, progress_wanted
from rcm_kin.cli.outputs import FOLDER_FORCE, add_force, new_folder, new_output
from rcm_kin.errors import RcmKinError

MAX_SAMPLES = 100_000     # samples of one step or segment: the logs hold a few thousand
EPILOG_SYSID = ("examples: rcm-kin sysid roll_step.csv --joint roll --json   (2nd-order fit of the step)\n"
                "          rcm-kin sysid prbs_roll_0_pitch_0.csv --joint pitch --order 4\n"
                "          rcm-kin sysid psm-sysid/roll-step --joint roll --out table   "
                "(every pose of a folder, beside the physics)")
EPILOG_GREYBOX = ("example: rcm-kin greybox psm-sysid/roll-step --joint roll --out roll_fitted.toml\n"
                  "         rcm-kin simulate psm --experiment sine --controller p --params roll_fitted.toml")


def add_sysid(sub) -> None:
    p = sub.add_parser("sysid", help="transfer-function identification from telemetry logs (step or PRBS)",
                       epilog=EPILOG_SYSID, formatter_class=RAW)
    p.add_argument("log", metavar="LOG", type=path_text,
                   help="telemetry CSV (position = measured deg, velocity = PWM), or a "
                        "folder of logs named ..._roll_R_pitch_P.csv")
    p.add_argument("--joint", required=True, choices=("roll", "pitch"))
    p.add_argument("--method", choices=("step", "prbs"),
                   help="step: trimmed open-loop step; prbs: whole record about its means (default: roll step, "
                        "pitch prbs)")
    p.add_argument("--order", type=count(1, 10, "poles"),
                   help="number of poles, 1 to 10 (default 2 for step, 3 for prbs)")
    p.add_argument("--zeros", type=count(0, 9, "zeros"),
                   help="number of zeros, fewer than the poles (default order - 1)")
    p.add_argument("--samples", type=count(50, MAX_SAMPLES), default=1000,
                   help=f"step: samples kept from the step, 50 to {MAX_SAMPLES:,} (default 1000)")
    p.add_argument("--segment", type=count(10, MAX_SAMPLES),
                   help="prbs: samples per segment simulated from its own initial state (default 500)")
    p.add_argument("--pose", nargs=2, metavar=("ROLL", "PITCH"),
                   help="pose in deg for the physics comparison (default: from the file name)")
    add_params(p, "drive parameter TOML of the physics model (default: the shipped set)")
    p.add_argument("--out", type=path_text, help="folder: write the per-pose table (CSV) when LOG is a folder")
    p.add_argument("--force", action="store_true", help=FOLDER_FORCE)
    add_json(p, '{"num", "den", "fit_percent", "A", "B", "C", "D", ...}; a folder gives {"models": [...]}')
    p.set_defaults(func=cmd_sysid)


def add_greybox(sub) -> None:
    p = sub.add_parser("greybox", help="fit extra inertia and friction to open-loop step logs by simulating the "
                                       "physics", epilog=EPILOG_GREYBOX, formatter_class=RAW)
    p.add_argument("logs", nargs="+", metavar="LOG", type=path_text,
                   help="step logs (telemetry CSV) or folders of them")
    p.add_argument("--joint", required=True, choices=("roll", "pitch"))
    p.add_argument("--samples", type=count(50, MAX_SAMPLES), default=1000,
                   help=f"samples kept from each step, 50 to {MAX_SAMPLES:,} (default 1000)")
    add_params(p, "starting drive parameter TOML (default: the shipped set)")
    p.add_argument("--out", help="write the fitted parameter set (TOML) to this new file (or --force)")
    add_force(p)
    add_json(p, '{"before", "after", "coulomb_per_log", "fit_percent_before", "fit_percent_after", ...}')
    p.set_defaults(func=cmd_greybox)


def cmd_sysid(args) -> None:
    """One log: its fitted transfer function beside the physics; a folder: one row per pose."""
    folder = Path(args.log).is_dir()
    if folder and args.pose:
        raise RcmKinError("--pose is for one log: a folder's poses are read from its file names")
    model = driven_model(args.params, coulomb=False)
    options = dict(method=args.method, order=args.order, zeros=args.zeros, samples=args.samples,
                   segment=args.segment)
    if folder:
        _sysid_folder(args, model, options)
    else:
        _sysid_log(args, model, options)


def _sysid_folder(args, model, options: dict) -> None:
    from rcm_kin.identification.pose_models import identify_folder, pose_table_rows, write_pose_table

    models = identify_folder(args.log, args.joint, model, **options)
    rows = pose_table_rows(models)
    payload = {"models": rows}
    lines = [f"{r['file']:46} fit {r['fit_percent']:6.2f} %  DC {r['dc_gain']:+.4f} deg/PWM  poles {r['poles']}"
             + (f"   physics DC {r['physics_dc_gain']:+.4f}, poles {r['physics_poles']}" if "physics_poles" in r
                else "") for r in rows]
    if args.out:
        path = write_pose_table(models, new_folder(args.out, args.force) / f"{args.joint}_pose_models.csv")
        payload["written"] = str(path)
        lines.append(f"wrote {path}")
    emit(args, payload, "\n".join(lines))


def _sysid_log(args, model, options: dict) -> None:
    from rcm_kin.identification.pose_models import identify_log
    from rcm_kin.identification.transfer_function import polynomial_text

    pose = tuple(floats(args.pose, "--pose")) if args.pose else None
    result = identify_log(args.log, args.joint, model=model, pose_deg=pose, **options)
    fit = result.fit
    payload = fit.as_dict()
    if result.physics is not None:
        payload["physics"] = {"pose_deg": list(result.pose_deg), "dc_gain": result.physics.dc_gain,
                              "poles": [[p.real, p.imag] for p in result.physics.poles]}
    np.set_printoptions(precision=5, suppress=True, linewidth=120)
    lines = [f"{args.joint}: G(s) = ({polynomial_text(fit.num)}) / ({polynomial_text(fit.den)})  (deg per PWM count)",
             f"fit {fit.fit_percent:.2f} % (NRMSE), DC gain {fit.dc_gain:+.4f} deg/PWM, poles {fit.poles}",
             f"operating point: PWM {result.record.u0:.2f}, angle {result.record.y0:.3f} deg"]
    if result.physics is not None:
        lines.append(f"physics at roll {result.pose_deg[0]:g}, pitch {result.pose_deg[1]:g} deg: DC gain "
                     f"{result.physics.dc_gain:+.4f} deg/PWM, poles {result.physics.poles}")
    emit(args, payload, "\n".join(lines))


def cmd_greybox(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.identification.greybox import fit_greybox, step_logs, write_greybox_parameters
    from rcm_kin.identification.rosbag import is_bag
    from rcm_kin.identification.telemetry import telemetry_files

    paths = []
    for item in args.logs:
        found = telemetry_files(item) if Path(item).is_dir() and not is_bag(item) else [Path(item)]
        if not found:
            raise RcmKinError(f"no logs (CSV or ROS 2 bags) in {item}")
        paths += found
    out = new_output(args.out, args.force, (".toml",)) if args.out is not None else None
    fit = fit_greybox(load_drive_parameters(args.params), args.joint, step_logs(paths, args.joint, args.samples),
                      progress=progress_wanted(args))
    payload = fit.as_dict()
    lines = [f"{args.joint} grey-box fit on {len(fit.logs)} step logs:"]
    lines += [f"  {n:16} {b:.6g} -> {a:.6g}" for n, b, a in zip(fit.names, fit.before, fit.after)]
    lines += ["  fit % per log: starting set -> fitted set (median Coulomb) -> with the log's own Coulomb"]
    lines += [f"  {name:44} {b:9.1f} -> {a:7.1f} -> {p:6.1f}   (coulomb {c:.3f} N m)" for name, c, b, a, p in
              zip(fit.logs, fit.coulomb_per_log, fit.fit_before, fit.fit_after, fit.fit_per_log_friction)]
    if out:
        path = write_greybox_parameters(fit, out)
        payload["written"] = str(path)
        lines.append(f"wrote {path} (use it with --params)")
    emit(args, payload, "\n".join(lines))

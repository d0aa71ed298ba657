"""``identify``: the stick-slip drive trains from measured logs (``predict``, what they predict:
:mod:`rcm_kin.cli.prediction`); ``excite``: the excitation that would identify them better."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import (
    RAW,
    add_json,
    add_params,
    check_finite,
    count,
    emit,
    finite,
    path_text,
    progress_wanted,
    psm_robot,
    require_psm,
)
from rcm_kin.cli.outputs import add_force, new_output

EPILOG_IDENTIFY = ("example: rcm-kin identify psm ../shared/data --out identified.toml --cv\n"
                   "         rcm-kin predict psm roll_step_response_roll_0_pitch_0.csv --joint roll "
                   "--params identified.toml")
EPILOG_EXCITE = ("example: rcm-kin excite psm --duration 60 --out excitation.csv --json\n"
                 "(the joints take turns, each for --duration s while the other holds at 0; the CSV is in the "
                 "telemetry format:\n __time s, <joint>/position and /effort = setpoint deg, <joint>/velocity = "
                 "feedforward PWM counts, every 2.5 ms)")


def add_identify(sub) -> None:
    p = sub.add_parser("identify", help="identify the drive trains (stick-slip friction, inertia) from logs",
                       parents=[psm_robot()], epilog=EPILOG_IDENTIFY, formatter_class=RAW)
    p.add_argument("logs", nargs="+", metavar="DIR_OR_FILE", type=path_text,
                   help="telemetry CSV logs, or folders searched for them")
    p.add_argument("--out", required=True, help="drive parameter TOML to write (the --params set with the "
                                                "identified drive trains)")
    p.add_argument("--joint", nargs="+", choices=("roll", "pitch"), default=["roll"],
                   help="joints to identify (default: roll; --joint pitch fits the pitch in its recorded loop, "
                        "for study: "
                        "its logs are too slow to fix its friction at tracking speeds, see the README)")
    p.add_argument("--cv", action="store_true",
                   help="leave-one-log-out cross-validation, each fold fitted from scratch (minutes)")
    p.add_argument("--seed", type=count(0, 2**32 - 1), default=0, help="seed of the evolutionary search (default 0)")
    add_force(p, "overwrite --out if it exists")
    add_params(p, "starting drive parameter TOML (default: the shipped set)")
    add_json(p, '{"parameters", "standard_errors", "jackknife_standard_errors", "undetermined", "logs", "fits", '
                '"cross_validation", "skipped", "written", "notes", "folds", "ranges", "constraints", "preloads", '
                '"discrepancy", "cross_validation_band": {joint: {log: {"coverage", "final_inside", '
                '"end_width_over_travel", "median_fit_percent", ...}}}}')
    p.set_defaults(func=cmd_identify)


def cmd_identify(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters, write_parameters
    from rcm_kin.identification.identify import identify

    require_psm(args, "identify models the PSM's drive trains, not the {robot}")
    out = new_output(args.out, args.force, (".toml",))
    result = identify(args.logs, load_drive_parameters(args.params), tuple(dict.fromkeys(args.joint)), args.cv,
                      args.seed, progress=progress_wanted(args))
    header = ["Drive parameters with drive trains identified by rcm-kin identify from:"]
    header += [f"  {j}: {', '.join(r.logs)}" for j, r in result.joints.items()]
    payload = result.as_dict()
    check_finite(payload)                  # a refused result writes no file
    payload["written"] = str(write_parameters(result.params, out, "\n".join(header)))
    emit(args, payload, "\n".join(_identify_lines(result) + [f"wrote {out}"]))


def _identify_lines(result) -> list[str]:
    lines = []
    for joint, r in result.joints.items():
        lines.append(f"{joint}: {len(r.fits)} records from {len(r.logs)} logs")
        lines += [f"  {name:22} {getattr(r.friction, name):.5g} " + _sigma_text(r.standard_errors[name]) + " (local)"
                  + (f", +- {r.jackknife_errors[name]:.2g} (over the folds)" if r.jackknife_errors else "")
                  for name in r.standard_errors]
        if r.cross_validation:
            lines.append("  leave-one-log-out: fit %, final travel measured / error (deg), stick time s")
            lines += [f"  {c.name:44} {c.fit_percent:7.1f}  {c.travel_deg:+.2f} / {c.final_error_deg:+.2f}  "
                      f"{c.stick_time:.2f} (model {c.predicted_stick_time:.2f})" for c in r.cross_validation]
        if r.cv_bands:
            lines.append(f"  left-out {r.cv_bands[0].level:.0%} band: coverage, final inside, end width / travel, "
                         "median fit %, median final error (deg)")
            lines += [f"  {b.name:44} {b.coverage:5.0%}  {'yes' if b.final_inside else 'no ':3}  "
                      + (f"{b.end_width_over_travel:5.2f}" if b.end_width_over_travel is not None else "    -")
                      + f"  {b.median_fit:7.1f}  {np.degrees(b.median[-1] - b.measured[-1]):+.2f}"
                      + ("  (extrapolated)" if b.extrapolated else "") for b in r.cv_bands]
        for b in r.bounds:
            value = b.value(r.friction)
            lines.append(f"  constraint {b.name}: friction at {np.degrees(b.speed):.0f} deg/s {value:.3g} <= "
                         f"{b.max_force:.3g} N m" + (" (active)" if b.active(r.friction) else "") + f"  [{b.source}]")
    lines += [f"note {e.path.name} ({e.joint}): {e.note}" for e in result.notes]
    lines += [f"skipped {e.path.name} ({e.joint}): {e.reason}" for e in result.skipped]
    return lines


def _sigma_text(sigma: float) -> str:
    return f"+- {sigma:.2g}" if np.isfinite(sigma) else "(not determined by these logs)"


def add_excite(sub) -> None:
    p = sub.add_parser("excite", help="design a periodic excitation for identifying the drive trains (replay CSV)",
                       parents=[psm_robot()], epilog=EPILOG_EXCITE, formatter_class=RAW)
    p.add_argument("--duration", type=finite(unit="s"), required=True, metavar="S",
                   help="seconds of excitation per joint (1 to 600; a whole number of ~10 s periods)")
    p.add_argument("--out", required=True, metavar="FILE.csv", help="replay CSV to write")
    p.add_argument("--joint", nargs="+", default=["roll", "pitch"], metavar="JOINT",
                   help="joints to excite, in turn (roll, pitch; default both)")
    p.add_argument("--harmonics", type=count(2, 20), default=5,
                   help="harmonics of each Fourier series (2 to 20, default 5)")
    p.add_argument("--seed", type=count(0, 2**32 - 1), default=0,
                   help="seed of the optimisation's random starts (default 0)")
    add_force(p, "overwrite --out if it exists")
    add_params(p, "drive parameter TOML for the feedforward and the drive trains (default: the shipped set)")
    add_json(p, '{"written", "condition_number", "baseline_condition_number", "standard_errors": {joint: '
                '{"regressor", "stick_slip"}}, "period_s", ...} (SI)')
    p.set_defaults(func=cmd_excite)


def cmd_excite(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.identification.excitation import UNITS, check_request, design_excitation, write_excitation

    require_psm(args, "excite designs the PSM's drive-train experiments, not the {robot}'s")
    joints = check_request(args.duration, args.joint, args.harmonics)
    out = new_output(args.out, args.force, (".csv",))
    result = design_excitation(args.duration, joints, args.harmonics, args.seed, load_drive_parameters(args.params),
                               progress=progress_wanted(args))
    payload = result.as_dict()
    payload["written"] = str(write_excitation(result, out))
    lines = []
    for joint, r in result.joints.items():
        lines.append(f"{joint} (from {r.start:g} s): condition number {r.condition_number:.3g} (a single sine of "
                     f"the same amplitude: {r.baseline_condition_number:.3g}); peaks {np.degrees(r.peak_position):.1f}"
                     f" deg, {np.degrees(r.peak_velocity):.1f} deg/s, {r.peak_pwm:.1f} PWM")
        lines += [f"  {name:12} {r.theta[name]:9.4g} +- {sigma:.2g} {UNITS[name]} (sine: +- "
                  f"{r.baseline_standard_errors[name]:.2g})" for name, sigma in r.standard_errors.items()]
        if r.stick_slip_errors:
            lines.append(f"  drive train, replayed with the P loop (tracking {np.degrees(r.tracking_rms):.2f} deg "
                         "RMS), encoder-count noise:")
            lines += [f"  {name:22} +- {sigma:.2g} (sine: +- {r.baseline_stick_slip_errors[name]:.2g})"
                      for name, sigma in r.stick_slip_errors.items()]
    lines.append(f"wrote {out}: {result.time.size} rows every 2.5 ms, period {result.period:g} s, "
                 f"{result.harmonics} harmonics (regressor errors: 1 PWM count equation error)")
    emit(args, payload, "\n".join(lines))

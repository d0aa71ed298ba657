"""``calibrate``: the drive gain and gravity offsets fitted to measured holds, and the holding bands they support."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import BadValue, add_json, add_params, emit, path_text
from rcm_kin.cli.outputs import add_force, new_output
from rcm_kin.model import load_robot

BAND_HELP = "a level in (0, 1), e.g. 0.9"


def band_level(word: str) -> float:
    """argparse ``type``: a band's level, a number strictly between 0 and 1."""
    try:
        value = float(word)
    except ValueError:
        raise BadValue(f"needs a level in (0, 1), e.g. 0.9, got {word[:40]!r}") from None
    if not 0.0 < value < 1.0:
        raise BadValue(f"needs a level in (0, 1), e.g. 0.9, got {word[:40]!r}")
    return value


def add_calibrate(sub) -> None:
    p = sub.add_parser("calibrate", help="fit drive gain and gravity offsets to measured holding efforts",
                       epilog="example: rcm-kin calibrate ../shared/data --out my_drive.toml")
    p.add_argument("data", type=path_text, help="folder with roll-step/*.csv and pitch-prbs/*.csv telemetry logs")
    add_params(p, "starting drive parameter TOML (default: the shipped set)")
    p.add_argument("--out", help="write the calibrated parameter TOML here (a new .toml file unless --force), with "
                                 "[uncertainty.hull] and [uncertainty.holding_residuals] (its other uncertainty "
                                 "tables kept from the starting file)")
    p.add_argument("--band", type=band_level, default=0.9,
                   help="level of the holding bands checked on the holds, each left out (default 0.9)")
    add_force(p)
    add_json(p, 'parameters with uncertainty, residuals per point, "holding_band" (level, half_width_pwm, '
                'left_out_inside, hull_deg, ...)')
    p.set_defaults(func=cmd_calibrate)


def cmd_calibrate(args) -> None:
    from rcm_kin.dynamics.drive import check_drive, load_drive_parameters, write_parameters
    from rcm_kin.identification.calibration import UNITS, calibrate, calibration_logs, holding_points
    from rcm_kin.identification.holding_bands import left_out_coverage, with_holding_uncertainty

    psm = load_robot("psm")
    base = check_drive(psm, load_drive_parameters(args.params))   # another robot's file: one line, before the data
    out = new_output(args.out, args.force, (".toml",)) if args.out is not None else None
    points = holding_points(calibration_logs(args.data))
    result = calibrate(psm, base, points)
    coverage = left_out_coverage(psm, base, points, args.band, result)
    fitted = list(zip(result.names, result.values, result.std, UNITS))
    payload = {"parameters": {n: {"value": float(v), "std": float(s), "unit": u} for n, v, s, u in fitted},
               "residual_rms_pwm": result.residual_rms.tolist(), "friction_band_pwm": result.friction_band.tolist(),
               "points": [{"source": p.source, "roll_deg": float(np.degrees(p.roll)),
                           "pitch_deg": float(np.degrees(p.pitch)), "measured_pwm": [p.pwm_roll, p.pwm_pitch],
                           "predicted_pwm": pred.tolist()} for p, pred in zip(points, result.predicted)],
               "holding_band": coverage.as_dict()}
    if out:
        header = (f"Drive parameters calibrated by `rcm-kin calibrate` on {len(points)} holding points.\n"
                  + "\n".join(f"{n} = {v:.6g} +- {s:.2g} {u}" for n, v, s, u in fitted)
                  + f"\nresidual RMS roll {result.residual_rms[0]:.2f}, pitch {result.residual_rms[1]:.2f} PWM; "
                  f"largest |residual| roll {result.friction_band[0]:.2f}, pitch {result.friction_band[1]:.2f} PWM."
                  "\n[uncertainty] holding_residuals: each hold left out of its fit (PWM, measured minus predicted)."
                  "\nFormat and assumed constants: see the shipped urdf/psm_drive.toml.")
        payload["written"] = str(write_parameters(with_holding_uncertainty(result.parameters, coverage), out, header))
    lines = [f"{n:20} {v:+.6g} +- {s:.2g} {u}" for n, v, s, u in fitted]
    lines.append(f"residual RMS: roll {result.residual_rms[0]:.2f}, pitch {result.residual_rms[1]:.2f} PWM "
                 f"over {len(points)} holding points")
    lines += band_lines(coverage)
    if out:
        lines.append(f"wrote {payload['written']}")
    emit(args, payload, "\n".join(lines))


def band_lines(coverage) -> list[str]:
    """The left-out check of the holding bands, for people."""
    n = len(coverage.sources)
    lines = [f"holding band {coverage.level:g}, each hold's band built without it (calibration and half-width "
             f"refitted on the other {n - 1}):"]
    for i, joint in enumerate(("roll", "pitch")):
        half = coverage.half_width[:, i]
        lines.append(f"  {joint:5} {int(coverage.inside[:, i].sum())}/{n} holds inside, half-width "
                     f"{half.min():.2f} to {half.max():.2f} PWM (from all {n} holds: "
                     f"{coverage.full_half_width[i]:.2f} PWM)")
    hull = ", ".join(f"{j} [{np.degrees(lo):.1f}, {np.degrees(hi):.1f}] deg" for j, (lo, hi) in coverage.hull.items())
    lines.append(f"  calibrated poses: {hull}")
    if coverage.extrapolated.any():
        lines.append("  outside the poses of the other holds when left out: "
                     + ", ".join(s for s, e in zip(coverage.sources, coverage.extrapolated) if e))
    return lines

"""``predict``: what the identified drive train says a log does, with a prediction band on request."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import RAW, BadValue, add_json, add_params, emit, path_text, psm_robot, require_psm
from rcm_kin.cli.outputs import add_force, new_output

EPILOG_PREDICT = ("example: rcm-kin predict psm roll_step_response_roll_0_pitch_0.csv --joint roll --plot roll.png "
                  "--json\n         rcm-kin predict psm roll_step_response_roll_0_pitch_0.csv --joint roll --band 0.9 "
                  "--params identified.toml\n(positions in deg, time in s; the model is driven by the log's recorded "
                  "PWM, no refitting; a closed-loop log from its first rest with the controller that ran, read back "
                  "from the log, in the loop; --band needs a file written by rcm-kin identify --cv: its "
                  "leave-one-log-out parameter sets, the ranges of the parameters the logs do not determine and the "
                  "presliding spring's unknown state before the record span the band, scored from the sample "
                  "before the step)")
BAND_KEYS = ('"band": {"level", "lower", "upper", "median" (deg), "coverage", "final_inside", '
             '"end_width_over_travel", "members", "sources", "extrapolated", ...} with --band')


def band_level(word: str) -> float:
    """argparse ``type``: a band level strictly between 0 and 1."""
    try:
        value = float(word)
    except ValueError:
        raise BadValue(f"needs a level strictly between 0 and 1 (e.g. 0.9), got {word!r}") from None
    if not 0.0 < value < 1.0:
        raise BadValue(f"needs a level strictly between 0 and 1 (e.g. 0.9), got {word!r}")
    return value


def add_predict(sub) -> None:
    p = sub.add_parser("predict", help="simulate a log from its recorded PWM with the identified model",
                       parents=[psm_robot()], epilog=EPILOG_PREDICT, formatter_class=RAW)
    p.add_argument("log", metavar="LOG", type=path_text, help="telemetry CSV (position = measured deg, velocity = PWM)")
    p.add_argument("--joint", required=True, choices=("roll", "pitch"))
    add_params(p, "drive parameter TOML with [drive_train.<joint>] (default: the shipped set)")
    p.add_argument("--band", type=band_level, metavar="LEVEL",
                   help="prediction band at LEVEL (0 < LEVEL < 1, e.g. 0.9) from the file's [uncertainty]")
    p.add_argument("--plot", metavar="FILE.png",
                   help="PNG of measured and predicted angle, stick phases shaded (and the band, with --band)")
    add_force(p)
    add_json(p, '{"fit_percent", "final_error_deg", "time" (s), "measured" (deg), "predicted" (deg), '
             + BAND_KEYS + '}')
    p.set_defaults(func=cmd_predict)


def cmd_predict(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters

    require_psm(args, "predict uses the PSM's drive trains, not the {robot}")
    plot = new_output(args.plot, args.force, (".png",)) if args.plot is not None else None
    params = load_drive_parameters(args.params)
    band = None
    if args.band is None:
        from rcm_kin.identification.identify import predict_file

        log, predicted, check = predict_file(params, args.log, args.joint)
    else:
        from rcm_kin.identification.file_bands import predict_band

        log, predicted, check, band = predict_band(params, args.log, args.joint, args.band)
    payload = {"fit_percent": check.fit_percent, "final_error_deg": check.final_error_deg,
               "time": log.time.tolist(), "measured": np.degrees(log.measured).tolist(),
               "predicted": np.degrees(predicted).tolist()}
    lines = [f"{log.name}, {args.joint}: fit {check.fit_percent:.1f} % (NRMSE), final angle measured "
             f"{np.degrees(log.measured[-1]):.3f} deg, predicted {np.degrees(predicted[-1]):.3f} deg "
             f"(error {check.final_error_deg:+.3f})"]
    if band is not None:
        payload["band"] = band.as_dict()
        lines += band_lines(band)
    if plot:
        title = f"{log.name}, {args.joint}: fit {check.fit_percent:.1f} %"
        if band is None:
            from rcm_kin.identification.figures import prediction_figure

            path = prediction_figure(log.time, np.degrees(log.measured), np.degrees(predicted), plot, title)
        else:
            path = band.plot(plot, predicted, title + f", {band.coverage:.0%} inside the {band.level:.0%} band")
        payload["written"] = str(path)
        lines.append(f"wrote {path}")
    emit(args, payload, "\n".join(lines))


def band_lines(band) -> list[str]:
    """The text of a :class:`~rcm_kin.identification.bands.PredictionBand`."""
    ratio = band.end_width_over_travel
    width = f"{np.degrees(band.end_width):.3f} deg" + (f" ({ratio:.2f} x the measured travel "
                                                         f"{np.degrees(band.travel):+.3f} deg)" if ratio else "")
    sources = ", ".join(f"{n} {k}" for n, k in band.sources.items())
    lines = [f"{band.level:.0%} band of {band.members} members ({sources}): width at the end {width}; "
             f"the measured angle inside {band.coverage:.1%} of the time from {band.time[band.start]:.2f} s, the final "
             f"angle {'inside' if band.final_inside else 'OUTSIDE'}; median fit {band.median_fit:.1f} %"]
    if band.undetermined:
        lines.append("  not determined by the logs, taken over their ranges: " + ", ".join(
            f"{n} {' / '.join(f'{v:.3g}' for v in vs)}" for n, vs in band.undetermined.items()))
    if band.extrapolated:
        lines.append(f"  extrapolated: {band.note}")
    elif band.note:
        lines.append(f"  {band.note}")
    return lines

"""``gravity``, ``torque-map``, ``calibrate``: what it takes to hold a pose, and the drive fit to holds."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import (
    RAW,
    add_force,
    add_json,
    add_params,
    any_robot,
    emit,
    finite,
    joint_values,
    new_output,
    path_text,
    progress_wanted,
    psm_robot,
    require_psm,
)
from rcm_kin.errors import RcmKinError, output_folder
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.model import load_robot

EPILOG_TORQUE_MAP = ("example: rcm-kin torque-map psm --roll=-30:30:61 --pitch=-30:30:61 --insertion 0.08 --out maps\n"
                     "large: rcm-kin torque-map psm --roll=-30:30:1001 --pitch=-30:30:1001 --format npz --out maps\n"
                     "(write negative ranges with =, as argparse reads a leading - as an option)")


def add_gravity(sub) -> None:
    p = sub.add_parser("gravity", help="holding torque (and PSM motor voltage/PWM) at a pose", parents=[any_robot()],
                       epilog="example: rcm-kin gravity psm 10 -15 0.08 --deg --json   "
                              "(roll, pitch in deg, insertion m)",
                       formatter_class=RAW)
    p.add_argument("q", nargs="*", metavar="Q", help="actuated joint values in 'info' order (rad, m); missing are 0")
    p.add_argument("--deg", action="store_true", help="revolute values in degrees")
    p.add_argument("--no-counterweights", action="store_true", help="remove the counterweights' mass")
    add_params(p)
    add_json(p, '{"joints", "tau" (N m, N), "pwm" (counts), "voltage" (V)} (PWM/V for roll, pitch, insertion)')
    p.set_defaults(func=cmd_gravity)


def add_torque_map(sub) -> None:
    p = sub.add_parser("torque-map", help="holding torque/voltage/PWM over roll x pitch (CSV + PNG)",
                       parents=[psm_robot()], epilog=EPILOG_TORQUE_MAP, formatter_class=RAW)
    p.add_argument("--roll", default="-30:30:61",
                   help="roll grid LO:HI:N in degrees, N >= 2 (or LO:LO:1, one value; default -30:30:61)")
    p.add_argument("--pitch", default="-30:30:61",
                   help="pitch grid LO:HI:N in degrees, N >= 2 (or LO:LO:1; default -30:30:61; at most "
                        "1001 x 1001 poses in all)")
    p.add_argument("--insertion", type=finite(unit="m"), default=HOME_INSERTION,
                   help=f"insertion in m (default {HOME_INSERTION:g})")
    p.add_argument("--no-counterweights", action="store_true", help="remove the counterweights' mass")
    add_params(p)
    p.add_argument("--out", required=True, type=path_text, help="output folder (created)")
    p.add_argument("--format", choices=("csv", "npz"), default="csv",
                   help="tables as csv (text, 9 decimals; default) or npz (NumPy, full precision, one array per "
                        "CSV column: np.load; fastest for large maps)")
    p.add_argument("--no-figures", action="store_true", help="write the tables only, not the three PNG figures")
    add_json(p, '{"files": [...], "poses": N}')
    p.set_defaults(func=cmd_torque_map)


def add_calibrate(sub) -> None:
    p = sub.add_parser("calibrate", help="fit drive gain and gravity offsets to measured holding efforts",
                       epilog="example: rcm-kin calibrate ../shared/data --out my_drive.toml")
    p.add_argument("data", type=path_text, help="folder with roll-step/*.csv and pitch-prbs/*.csv telemetry logs")
    add_params(p, "starting drive parameter TOML (default: the shipped set)")
    p.add_argument("--out", help="write the calibrated parameter TOML here (a new .toml file unless --force)")
    add_force(p)
    add_json(p, "parameters with uncertainty, residuals per point")
    p.set_defaults(func=cmd_calibrate)


def cmd_gravity(args) -> None:
    from rcm_kin.dynamics.drive import DRIVEN
    from rcm_kin.statics.maps import holding_effort

    robot = load_robot(args.robot, counterweights=not args.no_counterweights)
    if args.params is not None and robot.name != "psm":
        raise RcmKinError(f"--params sets the PSM's drives; the {robot.name} has none")
    q = joint_values(robot, args)
    effort = holding_effort(robot, q, args.params)
    payload = {"joints": list(robot.actuated), "q": q.tolist(), "tau": effort.tau.tolist()}
    if effort.drive is not None:
        payload.update(pwm=effort.drive.pwm.tolist(), voltage=effort.drive.voltage.tolist(), driven=list(DRIVEN),
                       saturated=effort.drive.saturated.tolist())
    else:
        payload.update(pwm=[], voltage=[], driven=[])
    units = ["N" if robot.joint_kind(n) == "prismatic" else "N m" for n in robot.actuated]
    lines = [f"{n:16} {t:+10.4f} {u}" for n, t, u in zip(robot.actuated, payload["tau"], units)]
    if payload["pwm"]:
        lines.append("driven joints (hardware PWM sign: positive decreases the angle):")
        lines += [f"{n:16} {v:+8.3f} V  {p:+8.2f} PWM" + ("  SATURATED" if s else "")
                  for n, v, p, s in zip(DRIVEN, payload["voltage"], payload["pwm"], payload["saturated"])]
    emit(args, payload, "\n".join(lines))


def cmd_torque_map(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.statics.maps import check_map_size, parse_range, write_gravity_maps

    require_psm(args, "torque maps are for the PSM's driven joints: rcm-kin torque-map psm ...")
    robot = load_robot("psm", counterweights=not args.no_counterweights)
    drive = load_drive_parameters(args.params)
    roll, pitch = (np.linspace(*parse_range(t, w)) for t, w in ((args.roll, "--roll"), (args.pitch, "--pitch")))
    check_map_size(roll.size * pitch.size)           # size and limits before the output folder is made
    for corner in ((roll[0], pitch[0]), (roll[-1], pitch[-1])):
        robot.check_limits(robot.check_q([*np.radians(corner), args.insertion], allow_short=True))
    gmap, files = write_gravity_maps(robot, drive, roll, pitch, args.insertion, output_folder(args.out),
                                     progress=progress_wanted(args), table=args.format, figures=not args.no_figures)
    payload = {"files": [str(f) for f in files], "poses": int(gmap.effort.tau[..., 0].size)}
    emit(args, payload, "\n".join(f"wrote {f}" for f in files))


def cmd_calibrate(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters, write_parameters
    from rcm_kin.identification.calibration import UNITS, calibrate, calibration_logs, holding_points

    base = load_drive_parameters(args.params)
    out = new_output(args.out, args.force, (".toml",)) if args.out is not None else None
    points = holding_points(calibration_logs(args.data))
    result = calibrate(load_robot("psm"), base, points)
    fitted = list(zip(result.names, result.values, result.std, UNITS))
    payload = {"parameters": {n: {"value": float(v), "std": float(s), "unit": u} for n, v, s, u in fitted},
               "residual_rms_pwm": result.residual_rms.tolist(), "friction_band_pwm": result.friction_band.tolist(),
               "points": [{"source": p.source, "roll_deg": float(np.degrees(p.roll)),
                           "pitch_deg": float(np.degrees(p.pitch)), "measured_pwm": [p.pwm_roll, p.pwm_pitch],
                           "predicted_pwm": pred.tolist()} for p, pred in zip(points, result.predicted)]}
    if out:
        header = (f"Drive parameters calibrated by `rcm-kin calibrate` on {len(points)} holding points.\n"
                  + "\n".join(f"{n} = {v:.6g} +- {s:.2g} {u}" for n, v, s, u in fitted)
                  + f"\nresidual RMS roll {result.residual_rms[0]:.2f}, pitch {result.residual_rms[1]:.2f} PWM; "
                  f"largest |residual| roll {result.friction_band[0]:.2f}, pitch {result.friction_band[1]:.2f} PWM."
                  "\nFormat and assumed constants: see the shipped urdf/psm_drive.toml.")
        payload["written"] = str(write_parameters(result.parameters, out, header))
    lines = [f"{n:20} {v:+.6g} +- {s:.2g} {u}" for n, v, s, u in fitted]
    lines.append(f"residual RMS: roll {result.residual_rms[0]:.2f}, pitch {result.residual_rms[1]:.2f} PWM "
                 f"over {len(points)} holding points")
    if out:
        lines.append(f"wrote {payload['written']}")
    emit(args, payload, "\n".join(lines))

"""``gravity``, ``torque-map``: what it takes to hold a pose (and, with ``--band``, the holding PWM band)."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.calibration import BAND_HELP, band_level
from rcm_kin.cli.common import (
    RAW,
    add_json,
    add_params,
    any_robot,
    emit,
    finite,
    floats,
    is_bundled_psm,
    joint_values,
    path_text,
    progress_wanted,
)
from rcm_kin.cli.outputs import FOLDER_FORCE, new_folder
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.model import load_robot

PSM_GRID_DEFAULT = "-30:30:61"
OWN_DRIVE_HELP = ("drive parameter TOML of this robot (default: the one its sidecar names; none: its URDF inertias, "
                  "torque only)")
EPILOG_TORQUE_MAP = ("example: rcm-kin torque-map psm --roll=-30:30:61 --pitch=-30:30:61 --insertion 0.08 --out maps\n"
                     "any robot: rcm-kin torque-map mtm --grid j1=-60:60:61 j3=-30:80:56 --out maps (shoulder, elbow)\n"
                     "large: rcm-kin torque-map psm --roll=-30:30:1001 --pitch=-30:30:1001 --format npz --out maps\n"
                     "(write negative ranges with =, as argparse reads a leading - as an option)")


def add_gravity(sub) -> None:
    p = sub.add_parser("gravity", help="holding torque (and motor voltage/PWM where a drive is described) at a pose",
                       parents=[any_robot()],
                       epilog="example: rcm-kin gravity psm 10 -15 0.08 --deg --json   "
                              "(roll, pitch in deg, insertion m)",
                       formatter_class=RAW)
    p.add_argument("q", nargs="*", metavar="Q", help="actuated joint values in 'info' order (rad, m); missing are 0")
    p.add_argument("--deg", action="store_true", help="revolute values in degrees")
    p.add_argument("--no-counterweights", action="store_true", help="remove the counterweights' mass")
    add_params(p, OWN_DRIVE_HELP)
    p.add_argument("--band", type=band_level, metavar="LEVEL",
                   help=f"also the holding PWM band at this level ({BAND_HELP}) from the drive file's holding "
                        "residuals, flagged 'extrapolated' outside the calibrated poses")
    add_json(p, '{"joints", "tau" (N m, N), "pwm" (counts), "voltage" (V), "driven", "model"} (PWM/V of the '
                'drive\'s joints, where the robot has a drive); --band: "band" {"level", "lower_pwm", "upper_pwm", '
                '"half_width_pwm", "nominal_pwm", "extrapolated", "outside", "hull_deg"}')
    p.set_defaults(func=cmd_gravity)


def add_torque_map(sub) -> None:
    p = sub.add_parser("torque-map", help="holding torque (and voltage/PWM where a drive is described) over two "
                                          "joints (CSV + PNG)",
                       parents=[any_robot()], epilog=EPILOG_TORQUE_MAP, formatter_class=RAW)
    p.add_argument("--grid", nargs="+", metavar="J=LO:HI:N",
                   help="any robot: the two actuated joints of the map and their grids, LO:HI:N in degrees for "
                        "revolute joints, metres for prismatic (e.g. j1=-60:60:61 j3=-30:80:56); the other joints "
                        "at zero (inside their limits) or --at")
    p.add_argument("--at", nargs="+", metavar="J=VALUE",
                   help="with --grid: values of other actuated joints (degrees for revolute, metres for prismatic)")
    p.add_argument("--roll", default=None,
                   help="the bundled PSM's form: roll grid LO:HI:N in degrees, N >= 2 (or LO:LO:1, one value; "
                        f"default {PSM_GRID_DEFAULT})")
    p.add_argument("--pitch", default=None,
                   help=f"the bundled PSM's form: pitch grid LO:HI:N in degrees, N >= 2 (or LO:LO:1; default "
                        f"{PSM_GRID_DEFAULT}; at most "
                        "1001 x 1001 poses in all)")
    p.add_argument("--insertion", type=finite(unit="m"), default=None,
                   help=f"the bundled PSM's form: insertion in m (default {HOME_INSERTION:g})")
    p.add_argument("--no-counterweights", action="store_true", help="remove the counterweights' mass")
    add_params(p, OWN_DRIVE_HELP)
    p.add_argument("--out", required=True, type=path_text, help="output folder (created)")
    p.add_argument("--force", action="store_true", help=FOLDER_FORCE)
    p.add_argument("--format", choices=("csv", "npz"), default="csv",
                   help="tables as csv (text, 9 decimals; default) or npz (NumPy, full precision, one array per "
                        "CSV column: np.load; fastest for large maps)")
    p.add_argument("--no-figures", action="store_true", help="write the tables only, not the PNG figures")
    p.add_argument("--band", type=band_level, metavar="LEVEL",
                   help=f"the tables gain the holding band at this level ({BAND_HELP}): lower_pwm_<joint>, "
                        "upper_pwm_<joint>, extrapolated (1 outside the calibrated poses)")
    add_json(p, '{"files": [...], "poses": N, "model"} (--grid: also "joints"; --band: "band" {"level", '
                '"half_width_pwm", "columns", "extrapolated_poses", "hull_deg"})')
    p.set_defaults(func=cmd_torque_map)


def cmd_gravity(args) -> None:
    from rcm_kin.dynamics.drive import resolve_drive
    from rcm_kin.statics.maps import holding_effort

    robot = load_robot(args.robot, counterweights=not args.no_counterweights)
    drive = resolve_drive(robot, args.params)        # --params of another robot: one line, before any number
    q = joint_values(robot, args)
    effort = holding_effort(robot, q, drive)
    payload = {"joints": list(robot.actuated), "q": q.tolist(), "tau": effort.tau.tolist()}
    if effort.drive is not None:
        payload.update(pwm=effort.drive.pwm.tolist(), voltage=effort.drive.voltage.tolist(), driven=list(effort.driven),
                       saturated=effort.drive.saturated.tolist())
    else:
        payload.update(pwm=[], voltage=[], driven=[])
    payload["model"] = effort.model
    units = ["N" if robot.joint_kind(n) == "prismatic" else "N m" for n in robot.actuated]
    lines = [f"{n:16} {t:+10.4f} {u}" for n, t, u in zip(robot.actuated, payload["tau"], units)]
    if payload["pwm"]:
        lines.append("driven joints (hardware PWM sign: positive decreases the angle):")
        lines += [f"{n:16} {v:+8.3f} V  {p:+8.2f} PWM" + ("  SATURATED" if s else "")
                  for n, v, p, s in zip(effort.driven, payload["voltage"], payload["pwm"], payload["saturated"])]
    if args.band is not None:
        lines += band_text(robot, q, drive, args.band, payload)
    lines.append(f"model: {effort.model}")
    emit(args, payload, "\n".join(lines))


def band_text(robot, q, drive, level: float, payload: dict) -> list[str]:
    """``gravity --band``: the band into ``payload["band"]``, and its lines for people."""
    from rcm_kin.statics.holding_band import file_name, holding_band, hull_text

    band = holding_band(robot, q, level, drive)
    payload["band"] = band.as_dict()
    lines = [f"holding band {level:g} (PWM, nominal -+ half-width of the left-out holding residuals):"]
    lines += [f"{n:16} {lo:+8.2f} to {hi:+8.2f} PWM  (+-{h:.2f})"
              for n, lo, hi, h in zip(band.joints, band.lower, band.upper, band.half_width)]
    lines += [f"{n:16} no band: no holding residuals in {file_name(drive)}" for n in drive.driven
              if n not in band.joints]
    if band.extrapolated:
        lines.append(f"extrapolated (outside the calibrated poses {hull_text(drive)}): {', '.join(band.outside)} "
                     "outside; the band's level is not supported there")
    return lines


def cmd_torque_map(args) -> None:
    if args.grid is not None:
        return grid_torque_map(args)
    if args.at is not None:
        raise RcmKinError("--at sets the other joints of a --grid map: give --grid J=LO:HI:N J=LO:HI:N")
    return psm_torque_map(args)


def _grid_needed(args) -> str:
    """What a torque map of a robot other than the bundled PSM needs, with its own joints as the example."""
    if any(x is not None for x in (args.roll, args.pitch, args.insertion)):
        return (f"--roll/--pitch/--insertion are the bundled PSM's: for {args.robot} give --grid J=LO:HI:N "
                "J=LO:HI:N over two of its actuated joints")
    robot = load_robot(args.robot)
    words = [f"{n}={np.degrees(lo):g}:{np.degrees(hi):g}:61" if robot.joint_kind(n) == "revolute" else
             f"{n}={lo:g}:{hi:g}:61" for n, lo, hi in zip(robot.actuated[:2], robot.lower, robot.upper)]
    return (f"a torque map of {robot.name} is over two of its actuated joints ({', '.join(robot.actuated)}): give "
            f"--grid, e.g. rcm-kin torque-map {args.robot} --grid {' '.join(words)} --out {args.out}")


def psm_torque_map(args) -> None:
    from rcm_kin.statics.holding_band import residuals_of
    from rcm_kin.statics.maps import check_map_size, map_drive, parse_range, write_gravity_maps

    if not is_bundled_psm(args.robot):
        raise RcmKinError(_grid_needed(args))
    robot = load_robot("psm", counterweights=not args.no_counterweights)
    drive = map_drive(robot, args.params)            # --params of another robot: one line, nothing written
    roll_text, pitch_text = (t if t is not None else PSM_GRID_DEFAULT for t in (args.roll, args.pitch))
    insertion = HOME_INSERTION if args.insertion is None else args.insertion
    roll, pitch = (np.linspace(*parse_range(t, w)) for t, w in ((roll_text, "--roll"), (pitch_text, "--pitch")))
    check_map_size(roll.size * pitch.size)           # size and limits before the output folder is made
    for corner in ((roll[0], pitch[0]), (roll[-1], pitch[-1])):
        robot.check_limits(robot.check_q([*np.radians(corner), insertion], allow_short=True))
    if args.band is not None:
        residuals_of(drive)                          # none in the file: one line, nothing written
    gmap, files = write_gravity_maps(robot, drive, roll, pitch, insertion, new_folder(args.out, args.force),
                                     progress=progress_wanted(args), table=args.format, figures=not args.no_figures,
                                     band=args.band)
    payload = {"files": [str(f) for f in files], "poses": int(gmap.effort.tau[..., 0].size), "model": drive.model}
    emit_map(args, payload, files, drive, gmap.extra)


def emit_map(args, payload: dict, files, drive, extra: dict) -> None:
    """A torque map's output: the files written, the model, and with ``--band`` the band's summary."""
    from rcm_kin.statics.holding_band import band_summary, hull_text

    lines = [*(f"wrote {f}" for f in files), f"model: {payload['model']}"]
    if args.band is not None:
        payload["band"] = band = band_summary(drive, args.band, extra)
        lines.append(f"holding band {args.band:g}: " + ", ".join(f"{j} +-{h:.2f} PWM"
                                                                   for j, h in band["half_width_pwm"].items()))
        if band["extrapolated_poses"]:
            lines.append(f"extrapolated (outside the calibrated poses {hull_text(drive)}): "
                         f"{band['extrapolated_poses']} of {payload['poses']} poses (column extrapolated = 1)")
    emit(args, payload, "\n".join(lines))


def grid_torque_map(args) -> None:
    from rcm_kin.dynamics.drive import resolve_drive
    from rcm_kin.statics.holding import torque_map, write_torque_map

    if any(x is not None for x in (args.roll, args.pitch, args.insertion)):
        raise RcmKinError("--grid replaces --roll/--pitch/--insertion: give the joints' values with --grid and --at")
    robot = load_robot(args.robot, counterweights=not args.no_counterweights)
    drive = resolve_drive(robot, args.params)
    grid, q = grid_and_pose(robot, args.grid, args.at)
    tmap = torque_map(robot, grid, q, drive, counterweights=not args.no_counterweights,
                      progress=progress_wanted(args), band=args.band)
    files = write_torque_map(tmap, new_folder(args.out, args.force), args.format, figures=not args.no_figures)
    payload = {"files": [str(f) for f in files], "poses": tmap.poses, "joints": list(tmap.joints),
               "model": tmap.model}
    emit_map(args, payload, files, tmap.params, tmap.extra)


def grid_and_pose(robot, grid_words: list[str], at_words: list[str] | None) -> tuple[dict, np.ndarray]:
    """``--grid J=LO:HI:N J=LO:HI:N`` and ``--at J=VALUE ...`` (degrees for revolute joints, metres
    for prismatic) as the grid {joint: values} and the pose of the other joints, SI (rad, m): two
    different actuated joints, a map of at most MAX_POSES poses, no ``--at`` on a grid joint."""
    from rcm_kin.statics.holding import check_actuated, default_pose
    from rcm_kin.statics.maps import check_map_size, parse_range

    grid = {}
    for name, text in joint_assignments(grid_words, "--grid"):
        check_actuated(robot, name)
        if name in grid:
            raise RcmKinError(f"--grid names {name} twice: give two different joints")
        unit = "deg" if robot.joint_kind(name) == "revolute" else "m"
        grid[name] = np.linspace(*parse_range(text, f"--grid {name}", unit))
    if len(grid) != 2:
        raise RcmKinError(f"--grid takes two joints J=LO:HI:N J=LO:HI:N, got {len(grid)}")
    check_map_size(int(np.prod([v.size for v in grid.values()])))
    q = default_pose(robot)
    for name, text in joint_assignments(at_words or [], "--at"):
        check_actuated(robot, name)
        if name in grid:
            raise RcmKinError(f"--at {name}: {name} is a joint of the grid")
        q[robot.actuated.index(name)] = to_si(robot, name, floats([text], f"--at {name}")[0])
    return {name: to_si(robot, name, values) for name, values in grid.items()}, q


def joint_assignments(words: list[str], flag: str) -> list[tuple[str, str]]:
    """``J=VALUE`` words as (joint, value text), or a user error naming ``flag``."""
    out = []
    for word in words:
        name, sep, value = word.partition("=")
        if not sep or not name or not value:
            raise RcmKinError(f"{flag} takes JOINT=VALUE words (e.g. j2=-40:60:51), got {word!r}"[:200])
        out.append((name, value))
    return out


def to_si(robot, joint: str, value):
    """A command-line joint value (degrees for a revolute joint, metres for a prismatic one) in rad or m."""
    return np.radians(value) if robot.joint_kind(joint) == "revolute" else value

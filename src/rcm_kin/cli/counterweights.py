"""``counterweights``: where a counterweight the sidecar marks best holds the arm, for any robot."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import RAW, add_json, add_params, any_robot, emit, finite
from rcm_kin.errors import RcmKinError
from rcm_kin.model import load_robot

EPILOG = ("examples: rcm-kin counterweights mtm --grid j1=-60:60:25 j3=-30:80:23 --json\n"
          "          rcm-kin counterweights psm --grid roll=-30:30:13 pitch=-30:30:13 --link main_counterweight\n"
          "Gravity is affine in the counterweight's position: a linear least-squares fit (minimum norm where the\n"
          "grid leaves a direction free, e.g. along the joint axis), weighed in PWM counts where a drive is\n"
          "described, else in N m. Positions in the frame of the link the counterweight is fixed to.")


def add_counterweights(sub) -> None:
    p = sub.add_parser("counterweights", help="place the counterweights the sidecar marks: the position that best "
                                              "holds the arm over two joints' grid",
                       parents=[any_robot()], epilog=EPILOG, formatter_class=RAW)
    p.add_argument("--grid", nargs="+", metavar="J=LO:HI:N", required=True,
                   help="the two actuated joints weighed over and their grids, LO:HI:N in degrees for revolute "
                        "joints, metres for prismatic; the other joints at zero (inside their limits) or --at")
    p.add_argument("--at", nargs="+", metavar="J=VALUE", help="values of other actuated joints (deg, m)")
    p.add_argument("--link", help="one counterweight link (default: every one the sidecar marks)")
    p.add_argument("--mass", type=finite(0.0, 100.0, "kg", open_lo=True),
                   help="counterweight mass in kg (default: the URDF's)")
    p.add_argument("--max-distance", type=finite(0.0, 10.0, "m", open_lo=True), default=0.30,
                   help="bound on each coordinate of the position, m (default 0.3)")
    add_params(p, "drive parameter TOML of this robot (default: its own drive file, else torque in N m)")
    add_json(p, '{"model", "counterweights": [{"link", "mount", "mass_kg", "position_m", "as_built_m", '
                '"distance_m", "joints", "unit", "units", "rms", "peak", "rms_as_built", "rms_without", "rank"}]}')
    p.set_defaults(func=cmd_counterweights)


def cmd_counterweights(args) -> None:
    from rcm_kin.cli.statics import grid_and_pose
    from rcm_kin.dynamics.drive import resolve_drive
    from rcm_kin.statics.counterweights import place_counterweight

    robot = load_robot(args.robot)
    if not robot.description.counterweights:
        raise RcmKinError(f"{robot.name}'s sidecar marks no counterweight link (its `counterweights` list)")
    links = robot.description.counterweights if args.link is None else (args.link,)
    drive = resolve_drive(robot, args.params)
    grid, q = grid_and_pose(robot, args.grid, args.at)     # size, units and --at as torque-map's
    designs = [place_counterweight(robot, link, grid, q, args.mass, drive, max_distance=args.max_distance)
               for link in links]
    payload = {"model": designs[0].model, "counterweights": [{
        "link": d.link, "mount": d.mount, "mass_kg": d.mass, "position_m": d.position.tolist(),
        "as_built_m": d.as_built.tolist(), "distance_m": d.distance, "joints": list(d.joints), "unit": d.unit,
        "units": list(d.units), "rms": d.rms.tolist(), "peak": d.peak.tolist(), "rms_as_built": d.rms_as_built.tolist(),
        "rms_without": d.rms_without.tolist(), "rank": d.rank} for d in designs]}
    lines = []
    for d in designs:
        built = np.round(d.as_built * 1e3, 1).tolist()
        lines.append(f"{d.link} ({d.mass:.4g} kg) on {d.mount}: at {np.round(d.position * 1e3, 1).tolist()} mm "
                     f"({d.distance * 1e3:.1f} mm from its origin; as built {built} mm)")
        if np.any(np.isclose(np.abs(d.position), args.max_distance)):
            lines.append(f"  (at the --max-distance bound {args.max_distance:g} m: a heavier counterweight would sit "
                         "closer)")
        lines += [f"  {j:16} RMS {w:9.4f} without, {b:9.4f} as built, {r:9.4f} placed  ({u})"
                  for j, w, b, r, u in zip(d.joints, d.rms_without, d.rms_as_built, d.rms, d.units)]
        if d.rank < 3:
            lines.append(f"  (the grid fixes {d.rank} of the 3 coordinates: the minimum-norm position is given)")
    lines.append(f"model: {designs[0].model}")
    emit(args, payload, "\n".join(lines))

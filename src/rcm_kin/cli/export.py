"""``export``: a bundled robot in another tool's format. Each format is one option and one writer
call; the handler only dispatches: ``--mjcf FILE`` (MuJoCo), ``--c DIR`` (plain C99 of the PSM's
holding PWM for the firmware)."""

from __future__ import annotations

from rcm_kin.cli.common import RAW, add_force, add_json, add_params, any_robot, emit, new_output
from rcm_kin.errors import RcmKinError
from rcm_kin.model import load_robot

EPILOG = ("examples: rcm-kin export psm --mjcf psm.xml   (MuJoCo: python -m mujoco.viewer --mjcf psm.xml)\n"
          "          rcm-kin export davinci --mjcf davinci.xml\n"
          "          rcm-kin export psm --c firmware/model --json")


def add_export(sub) -> None:
    p = sub.add_parser("export", help="write a robot model for another tool (MuJoCo MJCF, C99 for the firmware)",
                       parents=[any_robot()], epilog=EPILOG, formatter_class=RAW)
    p.add_argument("--mjcf", metavar="FILE", help="MuJoCo MJCF file: loops closed by equality/connect, a motor "
                                                  "per actuated joint (N m, N), keyframes (home, thesis grid)")
    p.add_argument("--c", metavar="DIR", help="PSM only: write rcm_psm_model.h/.c, the holding PWM (counts) and its "
                                              "gradient as functions of roll, pitch (rad), insertion (m)")
    add_params(p, "drive parameter TOML for the PSM's drives (default: the shipped calibrated set)")
    add_force(p)
    add_json(p, '{"files": [...]} and, with --c, "operations": N, "functions": [...], "operation_counts": {...}')
    p.set_defaults(func=cmd_export)


def cmd_export(args) -> None:
    if args.mjcf is None and args.c is None:
        raise RcmKinError("choose what to write: --mjcf FILE and/or --c DIR")
    robot = load_robot(args.robot)
    if robot.name != "psm" and (args.params or args.c):
        raise RcmKinError(f"--c writes the PSM's holding PWM and --params sets the PSM's drives; the "
                          f"{robot.name} has neither (rcm-kin export psm --c DIR)")
    mjcf = None if args.mjcf is None else new_output(args.mjcf, args.force, (".xml",))
    if args.c is not None and not str(args.c).strip():
        raise RcmKinError("--c: an empty folder path; give the folder for rcm_psm_model.h/.c (created if missing)")
    if args.c is not None and not args.force:
        from rcm_kin.codegen.psm_model import c_files

        existing = [f.name for f in c_files(args.c) if f.exists()]
        if existing:
            raise RcmKinError(f"{args.c} already holds {', '.join(existing)}: choose another folder or add --force")
    payload, lines = {"files": []}, []
    if mjcf:
        from rcm_kin.dynamics.drive import load_drive_parameters
        from rcm_kin.export.mjcf import write_mjcf

        params = load_drive_parameters(args.params) if robot.name == "psm" else None
        payload["files"].append(str(write_mjcf(robot, mjcf, params)))
        lines.append(f"wrote {payload['files'][-1]}")
    if args.c is not None:
        from rcm_kin.cli.common import driven_model
        from rcm_kin.codegen.psm_model import export_c

        result = export_c(driven_model(args.params, coulomb=False), args.c, source=args.params or "")
        payload["files"] += [str(f) for f in result.files]
        payload.update(operations=result.operations, functions=result.functions,
                       operation_counts=result.operation_counts)
        lines += [f"wrote {f}" for f in result.files]
        lines.append(f"{', '.join(result.functions)}: {result.operations} floating-point operations per call")
    emit(args, payload, "\n".join(lines))

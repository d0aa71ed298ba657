"""``export``: a robot in another tool's format. Each format is one option and one writer call; the
handler only dispatches: ``--mjcf FILE`` (MuJoCo, any robot), ``--c DIR`` (plain C99 of the bundled
PSM's holding PWM for the firmware)."""

from __future__ import annotations

from rcm_kin.cli.common import RAW, add_json, add_params, any_robot, emit, is_bundled_psm
from rcm_kin.cli.outputs import add_force, new_output
from rcm_kin.cli.packages import add_package_dirs, package_dirs
from rcm_kin.errors import RcmKinError
from rcm_kin.model import load_robot

EPILOG = ("examples: rcm-kin export psm --mjcf psm.xml   (MuJoCo: python -m mujoco.viewer --mjcf psm.xml)\n"
          "          rcm-kin export davinci --mjcf davinci.xml\n"
          "          rcm-kin export my_arm.toml --mjcf arm.xml --package-dir my_arm_description=~/ws/src/my_arm\n"
          "          rcm-kin export psm --c firmware/model --json\n"
          "The MJCF holds the model `rcm-kin gravity` uses: the robot's own calibration (its sidecar's drive\n"
          "file; --params another of the same robot) as centre-of-mass shifts, or the URDF inertias (CAD).")


def add_export(sub) -> None:
    p = sub.add_parser("export", help="write a robot model for another tool (MuJoCo MJCF; C99 for the PSM's firmware)",
                       parents=[any_robot()], epilog=EPILOG, formatter_class=RAW)
    p.add_argument("--mjcf", metavar="FILE", help="MuJoCo MJCF file (any robot): loops closed by equality/connect, "
                                                  "a motor per actuated joint (N m, N), keyframes (home; the PSM's "
                                                  "thesis grid), STL/OBJ meshes as assets")
    p.add_argument("--c", metavar="DIR", help="the bundled PSM only (other robots are refused): write "
                                              "rcm_psm_model.h/.c, the holding PWM (counts) and its gradient as "
                                              "functions of roll, pitch (rad), insertion (m)")
    add_params(p, "drive parameter TOML of this robot (it must name it): its calibration goes into the MJCF "
                  "(default: the robot's own drive file, else the URDF inertias); with --c the PSM's drives")
    add_package_dirs(p)
    add_force(p)
    add_json(p, '{"files": [...], "model": "CAD (URDF inertias)" | "calibration FILE"} and, with --c, '
                '"operations": N, "functions": [...], "operation_counts": {...}')
    p.set_defaults(func=cmd_export)


def _check_c(args) -> None:
    """``--c DIR``: the bundled PSM's, a folder path, no files overwritten without --force."""
    if not is_bundled_psm(args.robot):
        raise RcmKinError(f"--c writes the bundled PSM's holding PWM for its firmware; {args.robot} is not the "
                          "bundled psm (rcm-kin export psm --c DIR; --mjcf works for any robot)")
    if not str(args.c).strip():
        raise RcmKinError("--c: an empty folder path; give the folder for rcm_psm_model.h/.c (created if missing)")
    if not args.force:
        from rcm_kin.codegen.psm_model import c_files

        existing = [f.name for f in c_files(args.c) if f.exists()]
        if existing:
            raise RcmKinError(f"{args.c} already holds {', '.join(existing)}: choose another folder or add --force")


def cmd_export(args) -> None:
    if args.mjcf is None and args.c is None:
        raise RcmKinError("choose what to write: --mjcf FILE and/or --c DIR")
    if args.c is not None:
        _check_c(args)
    robot = load_robot(args.robot)
    mjcf = None if args.mjcf is None else new_output(args.mjcf, args.force, (".xml",))
    payload, lines = {"files": []}, []
    if mjcf:
        from rcm_kin.dynamics.drive import model_label, resolve_drive
        from rcm_kin.export.mjcf import write_mjcf

        params = resolve_drive(robot, args.params)
        payload["files"].append(str(write_mjcf(robot, mjcf, params, package_dirs(args))))
        payload["model"] = model_label(params)
        lines += [f"wrote {payload['files'][-1]}", f"model: {payload['model']}"]
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

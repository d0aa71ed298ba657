"""``export``: the model written for other tools; ``--c DIR`` plain C99 of the PSM's holding PWM."""

from __future__ import annotations

from rcm_kin.cli.common import RAW, add_json, add_params, emit, psm_robot, require_psm
from rcm_kin.errors import RcmKinError


def add_export(sub) -> None:
    p = sub.add_parser("export", help="write the model for other tools (plain C99 for the firmware)",
                       parents=[psm_robot()], formatter_class=RAW,
                       epilog="example: rcm-kin export psm --c firmware/model --json")
    p.add_argument("--c", metavar="DIR", help="write rcm_psm_model.h/.c: holding PWM (counts) and its gradient "
                                              "as functions of roll, pitch (rad), insertion (m)")
    add_params(p)
    add_json(p, '{"files": [...], "operations": N, "functions": [...], "operation_counts": {...}}')
    p.set_defaults(func=cmd_export)


def cmd_export(args) -> None:
    if not args.c:
        raise RcmKinError("say what to export: --c DIR")
    require_psm(args, "the C model is the PSM's holding PWM: rcm-kin export psm --c DIR")
    from rcm_kin.cli.common import driven_model
    from rcm_kin.codegen.psm_model import export_c

    result = export_c(driven_model(args.params, coulomb=False), args.c, source=args.params or "")
    payload = {"files": [str(f) for f in result.files], "operations": result.operations,
               "functions": result.functions, "operation_counts": result.operation_counts}
    lines = [f"wrote {f}" for f in result.files]
    lines.append(f"{', '.join(result.functions)}: {result.operations} floating-point operations per call")
    emit(args, payload, "\n".join(lines))

"""``safety simulate`` and ``safety certify``: CBF-filtered scenarios and SOS barrier certificates."""

from __future__ import annotations

from rcm_kin.cli.common import RAW, Parser, add_json, emit, finite, path_text
from rcm_kin.errors import RcmKinError

LENGTH = finite(0, 1, open_lo=True)      # the certificates' sets live within +-0.1 m (eps_bar: B, unitless)
EPILOG_SAFETY = ("examples: rcm-kin safety simulate ellipsoid --json   (CBF blend on the 3-D no-go ellipsoid)\n"
                 "          rcm-kin safety simulate psm --filter qp   (PSM teleoperation towards a forbidden region)\n"
                 "          rcm-kin safety certify 3 --error-bound 0.007 --json   (SOS barrier certificate)")


def add_safety(sub) -> None:
    p = sub.add_parser("safety", help="CBF safety filter simulations and SOS barrier certificates",
                       epilog=EPILOG_SAFETY, formatter_class=RAW)
    safety = p.add_subparsers(dest="safety_command", required=True, parser_class=Parser)
    s = safety.add_parser("simulate", help="a scenario of the safety thesis with the CBF filter", epilog=EPILOG_SAFETY,
                          formatter_class=RAW)
    s.add_argument("scenario", choices=("ellipsoid", "slide", "heart", "psm"),
                   help="ellipsoid: 3-D no-go ellipsoid (radii 30/60/30 mm); slide: workspace [-0.10, 0.05] m; "
                        "heart: beating-heart fixture; psm: our PSM teleoperated towards a 1.5 mm no-go ellipsoid")
    s.add_argument("--filter", choices=("blend", "qp", "none"), default="blend",
                   help="blend: the thesis's sigma k0 + (1 - sigma) u; qp: CBF-QP (DAQP, exact active set); "
                        "none (default blend)")
    s.add_argument("--kappa", type=finite(0, 100, "m", open_lo=True),
                   help="aggressiveness of k0 in m, in (0, 100] (default 1; psm 0.01)")
    s.add_argument("--trajectory", type=path_text, help="psm: MTM recording CSV (default: the bundled figure-eight)")
    add_json(s, '{"min_margin", "violations", ...}')
    s.set_defaults(func=cmd_safety_simulate)
    s = safety.add_parser("certify", help="SOS barrier certificate of one of the thesis's programs 1-4",
                          epilog=EPILOG_SAFETY, formatter_class=RAW)
    s.add_argument("program", choices=("1", "2", "3", "4"),
                   help="1: slide first order, zero reference; 2: reference as a state; 3: first-order error "
                        "state; 4: second-order error state")
    s.add_argument("--delta", type=LENGTH, help="separation of the initial and unsafe sets in m (thesis: 0.001, "
                                               "0.015, 0.004, 0.005)")
    s.add_argument("--error-bound", type=LENGTH,
                   help="programs 3-4: unsafe error beyond this in m (thesis 0.009, 0.008)")
    s.add_argument("--r-max", type=LENGTH, help="program 2: largest reference in m (thesis 0.017)")
    s.add_argument("--eps-bar", type=LENGTH, help="B on the unsafe set at least this (thesis 0.001, 0.1, 0.01, 0.05)")
    add_json(s, '{"feasible", "certificate", "sampling_check", ...}')
    s.set_defaults(func=cmd_safety_certify)


def cmd_safety_simulate(args) -> None:
    from rcm_kin.safety.scenarios import run_scenario

    options = {"kappa": args.kappa} if args.kappa is not None else {}
    if args.trajectory:
        if args.scenario != "psm":
            raise RcmKinError("--trajectory is for the psm scenario")
        options["trajectory"] = args.trajectory
    summary = run_scenario(args.scenario, args.filter, **options).summary()
    payload = {"scenario": args.scenario, "filter": args.filter, **summary}
    lines = [f"{args.scenario} with the {args.filter} filter: min margin {summary['min_margin']:+.4g} "
             f"(-max B; >= 0 is safe), {summary['violations']} of {summary['samples']} samples unsafe"]
    if "min_distance_mm" in summary:
        lines.append(f"achieved shaft tip: at least {summary['min_distance_mm']:.3f} mm outside the ellipsoid; "
                     f"filtered reference margin {summary['reference_min_margin']:+.4g}")
    emit(args, payload, "\n".join(lines))


def cmd_safety_certify(args) -> None:
    from rcm_kin.safety.sos import find_certificate, poly_text, thesis_program

    program = thesis_program(args.program, args.delta, args.error_bound, args.r_max, args.eps_bar)
    certificate = find_certificate(program)
    payload = {"program": args.program, "name": program.name, "feasible": certificate.feasible,
               "solver_status": certificate.status,
               "certificate": certificate.as_dict() if certificate.B else None}
    lines = [f"program {args.program} ({program.name}): {'FEASIBLE' if certificate.feasible else 'no certificate'} "
             f"(solver: {certificate.status})"]
    if certificate.B:
        check = certificate.check                     # find_certificate's sampling check
        payload["sampling_check"] = vars(check)
        lines += [f"B = {poly_text(certificate.B, program.variables)}",
                  f"sampling check: max B on X0 {check.initial_max_B:+.3g}, min B on Xu {check.unsafe_min_B:+.3g}, "
                  f"max L_f B on X {check.max_lie:+.3g} -> {'passed' if check.passed else 'FAILED'}"]
    emit(args, payload, "\n".join(lines))

"""``dynamics``, ``linearize``, ``schedule``: the PSM's driven-joint model and its gain schedule."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from rcm_kin.cli.common import (
    RAW,
    add_json,
    add_params,
    count,
    driven_model,
    emit,
    finite,
    floats,
    path_text,
    psm_robot,
    require_psm,
)
from rcm_kin.control.friction import DEFAULT_RAMP_DEG_S
from rcm_kin.control.weights import Weights
from rcm_kin.errors import output_folder
from rcm_kin.hardware import DRIVER_PWM_RANGE, FIRMWARE_PERIOD, HOME_INSERTION

MAX_CHECK_POINTS = 201    # 201 x 201 poses: about a minute of eigenvalues
NOT_PSM = "the driven-joint dynamics are the PSM's (roll, pitch, insertion), not '{robot}'"
EPILOG_SCHEDULE = ("examples: rcm-kin schedule psm --out gains\n"
                   "          rcm-kin schedule psm --grid=-30,-15,0,15,30:-30,0,30 --gravity-feedforward --out gains\n"
                   "          rcm-kin schedule psm --gravity-feedforward --friction-feedforward --out gains")


def add_dynamics(sub) -> None:
    p = sub.add_parser("dynamics", help="PSM driven-joint accelerations for a state and PWM input",
                       parents=[psm_robot()],
                       epilog="example: rcm-kin dynamics psm --q 0.1 -0.2 0.08 --v 0 0 0 --u 10 -90 0 --json")
    p.add_argument("--q", nargs=3, required=True, metavar="Q", help="roll rad, pitch rad, insertion m")
    p.add_argument("--v", nargs=3, default=["0", "0", "0"], metavar="V", help="their rates (rad/s, m/s; default 0)")
    p.add_argument("--u", nargs=3, default=["0", "0", "0"], metavar="U",
                   help=f"PWM counts of the three drivers, hardware sign (|u| <= {DRIVER_PWM_RANGE:g}; default 0)")
    p.add_argument("--no-coulomb", action="store_true", help="leave the smoothed Coulomb friction out")
    add_params(p)
    add_json(p, '{"qdd": [roll rad/s^2, pitch rad/s^2, insertion m/s^2]}')
    p.set_defaults(func=cmd_dynamics)


def add_linearize(sub) -> None:
    p = sub.add_parser("linearize", help="linear model (A, B, C, D) of the PSM driven joints at a held pose",
                       parents=[psm_robot()],
                       epilog="example: rcm-kin linearize psm --roll 10 --pitch=-5 --insertion 0.08 --json")
    p.add_argument("--roll", required=True, type=finite(unit="deg"), help="roll angle in degrees")
    p.add_argument("--pitch", required=True, type=finite(unit="deg"), help="pitch angle in degrees")
    p.add_argument("--insertion", type=finite(unit="m"), default=HOME_INSERTION,
                   help=f"insertion in m (default {HOME_INSERTION:g})")
    p.add_argument("--no-coulomb", action="store_true",
                   help="leave the smoothed Coulomb friction out (its slope at rest is set by the smoothing width)")
    add_params(p)
    add_json(p, '{"x0", "u0", "A", "B", "C", "D", "state", "input"}: SI state [q; v], PWM input')
    p.set_defaults(func=cmd_linearize)


def add_schedule(sub) -> None:
    p = sub.add_parser("schedule", help="model-based LQR (roll) / LQI (pitch) gain tables, C header, JSON, CSV",
                       parents=[psm_robot()], epilog=EPILOG_SCHEDULE, formatter_class=RAW)
    p.add_argument("--grid", default="thesis",
                   help="'thesis' (roll -20,0,20 x pitch -15,0,15 deg) or ROLLS:PITCHES in degrees, comma-separated "
                        "(write --grid=-20,0,20:-15,0,15 when it starts with a minus)")
    p.add_argument("--insertion", type=finite(unit="m"), default=HOME_INSERTION,
                   help=f"insertion of the models in m (default {HOME_INSERTION:g})")
    p.add_argument("--gravity-feedforward", action="store_true",
                   help="also export the holding-PWM table (u_hold) and rcm_holding_pwm()")
    p.add_argument("--friction-feedforward", action="store_true",
                   help="also export the sliding-friction compensation (RCM_FC_* and rcm_friction_feedforward(): "
                        "-F_c/|k_u| tanh(rdot / ramp) PWM on the reference velocity; needs <math.h>)")
    p.add_argument("--friction-ramp", type=finite(0, 1e4, "deg/s", open_lo=True), default=DEFAULT_RAMP_DEG_S,
                   help=f"ramp velocity of the friction compensation in deg/s (default {DEFAULT_RAMP_DEG_S:g})")
    for name, value in asdict(Weights()).items():
        p.add_argument("--" + name.replace("_", "-"), dest=name, type=finite(0, 1e6, open_lo=True), default=value,
                       help=f"Bryson budget, > 0 (default {value:g})")
    p.add_argument("--check-points", type=count(2, MAX_CHECK_POINTS), default=41,
                   help=f"stability check on N x N poses across the grid (2 to {MAX_CHECK_POINTS}, default 41)")
    add_params(p)
    p.add_argument("--out", required=True, type=path_text, help="output folder (created)")
    add_json(p, '{"files", "stable", weakest point}')
    p.set_defaults(func=cmd_schedule)


def cmd_dynamics(args) -> None:
    from rcm_kin.control.linearization import check_in_range
    from rcm_kin.dynamics.state_space import check_state

    require_psm(args, NOT_PSM)
    model = driven_model(args.params, coulomb=not args.no_coulomb)
    x, u = check_state(np.r_[floats(args.q, "--q"), floats(args.v, "--v")], floats(args.u, "--u"))
    check_in_range(model, x[:3])
    qdd = np.array(model.forward(x, u)).ravel()[3:]
    lines = [f"{n:10} qdd {a:+.6g} {'m/s^2' if n == 'insertion' else 'rad/s^2'}" for n, a in zip(model.joints, qdd)]
    emit(args, {"qdd": qdd.tolist()}, "\n".join(lines))


def cmd_linearize(args) -> None:
    from rcm_kin.control.linearization import linearize

    require_psm(args, NOT_PSM)
    model = driven_model(args.params, coulomb=not args.no_coulomb)
    lin = linearize(model, [np.radians(args.roll), np.radians(args.pitch), args.insertion])
    np.set_printoptions(precision=5, suppress=True, linewidth=120)
    text = (f"equilibrium x0 = {lin.x0.round(6).tolist()} (rad, m; at rest), "
            f"holding PWM u0 = {lin.u0.round(3).tolist()}"
            f"\nstate {lin.state}, input {lin.inputs}"
            f"{'' if model.coulomb else ' (Coulomb friction left out)'}\nA =\n{lin.A}\nB =\n{lin.B}")
    emit(args, lin.as_dict(), text)


def cmd_schedule(args) -> None:
    from rcm_kin.codegen.firmware_export import write_gain_schedule
    from rcm_kin.control.gain_schedule import parse_grid, schedule_gains
    from rcm_kin.control.stability import stability_survey

    require_psm(args, NOT_PSM)
    model = driven_model(args.params, coulomb=False)
    rolls, pitches = parse_grid(args.grid)
    weights = Weights(**{name: getattr(args, name) for name in asdict(Weights())})
    schedule = schedule_gains(model, rolls, pitches, args.insertion, weights, args.friction_ramp)
    survey = stability_survey(model, schedule, points=args.check_points)
    files = write_gain_schedule(schedule, output_folder(args.out), survey, args.gravity_feedforward,
                                args.friction_feedforward)
    weakest = survey.weakest()
    payload = {"files": [str(f) for f in files], "stable": survey.stable, **weakest}
    text = "\n".join([f"wrote {f}" for f in files] + [
        f"{'stable' if survey.stable else 'NOT STABLE'} at every grid point and with frozen interpolated gains on "
        f"{args.check_points}x{args.check_points} poses between ({1 / FIRMWARE_PERIOD:g} Hz firmware loop and "
        "continuous);",
        f"slowest mode |z| = {weakest['spectral_radius']:.4f} at roll {weakest['roll_deg']:.1f}, pitch "
        f"{weakest['pitch_deg']:.1f} deg; least damping {weakest['min_damping']:.3f} at roll "
        f"{weakest['min_damping_roll_deg']:.1f}, pitch {weakest['min_damping_pitch_deg']:.1f} deg"])
    emit(args, payload, text)

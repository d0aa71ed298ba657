"""``dynamics``, ``linearize``: any robot's joint model (PWM through its drive, torque without)."""

from __future__ import annotations

import numpy as np

from rcm_kin.cli.common import (
    RAW,
    add_json,
    add_params,
    any_robot,
    driven_model,
    emit,
    finite,
    floats,
)
from rcm_kin.dynamics.drive import DRIVEN
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import DRIVER_PWM_RANGE, HOME_INSERTION

EPILOG_DYNAMICS = ("examples: rcm-kin dynamics psm --q 0.1 -0.2 0.08 --v 0 0 0 --u 10 -90 0 --json\n"
                   "          rcm-kin dynamics mtm --q 0 20 -30 0 0 0 0 --deg --u 0 1 0 0 0 0 0   (N m: no drive)\n"
                   "          rcm-kin dynamics my_arm.toml --joints j2 j3 --q 0.3 -0.5 --json")
EPILOG_LINEARIZE = ("examples: rcm-kin linearize psm --roll 10 --pitch=-5 --insertion 0.08 --json\n"
                    "          rcm-kin linearize mtm --q 0 20 -30 0 0 0 0 --deg --json   (torque input: no drive)\n"
                    "          rcm-kin linearize my_arm.toml --q 0.1 0.2 0.3 --params my_arm_drive.toml")



def add_dynamics(sub) -> None:
    p = sub.add_parser("dynamics", help="joint accelerations of a robot's model for a state and input (PWM through "
                       "its drive, joint torque without one)", parents=[any_robot()], epilog=EPILOG_DYNAMICS,
                       formatter_class=RAW)
    p.add_argument("--q", nargs="+", required=True, metavar="Q",
                   help="the model's joint positions, rad or m (--deg: degrees); PSM: roll, pitch, insertion")
    p.add_argument("--v", nargs="+", metavar="V", help="their rates (rad/s, m/s; default 0)")
    p.add_argument("--u", nargs="+", default=None, metavar="U",
                   help=f"inputs: PWM counts of the drivers, hardware sign (|u| <= {DRIVER_PWM_RANGE:g}), where the "
                        "robot has a drive; joint torques N m (N) where it has none (default 0)")
    add_model_options(p)
    add_json(p, '{"qdd": [per joint, rad/s^2 or m/s^2], "joints", "model", "input_unit"}')
    p.set_defaults(func=cmd_dynamics)


def add_linearize(sub) -> None:
    p = sub.add_parser("linearize", help="linear model (A, B, C, D) of a robot's joints at a held pose (PWM input "
                       "through its drive, joint torque without one)", parents=[any_robot()], epilog=EPILOG_LINEARIZE,
                       formatter_class=RAW)
    p.add_argument("--q", nargs="+", metavar="Q",
                   help="the pose of the model's joints, rad or m (--deg: degrees); instead of --roll/--pitch")
    p.add_argument("--roll", type=finite(unit="deg"), help="PSM: roll angle in degrees")
    p.add_argument("--pitch", type=finite(unit="deg"), help="PSM: pitch angle in degrees")
    p.add_argument("--insertion", type=finite(unit="m"), help=f"PSM: insertion in m (default {HOME_INSERTION:g})")
    add_model_options(p, linear=True)
    add_json(p, '{"x0", "u0", "A", "B", "C", "D", "state", "input", "model", "input_unit", "coulomb_slope"}: SI '
                'state [q; v]')
    p.set_defaults(func=cmd_linearize)


def add_model_options(p, linear: bool = False) -> None:
    """The options that choose a robot's model: joints, --deg, friction, parameters. A ``linear``
    model (``linearize``) leaves the smoothed Coulomb friction out unless ``--coulomb``: its slope
    at rest is an artefact of the smoothing, and the schedule's model has none."""
    p.add_argument("--joints", nargs="+", metavar="JOINT",
                   help="the joints to model where the robot has no drive (default all actuated; the others "
                        "held at 0); with a drive the model is over its joints")
    p.add_argument("--deg", action="store_true", help="revolute positions (and rates) in degrees (deg/s)")
    if linear:
        p.add_argument("--coulomb", action="store_true",
                       help="add the slope of the drive's smoothed Coulomb friction at rest (a smoothing artefact, "
                            "left out by default as in the gain schedule's model)")
        p.add_argument("--no-coulomb", action="store_true", help="the default: no smoothed-Coulomb slope")
    else:
        p.add_argument("--no-coulomb", action="store_true", help="leave the drive's smoothed Coulomb friction out")
    add_params(p, "drive parameter TOML of this robot (default: the one its sidecar names; none: its URDF "
                  "inertias, torque input)")


def _model(args):
    """The model the command line asks for."""
    coulomb = getattr(args, "coulomb", None)
    if coulomb is not None and coulomb and args.no_coulomb:
        raise RcmKinError("--coulomb and --no-coulomb contradict each other: give one")
    coulomb = not args.no_coulomb if coulomb is None else coulomb
    return driven_model(args.params, coulomb=coulomb, robot=args.robot, joints=args.joints)


def model_values(model, words, what: str, deg: bool, zero: bool = False) -> np.ndarray:
    """Per modelled joint values typed after ``what`` (revolute in degrees with ``deg``), or zeros."""
    n = len(model.joints)
    values = np.zeros(n) if words is None and zero else floats(words, what)
    if values.size != n:
        raise RcmKinError(f"{what} takes {n} values ({', '.join(model.joints)}), got {values.size}")
    revolute = np.array([u == "rad" for u in model.units])
    return np.where(revolute, np.radians(values), values) if deg else values


def model_line(model) -> str:
    """The last line of a text output: which model it used (``model: <label>, <input unit> input``)."""
    return f"model: {model.model_label}, {model.input_unit} input"


def cmd_dynamics(args) -> None:
    from rcm_kin.control.linearization import check_in_range
    from rcm_kin.dynamics.state_space import check_state

    model = _model(args)
    q, v = model_values(model, args.q, "--q", args.deg), model_values(model, args.v, "--v", args.deg, zero=True)
    x, u = check_state(np.r_[q, v], model_values(model, args.u, "--u", False, zero=True), model)
    check_in_range(model, x[:len(model.joints)])
    qdd = np.array(model.forward(x, u)).ravel()[len(model.joints):]
    lines = [f"{n:10} qdd {a:+.6g} {unit}/s^2" for n, a, unit in zip(model.joints, qdd, model.units)]
    emit(args, {"qdd": qdd.tolist(), "joints": list(model.joints), "model": model.model_label,
                "input_unit": model.input_unit}, "\n".join([*lines, model_line(model)]))


def _pose(args, model) -> np.ndarray:
    """The pose of ``linearize``: --q, or the PSM's --roll/--pitch/--insertion."""
    psm_flags = args.roll is not None or args.pitch is not None or args.insertion is not None
    if args.q is not None:
        if psm_flags:
            raise RcmKinError("give the pose either as --q or as --roll/--pitch/--insertion, not both")
        return model_values(model, args.q, "--q", args.deg)
    if tuple(model.joints) != DRIVEN:
        raise RcmKinError(f"--roll/--pitch/--insertion are the PSM's driven joints: give the pose of "
                          f"{', '.join(model.joints)} as --q")
    if args.roll is None or args.pitch is None:
        raise RcmKinError("linearize needs --roll and --pitch (degrees), or --q")
    insertion = HOME_INSERTION if args.insertion is None else args.insertion
    return np.array([np.radians(args.roll), np.radians(args.pitch), insertion])


def cmd_linearize(args) -> None:
    from rcm_kin.control.linearization import linearize

    model = _model(args)
    lin = linearize(model, _pose(args, model))
    np.set_printoptions(precision=5, suppress=True, linewidth=120)
    held = "holding PWM" if model.pwm_input else "holding torque (N m, N)"
    text = (f"equilibrium x0 = {lin.x0.round(6).tolist()} (rad, m; at rest), "
            f"{held} u0 = {lin.u0.round(3).tolist()}"
            f"\nstate {lin.state}, input {lin.inputs}"
            f"{'' if model.coulomb or not model.pwm_input else ' (no smoothed-Coulomb slope: --coulomb adds it)'}"
            f"\nA =\n{lin.A}\nB =\n{lin.B}\n{model_line(model)}")
    emit(args, {**lin.as_dict(), "model": model.model_label, "input_unit": model.input_unit,
                "coulomb_slope": bool(model.pwm_input and model.coulomb)}, text)

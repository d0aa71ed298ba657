"""``schedule``: model-based LQR / LQI gain tables over two joints of a robot with a drive (the
firmware C header: the bundled PSM's)."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from rcm_kin.cli.common import (
    RAW,
    add_json,
    add_params,
    any_robot,
    count,
    driven_model,
    emit,
    finite,
    floats,
    path_text,
)
from rcm_kin.cli.control import model_line
from rcm_kin.cli.outputs import FOLDER_FORCE, new_folder
from rcm_kin.cli.statics import joint_assignments
from rcm_kin.cli.tuning import add_tune_options, check_tune_options, run_tune
from rcm_kin.control.friction import DEFAULT_RAMP_DEG_S
from rcm_kin.control.weights import Weights
from rcm_kin.dynamics.drive import DRIVEN
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import FIRMWARE_PERIOD, HOME_INSERTION

MAX_CHECK_POINTS = 201    # 201 x 201 poses: about a minute of eigenvalues
CHECK_POINTS = 41         # the PSM's default
EPILOG_SCHEDULE = ("examples: rcm-kin schedule psm --out gains\n"
                   "          rcm-kin schedule psm --grid roll=-20:20:5 pitch=-15:15:3 --out gains\n"
                   "          rcm-kin schedule my_arm.toml --grid j2=-30:60:7 j3=-20:40:5 --out gains   (JSON, CSV)\n"
                   "          rcm-kin schedule my_arm.toml --grid j2=-30:60:7 j3=-20:40:5 --at j4=15 --out gains\n"
                   "          rcm-kin schedule psm --gravity-feedforward --friction-feedforward --out gains\n"
                   "          rcm-kin schedule psm --tune --out tuned   (about 7 minutes on 2 cores)")


def add_schedule(sub) -> None:
    p = sub.add_parser("schedule", help="model-based LQR / LQI gain tables over two joints of a robot with a drive "
                       "(JSON, CSV; the firmware C header: the bundled PSM only)", parents=[any_robot()],
                       epilog=EPILOG_SCHEDULE, formatter_class=RAW)
    p.add_argument("--grid", nargs="+", default=None, metavar="GRID",
                   help="JOINT=LO:HI:N JOINT=LO:HI:N (degrees; first joint LQR, second LQI); the PSM also takes "
                        "'thesis' (its default: roll -20,0,20 x pitch -15,0,15 deg) or ROLLS:PITCHES in degrees, "
                        "comma-separated (write --grid=-20,0,20:-15,0,15 when it starts with a minus)")
    p.add_argument("--insertion", type=finite(unit="m"), default=None,
                   help=f"PSM: insertion of the models in m (default {HOME_INSERTION:g}); other robots: --at")
    p.add_argument("--at", nargs="+", metavar="J=VALUE", help="not the PSM: values the model's other joints are "
                   "held at (deg, m; default mid-range)")
    p.add_argument("--gravity-feedforward", action="store_true",
                   help="PSM firmware header: also export the holding-PWM table (u_hold) and rcm_holding_pwm()")
    p.add_argument("--friction-feedforward", action="store_true",
                   help="PSM firmware header: also export the sliding-friction compensation (RCM_FC_* and "
                        "rcm_friction_feedforward(): -F_c/|k_u| tanh(rdot / ramp) PWM on the reference velocity; "
                        "needs <math.h>)")
    p.add_argument("--friction-ramp", type=finite(0, 1e4, "deg/s", open_lo=True), default=DEFAULT_RAMP_DEG_S,
                   help=f"ramp velocity of the friction compensation in deg/s (default {DEFAULT_RAMP_DEG_S:g})")
    for name, value in asdict(Weights()).items():
        p.add_argument("--" + name.replace("_", "-"), dest=name, type=finite(0, 1e6, open_lo=True), default=value,
                       help=f"Bryson budget, > 0 (default {value:g}; roll: the first joint, pitch: the second)")
    p.add_argument("--check-points", type=count(2, MAX_CHECK_POINTS), default=None,
                   help=f"PSM: stability check on N x N poses across the grid (2 to {MAX_CHECK_POINTS}, default "
                        f"{CHECK_POINTS}); other robots: the closed loop at every grid point, no option")
    add_tune_options(p)
    add_params(p, "drive parameter TOML of this robot (default: the one its sidecar names; a schedule needs one)")
    p.add_argument("--out", required=True, type=path_text, help="output folder (created)")
    p.add_argument("--force", action="store_true", help=FOLDER_FORCE)
    add_json(p, '{"files", "stable", weakest point, "model", "input_unit"}; with --tune also "chosen", "values", '
                '"scores", "criteria"')
    p.set_defaults(func=cmd_schedule)


def cmd_schedule(args) -> None:
    check_tune_options(args, asdict(Weights()))
    model = driven_model(args.params, coulomb=False, robot=args.robot)
    if not model.pwm_input:
        raise RcmKinError(f"schedule needs a drive: {model.robot} has no drive parameter file (a drive key in its "
                          "sidecar, or --params); without one its model has torque input")
    if model.robot == "psm" and tuple(model.joints) == DRIVEN:
        if args.at is not None:
            raise RcmKinError("--at is not an option of the PSM's schedule: it holds the insertion at --insertion "
                              f"(default {HOME_INSERTION:g} m)")
        return run_tune(args, model) if args.tune else _psm_schedule(args, model)
    if args.tune:
        raise RcmKinError(f"--tune simulates the bundled PSM's firmware and thesis experiments; {model.robot}'s "
                          "schedule is designed by LQR/LQI")
    if args.gravity_feedforward or args.friction_feedforward:
        raise RcmKinError("--gravity-feedforward and --friction-feedforward are of the PSM firmware's C header; "
                          f"the schedule of {model.robot} is written as JSON and CSV")
    if args.insertion is not None:
        raise RcmKinError(f"--insertion is the bundled PSM's: hold {model.robot}'s other joints with --at J=VALUE "
                          "(deg, m)")
    if args.check_points is not None:
        raise RcmKinError(f"--check-points is the bundled PSM's (its firmware loop between grid points): the schedule "
                          f"of {model.robot} checks the closed loop at every grid point")
    return _joint_schedule(args, model)


def _psm_grid(args):
    """The PSM's roll and pitch grids (deg): 'thesis', ROLLS:PITCHES or roll=LO:HI:N pitch=LO:HI:N."""
    from rcm_kin.control.gain_schedule import parse_grid
    from rcm_kin.control.joint_schedule import parse_joint_grid

    words = args.grid or ["thesis"]
    if len(words) == 1:
        return parse_grid(words[0])
    grid = parse_joint_grid(words, args.model)
    if list(grid) != ["roll", "pitch"]:
        raise RcmKinError("the PSM's firmware schedule is over roll (first) and pitch (second): "
                          "--grid roll=LO:HI:N pitch=LO:HI:N")
    return grid["roll"], grid["pitch"]


def _psm_schedule(args, model) -> None:
    from rcm_kin.codegen.firmware_export import write_gain_schedule
    from rcm_kin.control.gain_schedule import schedule_gains
    from rcm_kin.control.stability import stability_survey

    args.model = model
    rolls, pitches = _psm_grid(args)
    weights = Weights(**{name: getattr(args, name) for name in asdict(Weights())})
    insertion = HOME_INSERTION if args.insertion is None else args.insertion
    points = CHECK_POINTS if args.check_points is None else args.check_points
    schedule = schedule_gains(model, rolls, pitches, insertion, weights, args.friction_ramp)
    survey = stability_survey(model, schedule, points=points)
    files = write_gain_schedule(schedule, new_folder(args.out, args.force), survey, args.gravity_feedforward,
                                args.friction_feedforward)
    weakest = survey.weakest()
    payload = {"files": [str(f) for f in files], "stable": survey.stable, **weakest, "model": model.model_label,
               "input_unit": model.input_unit}
    text = "\n".join([f"wrote {f}" for f in files] + [
        f"{'stable' if survey.stable else 'NOT STABLE'} at every grid point and with frozen interpolated gains on "
        f"{points}x{points} poses between ({1 / FIRMWARE_PERIOD:g} Hz firmware loop and "
        "continuous);",
        f"slowest mode |z| = {weakest['spectral_radius']:.4f} at roll {weakest['roll_deg']:.1f}, pitch "
        f"{weakest['pitch_deg']:.1f} deg; least damping {weakest['min_damping']:.3f} at roll "
        f"{weakest['min_damping_roll_deg']:.1f}, pitch {weakest['min_damping_pitch_deg']:.1f} deg",
        model_line(model)])
    emit(args, payload, text)


def _joint_schedule(args, model) -> None:
    from rcm_kin.control.joint_schedule import parse_joint_grid, schedule_joints, write_joint_schedule

    if args.grid is None:
        raise RcmKinError(f"schedule {model.robot} needs --grid JOINT=LO:HI:N JOINT=LO:HI:N over two of "
                          f"{', '.join(model.joints)} (degrees)")
    grid = parse_joint_grid(args.grid, model)
    at = held_pose(model, args.at, grid)
    schedule = schedule_joints(model, grid, at, Weights(**{name: getattr(args, name) for name in asdict(Weights())}))
    files = write_joint_schedule(schedule, model, args.out)
    weakest, (a, b) = schedule.weakest(), schedule.joints
    text = "\n".join([f"wrote {f}" for f in files] + [
        f"{'stable' if schedule.stable else 'NOT STABLE'} at every grid point (continuous closed loop of {a} and "
        f"{b}; the firmware's sampled loop and C header are the PSM's);",
        f"slowest mode Re = {weakest['max_real']:.4g} 1/s at {a} {weakest[f'{a}_deg']:.1f}, {b} "
        f"{weakest[f'{b}_deg']:.1f} deg", model_line(model)])
    emit(args, {"files": [str(f) for f in files], "stable": schedule.stable, **weakest, "model": model.model_label,
                "input_unit": model.input_unit}, text)


def held_pose(model, words, grid) -> np.ndarray | None:
    """The model pose (SI) of ``--at J=VALUE`` words (degrees for a revolute joint, metres for a
    prismatic one; the joints not named at mid-range), or None when none is given."""
    if words is None:
        return None
    at = (model.lower + model.upper) / 2
    for name, text in joint_assignments(words, "--at"):
        if name not in model.joints:
            raise RcmKinError(f"--at {name}: not a joint of the model of {model.robot} ({', '.join(model.joints)})")
        if name in grid:
            raise RcmKinError(f"--at {name}: {name} is a joint of the grid")
        k = model.joints.index(name)
        value = floats([text], f"--at {name}")[0]
        at[k] = np.radians(value) if model.units[k] == "rad" else value
    return at

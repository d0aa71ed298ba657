"""The ``rcm-kin`` command line. Units: SI (rad, m) unless ``--deg``; ``--json`` for scripts.

User errors print one line ``error: ...`` on stderr and exit with status 2.
"""

from __future__ import annotations

import argparse
import json
import re
import sys

import numpy as np
import pinocchio as pin

from rcm_kin.errors import RcmKinError, output_folder
from rcm_kin.robot import GRAVITY, load_robot, robot_names

EPILOG_INFO = "example: rcm-kin info psm --json"
EPILOG_FK = "example: rcm-kin fk psm 10 -5 0.08 --deg --json   (roll 10 deg, pitch -5 deg, insertion 0.08 m)"
EPILOG_IK = ("examples: rcm-kin ik psm 0.01 0.02 -0.06 --json   (shaft tip at x y z in m, base frame)\n"
             "          rcm-kin ik psm 0.01 0.02 -0.07 --rpy 180 0 0 --deg   (tool_tip pose, numeric)\n"
             "          rcm-kin ik mtm 0.26 0.02 -0.2 --json   (MTM wrist centre)")
EPILOG_SIMULATE = ("examples: rcm-kin simulate psm --experiment sine --controller scheduled --json\n"
                   "          rcm-kin simulate psm --experiment target --controller p --plot figures   "
                   "(bundled trajectory)\n"
                   "          rcm-kin simulate psm --experiment target --trajectory mtm_target_trajectory.csv")
EPILOG_SYSID = ("examples: rcm-kin sysid roll_step.csv --joint roll --json   (2nd-order fit of the step)\n"
                "          rcm-kin sysid prbs_roll_0_pitch_0.csv --joint pitch --order 4\n"
                "          rcm-kin sysid psm-sysid/roll-step --joint roll --out table   "
                "(every pose of a folder, beside the physics)")
EPILOG_GREYBOX = ("example: rcm-kin greybox psm-sysid/roll-step --joint roll --out roll_fitted.toml\n"
                  "         rcm-kin simulate psm --experiment sine --controller p --params roll_fitted.toml")
EPILOG_VIEW = ("examples: rcm-kin view psm --q 10 -5 0.08 --deg --html psm.html   (self-contained page)\n"
               "          rcm-kin view mtm --frames wrist_center tool_tip   (serves on localhost, prints the URL)\n"
               "          rcm-kin view psm --q 10 -5 0.08 --deg --png psm.png   (matplotlib drawing)")
EPILOG_SAFETY = ("examples: rcm-kin safety simulate ellipsoid --json   (CBF blend on the 3-D no-go ellipsoid)\n"
                 "          rcm-kin safety simulate psm --filter qp   (PSM teleoperation towards a forbidden region)\n"
                 "          rcm-kin safety certify 3 --error-bound 0.007 --json   (SOS barrier certificate)")
EPILOG_REPORT = ("examples: rcm-kin report --out report   (then open report/index.html)\n"
                 "          rcm-kin report --out report --data ../shared/data   (with the measured logs)")


class _Parser(argparse.ArgumentParser):
    """argparse with the project's one-line error format, reading ``-1e-06`` as a number."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str):  # noqa: D102 - argparse API
        self.exit(2, f"error: {message} (see: {self.prog} --help)\n")


def _floats(values: list[str], what: str) -> np.ndarray:
    try:
        return np.array([float(v) for v in values])
    except ValueError:
        raise RcmKinError(f"{what} must be numbers, got {' '.join(values)}") from None


def _degrees_to_si(robot, q: np.ndarray) -> np.ndarray:
    """Revolute joints deg -> rad; prismatic joints stay in m."""
    q = q.copy()
    for i, name in enumerate(robot.actuated[:q.size]):
        if robot.joint_kind(name) == "revolute":
            q[i] = np.radians(q[i])
    return q


def _joint_values(robot, args) -> np.ndarray:
    """The actuated q typed on the command line (``args.q``, ``--deg``), padded with zeros."""
    q = _floats(args.q, "joint values")
    if args.deg:
        q = _degrees_to_si(robot, q)
    return robot.check_q(q, allow_short=True)


def _emit(args, payload: dict, text: str) -> None:
    print(json.dumps(payload) if args.json else text)


def cmd_info(args) -> None:
    from rcm_kin.kinematics.fk import joint_axes_world

    robot = load_robot(args.robot)
    axes = joint_axes_world(robot, np.zeros(robot.nq))
    model = robot.tree
    joints = []
    for jid in range(1, model.njoints):
        name = model.names[jid]
        i = model.joints[jid].idx_q
        joints.append({"name": name, "type": robot.joint_kind(name),
                       "lower": float(model.lowerPositionLimit[i]), "upper": float(model.upperPositionLimit[i]),
                       "axis_world": axes[name].round(12).tolist(),
                       "role": "actuated" if name in robot.actuated else "passive"})
    payload = {"robot": robot.name, "joints": joints, "actuated": list(robot.actuated),
               "gravity": GRAVITY.tolist(), "frames": list(robot.description.frames),
               "loops": [c.loop.name for c in robot.constraints]}
    lines = [f"{robot.name}: {len(robot.actuated)} actuated joints, {len(robot.constraints)} loop closures, "
             f"gravity {GRAVITY.tolist()} m/s^2 (base frame)",
             f"{'joint':18} {'type':9} {'role':8} {'lower':>9} {'upper':>9}  axis (base frame, q = 0)"]
    for j in joints:
        scale, unit = (1e3, "mm") if j["type"] == "prismatic" else (180 / np.pi, "deg")
        lines.append(f"{j['name']:18} {j['type']:9} {j['role']:8} {j['lower'] * scale:9.2f} {j['upper'] * scale:9.2f}"
                     f" {unit:3} {np.round(j['axis_world'], 4).tolist()}")
    lines.append(f"frames of interest: {', '.join(robot.description.frames)}")
    rcm = robot.description.rcm
    if rcm is not None:
        from rcm_kin.kinematics.rcm_scatter import rcm_scatter

        scatter = rcm_scatter(robot, rcm.shaft_frame, rcm.joints, rcm.base_frame)
        payload["rcm"] = {"point": scatter.point.tolist(), "frame": rcm.base_frame or "base",
                          "max_distance": scatter.max_distance, "rms_distance": scatter.rms_distance}
        lines.append(f"remote centre of motion: {np.round(scatter.point, 6).tolist()} m in {rcm.base_frame or 'the base'};"
                     f" shaft lines over {rcm.joints[0]} x {rcm.joints[1]} pass within "
                     f"{scatter.max_distance * 1e3:.3g} mm (RMS {scatter.rms_distance * 1e3:.3g} mm)")
    _emit(args, payload, "\n".join(lines))


def cmd_fk(args) -> None:
    from rcm_kin.kinematics.fk import forward_kinematics

    robot = load_robot(args.robot)
    result = forward_kinematics(robot, _joint_values(robot, args))
    frames = {name: {"position": M.translation.tolist(), "rotation": M.rotation.tolist()}
              for name, M in result.frames.items()}
    payload = {"q": result.q.tolist(), "frames": frames, "closure_residual": result.closure_residual}
    lines = [f"q = {np.round(result.q, 6).tolist()} (rad, m)"]
    lines += [f"{name:14} position {np.round(M.translation, 6).tolist()} m" for name, M in result.frames.items()]
    lines.append(f"loop closure residual {result.closure_residual:.1e} m")
    _emit(args, payload, "\n".join(lines))


def cmd_ik(args) -> None:
    from rcm_kin.kinematics.fk import frame_placement

    robot = load_robot(args.robot)
    target = _floats([args.x, args.y, args.z], "the target x y z")
    if robot.name == "psm" and args.rpy is None:
        from rcm_kin.kinematics.psm_ik import ARM, shaft_tip_ik
        frame, joints = "shaft_tip", ARM
        q_short = shaft_tip_ik(robot, target)
        q_full = robot.check_q(q_short, allow_short=True)
        rotation_error = None
    elif robot.name == "psm":
        from rcm_kin.kinematics.psm_ik import ARM, WRIST, tool_pose_ik
        rpy = _floats(args.rpy, "--rpy")
        rotation = pin.rpy.rpyToMatrix(*(np.radians(rpy) if args.deg else rpy))
        frame, joints = "tool_tip", ARM + WRIST
        result = tool_pose_ik(robot, target, rotation)
        q_full, rotation_error = result.q, result.orientation_error
        q_short = q_full[:len(joints)]
    elif robot.name == "mtm":
        if args.rpy is not None:
            raise RcmKinError("--rpy is for the PSM tool; the MTM IK places its wrist centre")
        from rcm_kin.kinematics.numeric_ik import solve_ik
        frame, joints = "wrist_center", ("j1", "j2", "j3")
        q_full = solve_ik(robot, frame, target, joints=joints).q
        q_short, rotation_error = q_full[:3], None
    else:
        raise RcmKinError(f"no IK for robot '{robot.name}'")
    error = float(np.linalg.norm(frame_placement(robot, q_full, frame).translation - target))
    payload = {"q": q_short.tolist(), "position_error": error, "frame": frame, "joints": list(joints)}
    if rotation_error is not None:
        payload["orientation_error"] = rotation_error
    shown = [f"{n} {np.degrees(v):.4f} deg" if robot.joint_kind(n) == "revolute" else f"{n} {v * 1e3:.4f} mm"
             for n, v in zip(joints, q_short)]
    _emit(args, payload, f"{frame}: " + ", ".join(shown) + f"  (position error {error:.1e} m)")


def cmd_gravity(args) -> None:
    from rcm_kin.dynamics.drive import DRIVEN, drive_effort, load_drive_parameters
    from rcm_kin.dynamics.gravity import gravity_batch

    robot = load_robot(args.robot, counterweights=not args.no_counterweights)
    q = _floats(args.q, "joint values")
    if args.deg:
        q = _degrees_to_si(robot, q)
    q = robot.check_q(q, allow_short=True)
    payload = {"joints": list(robot.actuated), "q": q.tolist()}
    if robot.name == "psm":
        drive = load_drive_parameters(args.params)
        tau = gravity_batch(robot, q[None], drive.gravity_offsets)[0]
        effort = drive_effort(drive, tau[:3])
        payload.update(tau=tau.tolist(), pwm=effort.pwm.tolist(), voltage=effort.voltage.tolist(),
                       driven=list(DRIVEN), saturated=effort.saturated.tolist())
    else:
        tau = gravity_batch(robot, q[None])[0]
        payload.update(tau=tau.tolist(), pwm=[], voltage=[], driven=[])
    units = ["N" if robot.joint_kind(n) == "prismatic" else "N m" for n in robot.actuated]
    lines = [f"{n:16} {t:+10.4f} {u}" for n, t, u in zip(robot.actuated, payload["tau"], units)]
    if payload["pwm"]:
        lines.append("driven joints (hardware PWM sign: positive decreases the angle):")
        lines += [f"{n:16} {v:+8.3f} V  {p:+8.2f} PWM" + ("  SATURATED" if s else "")
                  for n, v, p, s in zip(DRIVEN, payload["voltage"], payload["pwm"], payload["saturated"])]
    _emit(args, payload, "\n".join(lines))


def cmd_torque_map(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.statics.gravity_map import parse_range, write_gravity_maps

    if args.robot != "psm":
        raise RcmKinError("torque maps are for the PSM's driven joints: rcm-kin torque-map psm ...")
    robot = load_robot("psm", counterweights=not args.no_counterweights)
    drive = load_drive_parameters(args.params)
    roll, pitch = (np.linspace(*parse_range(t, w)) for t, w in ((args.roll, "--roll"), (args.pitch, "--pitch")))
    gmap, files = write_gravity_maps(robot, drive, roll, pitch, args.insertion, output_folder(args.out), progress=True)
    payload = {"files": [str(f) for f in files], "poses": int(gmap.effort.tau[..., 0].size)}
    _emit(args, payload, "\n".join(f"wrote {f}" for f in files))


def cmd_calibrate(args) -> None:
    from rcm_kin.dynamics.drive import write_parameters
    from rcm_kin.statics.calibration import UNITS, calibrate, calibration_logs, holding_points
    from rcm_kin.dynamics.drive import load_drive_parameters

    robot = load_robot("psm")
    base = load_drive_parameters(args.params)
    points = holding_points(calibration_logs(args.data))
    result = calibrate(robot, base, points)
    payload = {"parameters": {n: {"value": float(v), "std": float(s), "unit": u}
                              for n, v, s, u in zip(result.names, result.values, result.std, UNITS)},
               "residual_rms_pwm": result.residual_rms.tolist(), "friction_band_pwm": result.friction_band.tolist(),
               "points": [{"source": p.source, "roll_deg": float(np.degrees(p.roll)),
                           "pitch_deg": float(np.degrees(p.pitch)), "measured_pwm": [p.pwm_roll, p.pwm_pitch],
                           "predicted_pwm": pred.tolist()} for p, pred in zip(points, result.predicted)]}
    if args.out:
        header = (f"Drive parameters calibrated by `rcm-kin calibrate` on {len(points)} holding points.\n"
                  + "\n".join(f"{n} = {v:.6g} +- {s:.2g} {u}" for n, v, s, u in
                               zip(result.names, result.values, result.std, UNITS))
                  + f"\nresidual RMS roll {result.residual_rms[0]:.2f}, pitch {result.residual_rms[1]:.2f} PWM; "
                  f"largest |residual| roll {result.friction_band[0]:.2f}, pitch {result.friction_band[1]:.2f} PWM."
                  "\nFormat and assumed constants: see the shipped rcm_kin/parameters/psm_drive.toml.")
        payload["written"] = str(write_parameters(result.parameters, args.out, header))
    lines = [f"{n:20} {v:+.6g} +- {s:.2g} {u}" for n, v, s, u in zip(result.names, result.values, result.std, UNITS)]
    lines.append(f"residual RMS: roll {result.residual_rms[0]:.2f}, pitch {result.residual_rms[1]:.2f} PWM "
                 f"over {len(points)} holding points")
    if args.out:
        lines.append(f"wrote {payload['written']}")
    _emit(args, payload, "\n".join(lines))


def _driven_model(args, coulomb: bool):
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.state_space import driven_dynamics

    if args.robot != "psm":
        raise RcmKinError(f"the driven-joint dynamics are the PSM's (roll, pitch, insertion), not '{args.robot}'")
    return driven_dynamics(load_robot("psm"), load_drive_parameters(args.params), coulomb=coulomb)


def cmd_dynamics(args) -> None:
    from rcm_kin.dynamics.state_space import check_state

    model = _driven_model(args, coulomb=not args.no_coulomb)
    x, u = check_state(np.r_[_floats(args.q, "--q"), _floats(args.v, "--v")], _floats(args.u, "--u"))
    qdd = np.array(model.forward(x, u)).ravel()[3:]
    lines = [f"{n:10} qdd {a:+.6g} {'m/s^2' if n == 'insertion' else 'rad/s^2'}" for n, a in zip(model.joints, qdd)]
    _emit(args, {"qdd": qdd.tolist()}, "\n".join(lines))


def cmd_linearize(args) -> None:
    from rcm_kin.control.linearization import linearize

    model = _driven_model(args, coulomb=not args.no_coulomb)
    pose = _floats([args.roll, args.pitch], "--roll and --pitch")
    lin = linearize(model, [np.radians(pose[0]), np.radians(pose[1]), args.insertion])
    np.set_printoptions(precision=5, suppress=True, linewidth=120)
    text = (f"equilibrium x0 = {lin.x0.round(6).tolist()} (rad, m; at rest), holding PWM u0 = {lin.u0.round(3).tolist()}"
            f"\nstate {lin.state}, input {lin.inputs}"
            f"{'' if model.coulomb else ' (Coulomb friction left out)'}\nA =\n{lin.A}\nB =\n{lin.B}")
    _emit(args, lin.as_dict(), text)


def cmd_schedule(args) -> None:
    from rcm_kin.control.firmware_export import write_gain_schedule
    from rcm_kin.control.gain_schedule import parse_grid, schedule_gains
    from rcm_kin.control.weights import Weights
    from rcm_kin.control.stability import stability_survey

    if args.check_points < 2:
        raise RcmKinError("--check-points needs at least 2 poses per axis")
    model = _driven_model(args, coulomb=False)
    rolls, pitches = parse_grid(args.grid)
    weights = Weights(**{name: getattr(args, name) for name in vars(Weights())})
    schedule = schedule_gains(model, rolls, pitches, args.insertion, weights)
    survey = stability_survey(model, schedule, points=args.check_points)
    files = write_gain_schedule(schedule, output_folder(args.out), survey, args.gravity_feedforward)
    weakest = survey.weakest()
    payload = {"files": [str(f) for f in files], "stable": survey.stable, **weakest}
    text = "\n".join([f"wrote {f}" for f in files] + [
        f"{'stable' if survey.stable else 'NOT STABLE'} at every grid point and with frozen interpolated gains on "
        f"{args.check_points}x{args.check_points} poses between (400 Hz firmware loop and continuous);",
        f"slowest mode |z| = {weakest['spectral_radius']:.4f} at roll {weakest['roll_deg']:.1f}, pitch "
        f"{weakest['pitch_deg']:.1f} deg; least damping {weakest['min_damping']:.3f} at roll "
        f"{weakest['min_damping_roll_deg']:.1f}, pitch {weakest['min_damping_pitch_deg']:.1f} deg"])
    _emit(args, payload, text)


def cmd_simulate(args) -> None:
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.simulation.experiments import run_experiment
    from rcm_kin.simulation.firmware import FirmwareSettings
    from rcm_kin.simulation.loop import tracking_metrics

    if args.robot != "psm":
        raise RcmKinError(f"the tracking experiments run on the PSM's driven joints, not '{args.robot}'")
    if not (np.isfinite(args.rate) and args.rate > 0):
        raise RcmKinError(f"--rate is a positive frequency in Hz, got {args.rate}")
    limits = _floats(args.pwm_limit, "--pwm-limit") if args.pwm_limit else None
    settings = FirmwareSettings(period=1.0 / args.rate, **({"pwm_limit": limits} if limits is not None else {}),
                                noise_counts=args.noise_counts)
    result = run_experiment(args.experiment, args.controller, args.duration, load_drive_parameters(args.params),
                            settings, args.trajectory, seed=args.seed, progress=sys.stderr.isatty())
    metrics = tracking_metrics(result, args.skip)
    payload = {axis: vars(m) for axis, m in metrics.items()}
    lines = [f"{args.experiment} with {args.controller}, {result.time[-1]:.2f} s at {args.rate:g} Hz:"] + [
        f"{axis:5}  max {m.max_error_deg:.3f}  mean {m.mean_error_deg:.3f}  RMS {m.rms_error_deg:.3f} deg;  "
        f"PWM RMS {m.rms_pwm:.1f}, saturated {m.saturation_s:.3f} s" for axis, m in metrics.items()]
    if args.plot:
        from rcm_kin.report.figures import tracking_figure

        path = tracking_figure(result, output_folder(args.plot) / f"{args.experiment}_{args.controller}.png",
                               title=f"{args.experiment}, {args.controller}:")
        lines.append(f"wrote {path}")
    _emit(args, payload, "\n".join(lines))


def _polynomial(coefficients) -> str:
    """``[a, b, c]`` (descending powers) as ``a s^2 + b s + c``."""
    n = len(coefficients) - 1
    text = ""
    for k, c in enumerate(coefficients):
        power = f" s^{n - k}" if n - k > 1 else " s" if n - k == 1 else ""
        sign = "-" if c < 0 else "+"
        text += (f"{'-' if c < 0 else ''}{abs(c):.5g}" if k == 0 else f" {sign} {abs(c):.5g}") + power
    return text


def cmd_sysid(args) -> None:
    from pathlib import Path

    from rcm_kin.identification.pose_models import identify_folder, identify_log, pose_table_rows, write_pose_table

    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.state_space import driven_dynamics

    model = driven_dynamics(load_robot("psm"), load_drive_parameters(args.params), coulomb=False)
    options = dict(method=args.method, order=args.order, zeros=args.zeros, samples=args.samples,
                   segment=args.segment)
    if args.samples < 50:
        raise RcmKinError("--samples needs at least 50 samples after the step")
    if Path(args.log).is_dir():
        models = identify_folder(args.log, args.joint, model, **options)
        rows = pose_table_rows(models)
        payload = {"models": rows}
        lines = [f"{r['file']:46} fit {r['fit_percent']:6.2f} %  DC {r['dc_gain']:+.4f} deg/PWM  poles {r['poles']}"
                 + (f"   physics DC {r['physics_dc_gain']:+.4f}, poles {r['physics_poles']}" if "physics_poles" in r
                    else "") for r in rows]
        if args.out:
            path = write_pose_table(models, output_folder(args.out) / f"{args.joint}_pose_models.csv")
            payload["written"] = str(path)
            lines.append(f"wrote {path}")
        _emit(args, payload, "\n".join(lines))
        return
    pose = tuple(_floats(args.pose, "--pose")) if args.pose else None
    result = identify_log(args.log, args.joint, model=model, pose_deg=pose, **options)
    fit = result.fit
    payload = fit.as_dict()
    if result.physics is not None:
        payload["physics"] = {"pose_deg": list(result.pose_deg), "dc_gain": result.physics.dc_gain,
                              "poles": [[p.real, p.imag] for p in result.physics.poles]}
    np.set_printoptions(precision=5, suppress=True, linewidth=120)
    lines = [f"{args.joint}: G(s) = ({_polynomial(fit.num)}) / ({_polynomial(fit.den)})  (deg per PWM count)",
             f"fit {fit.fit_percent:.2f} % (NRMSE), DC gain {fit.dc_gain:+.4f} deg/PWM, poles {fit.poles}",
             f"operating point: PWM {result.record.u0:.2f}, angle {result.record.y0:.3f} deg"]
    if result.physics is not None:
        lines.append(f"physics at roll {result.pose_deg[0]:g}, pitch {result.pose_deg[1]:g} deg: DC gain "
                     f"{result.physics.dc_gain:+.4f} deg/PWM, poles {result.physics.poles}")
    _emit(args, payload, "\n".join(lines))


def cmd_greybox(args) -> None:
    from pathlib import Path

    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.identification.greybox import fit_greybox, step_logs, write_greybox_parameters

    paths = []
    for item in args.logs:
        found = sorted(Path(item).glob("*.csv")) if Path(item).is_dir() else [Path(item)]
        if not found:
            raise RcmKinError(f"no *.csv logs in {item}")
        paths += found
    if args.samples < 50:
        raise RcmKinError("--samples needs at least 50 samples after the step")
    fit = fit_greybox(load_drive_parameters(args.params), args.joint, step_logs(paths, args.joint, args.samples))
    payload = fit.as_dict()
    lines = [f"{args.joint} grey-box fit on {len(fit.logs)} step logs:"]
    lines += [f"  {n:16} {b:.6g} -> {a:.6g}" for n, b, a in zip(fit.names, fit.before, fit.after)]
    lines += ["  fit % per log: starting set -> fitted set (median Coulomb) -> with the log's own Coulomb"]
    lines += [f"  {name:44} {b:9.1f} -> {a:7.1f} -> {p:6.1f}   (coulomb {c:.3f} N m)" for name, c, b, a, p in
              zip(fit.logs, fit.coulomb_per_log, fit.fit_before, fit.fit_after, fit.fit_per_log_friction)]
    if args.out:
        path = write_greybox_parameters(fit, args.out)
        payload["written"] = str(path)
        lines.append(f"wrote {path} (use it with --params)")
    _emit(args, payload, "\n".join(lines))


def cmd_view(args) -> None:
    from rcm_kin.visualization.views import robot_view, show, write_html

    robot = load_robot(args.robot)
    q = _joint_values(robot, args)
    frames = tuple(args.frames or ())
    if args.png:
        from rcm_kin.visualization.drawing import robot_drawing

        print(f"wrote {robot_drawing(robot, q, args.png, title=robot.name.upper())}")
    if args.html:
        viz = robot_view(robot, frames=frames)
        show(viz, robot, q)
        print(f"wrote {write_html(viz, args.html)}")
    if args.html or args.png:
        return
    import meshcat

    live = meshcat.Visualizer()            # starts the meshcat server and prints its URL
    viz = robot_view(robot, window=live.window, frames=frames)
    show(viz, robot, q)
    print("serving; press Ctrl-C to stop", flush=True)
    try:
        import time
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("stopped")


def cmd_safety_simulate(args) -> None:
    from rcm_kin.safety.scenarios import run_scenario

    options = {"kappa": args.kappa} if args.kappa is not None else {}
    if args.trajectory:
        if args.scenario != "psm":
            raise RcmKinError("--trajectory is for the psm scenario")
        options["trajectory"] = args.trajectory
    run = run_scenario(args.scenario, args.filter, **options)
    summary = run.summary()
    payload = {"scenario": args.scenario, "filter": args.filter, **summary}
    lines = [f"{args.scenario} with the {args.filter} filter: min margin {summary['min_margin']:+.4g} "
             f"(-max B; >= 0 is safe), {summary['violations']} of {summary['samples']} samples unsafe"]
    if "min_distance_mm" in summary:
        lines.append(f"achieved shaft tip: at least {summary['min_distance_mm']:.3f} mm outside the ellipsoid; "
                     f"filtered reference margin {summary['reference_min_margin']:+.4g}")
    _emit(args, payload, "\n".join(lines))


def cmd_safety_certify(args) -> None:
    from rcm_kin.safety.sos import check_by_sampling, find_certificate, thesis_program

    program = thesis_program(args.program, args.delta, args.error_bound, args.r_max, args.eps_bar)
    certificate = find_certificate(program)
    payload = {"program": args.program, "name": program.name, "feasible": certificate.feasible,
               "solver_status": certificate.status,
               "certificate": certificate.as_dict() if certificate.B else None}
    lines = [f"program {args.program} ({program.name}): {'FEASIBLE' if certificate.feasible else 'no certificate'} "
             f"(solver: {certificate.status})"]
    if certificate.B:
        check = check_by_sampling(certificate.B, program)
        payload["sampling_check"] = vars(check)
        def term(e, c):
            factors = [v if k == 1 else f"{v}^{k}" for v, k in zip(program.variables, e) if k]
            return " ".join([f"{c:+.6g}"] + factors)

        terms = "  ".join(term(e, c) for e, c in sorted(certificate.B.items(), key=lambda t: -sum(t[0])))
        lines += [f"B = {terms}",
                  f"sampling check: max B on X0 {check.initial_max_B:+.3g}, min B on Xu {check.unsafe_min_B:+.3g}, "
                  f"max L_f B on X {check.max_lie:+.3g} -> {'passed' if check.passed else 'FAILED'}"]
    _emit(args, payload, "\n".join(lines))


def cmd_report(args) -> None:
    from rcm_kin.report import write_report

    index = write_report(args.out, args.data, args.map_points, progress=True)
    print(f"report written: {index}")


def _weight_budgets() -> dict:
    from rcm_kin.control.weights import Weights
    return vars(Weights()).copy()


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="rcm-kin", description=(
        "Models of the low-cost RCM surgical robot (PSM and MTM): kinematics, dynamics, control. "
        "Units: rad, m, N m, V unless --deg; PWM in counts with the hardware sign."),
        epilog=("examples: rcm-kin fk psm 10 -5 0.08 --deg --json\n"
                "          rcm-kin simulate psm --experiment sine --controller scheduled\n"
                "          rcm-kin report --out report\n"
                "every command: rcm-kin COMMAND --help (units and an example); --json for scripts"),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    robots = ", ".join(robot_names())

    p = sub.add_parser("info", help="joints, limits, axes and frames of a robot", epilog=EPILOG_INFO)
    p.add_argument("robot", help=f"robot name ({robots})")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_info)

    p = sub.add_parser("fk", help="forward kinematics of the frames of interest", epilog=EPILOG_FK,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robot", help=f"robot name ({robots})")
    p.add_argument("q", nargs="*", metavar="Q",
                   help="actuated joint values in 'info' order (rad, m); missing trailing values are 0")
    p.add_argument("--deg", action="store_true", help="revolute values in degrees (prismatic stay in m)")
    p.add_argument("--json", action="store_true", help="machine-readable output (SI)")
    p.set_defaults(func=cmd_fk)

    p = sub.add_parser("ik", help="inverse kinematics: PSM shaft tip or tool pose, MTM wrist centre",
                       epilog=EPILOG_IK, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robot", help="psm or mtm")
    for axis in "xyz":
        p.add_argument(axis, metavar=axis.upper(), help=f"target {axis} in m, base frame")
    p.add_argument("--rpy", nargs=3, metavar=("R", "P", "Y"),
                   help="PSM only: also the tool_tip orientation as roll pitch yaw (rad, or deg with --deg)")
    p.add_argument("--deg", action="store_true", help="--rpy in degrees")
    p.add_argument("--json", action="store_true", help="machine-readable output (SI)")
    p.set_defaults(func=cmd_ik)

    p = sub.add_parser("gravity", help="holding torque (and PSM motor voltage/PWM) at a pose",
                       epilog="example: rcm-kin gravity psm 10 -15 0.08 --deg --json   (roll, pitch in deg, insertion m)",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robot", help=f"robot name ({robots})")
    p.add_argument("q", nargs="*", metavar="Q", help="actuated joint values in 'info' order (rad, m); missing are 0")
    p.add_argument("--deg", action="store_true", help="revolute values in degrees")
    p.add_argument("--no-counterweights", action="store_true", help="remove the counterweights' mass")
    p.add_argument("--params", help="drive parameter TOML (default: the shipped calibrated set)")
    p.add_argument("--json", action="store_true",
                   help='{"joints", "tau" (N m, N), "pwm" (counts), "voltage" (V)} (PWM/V for roll, pitch, insertion)')
    p.set_defaults(func=cmd_gravity)

    p = sub.add_parser("torque-map", help="holding torque/voltage/PWM over roll x pitch (CSV + PNG)",
                       epilog="example: rcm-kin torque-map psm --roll=-30:30:61 --pitch=-30:30:61 --insertion 0.08 --out maps\n(write negative ranges with =, as argparse reads a leading - as an option)",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robot", help="psm")
    p.add_argument("--roll", default="-30:30:61", help="roll grid LO:HI:N in degrees (default -30:30:61)")
    p.add_argument("--pitch", default="-30:30:61", help="pitch grid LO:HI:N in degrees (default -30:30:61)")
    p.add_argument("--insertion", type=float, default=0.08, help="insertion in m (default 0.08)")
    p.add_argument("--no-counterweights", action="store_true", help="remove the counterweights' mass")
    p.add_argument("--params", help="drive parameter TOML (default: the shipped calibrated set)")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--json", action="store_true", help='{"files": [...], "poses": N}')
    p.set_defaults(func=cmd_torque_map)

    p = sub.add_parser("calibrate", help="fit drive gain and gravity offsets to measured holding efforts",
                       epilog="example: rcm-kin calibrate ../shared/data --out my_drive.toml")
    p.add_argument("data", help="folder with roll-step/*.csv and pitch-prbs/*.csv telemetry logs")
    p.add_argument("--params", help="starting drive parameter TOML (default: the shipped set)")
    p.add_argument("--out", help="write the calibrated parameter TOML here")
    p.add_argument("--json", action="store_true", help="parameters with uncertainty, residuals per point")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("dynamics", help="PSM driven-joint accelerations for a state and PWM input",
                       epilog="example: rcm-kin dynamics psm --q 0.1 -0.2 0.08 --v 0 0 0 --u 10 -90 0 --json")
    p.add_argument("robot", help="psm")
    p.add_argument("--q", nargs=3, required=True, metavar="Q", help="roll rad, pitch rad, insertion m")
    p.add_argument("--v", nargs=3, default=["0", "0", "0"], metavar="V", help="their rates (rad/s, m/s; default 0)")
    p.add_argument("--u", nargs=3, default=["0", "0", "0"], metavar="U",
                   help="PWM counts of the three drivers, hardware sign (|u| <= 255; default 0)")
    p.add_argument("--no-coulomb", action="store_true", help="leave the smoothed Coulomb friction out")
    p.add_argument("--params", help="drive parameter TOML (default: the shipped calibrated set)")
    p.add_argument("--json", action="store_true", help='{"qdd": [roll rad/s^2, pitch rad/s^2, insertion m/s^2]}')
    p.set_defaults(func=cmd_dynamics)

    p = sub.add_parser("linearize", help="linear model (A, B, C, D) of the PSM driven joints at a held pose",
                       epilog="example: rcm-kin linearize psm --roll 10 --pitch=-5 --insertion 0.08 --json")
    p.add_argument("robot", help="psm")
    p.add_argument("--roll", required=True, help="roll angle in degrees")
    p.add_argument("--pitch", required=True, help="pitch angle in degrees")
    p.add_argument("--insertion", type=float, default=0.08, help="insertion in m (default 0.08)")
    p.add_argument("--no-coulomb", action="store_true",
                   help="leave the smoothed Coulomb friction out (its slope at rest is set by the smoothing width)")
    p.add_argument("--params", help="drive parameter TOML (default: the shipped calibrated set)")
    p.add_argument("--json", action="store_true",
                   help='{"x0", "u0", "A", "B", "C", "D", "state", "input"}: SI state [q; v], PWM input')
    p.set_defaults(func=cmd_linearize)

    p = sub.add_parser("schedule", help="model-based LQR (roll) / LQI (pitch) gain tables, C header, JSON, CSV",
                       epilog="examples: rcm-kin schedule psm --out gains\n"
                              "          rcm-kin schedule psm --grid=-30,-15,0,15,30:-30,0,30 --gravity-feedforward --out gains",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robot", help="psm")
    p.add_argument("--grid", default="thesis",
                   help="'thesis' (roll -20,0,20 x pitch -15,0,15 deg) or ROLLS:PITCHES in degrees, comma-separated "
                        "(write --grid=-20,0,20:-15,0,15 when it starts with a minus)")
    p.add_argument("--insertion", type=float, default=0.08, help="insertion of the models in m (default 0.08)")
    p.add_argument("--gravity-feedforward", action="store_true",
                   help="also export the holding-PWM table (u_hold) and rcm_holding_pwm()")
    defaults = _weight_budgets()
    for name, value in defaults.items():
        p.add_argument("--" + name.replace("_", "-"), dest=name, type=float, default=value,
                       help=f"Bryson budget (default {value:g})")
    p.add_argument("--check-points", type=int, default=41,
                   help="stability check on N x N poses across the grid (default 41)")
    p.add_argument("--params", help="drive parameter TOML (default: the shipped calibrated set)")
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--json", action="store_true", help='{"files", "stable", weakest point}')
    p.set_defaults(func=cmd_schedule)

    p = sub.add_parser("simulate", help="closed-loop 400 Hz simulation of the thesis tracking experiments",
                       epilog=EPILOG_SIMULATE, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robot", help="psm")
    p.add_argument("--experiment", required=True, choices=("sine", "step", "target"),
                   help="sine: roll 20 deg / pitch 15 deg, 3 s period; step: 10 deg at 0.5 s; "
                        "target: MTM trajectory through teleoperation and IK")
    p.add_argument("--controller", required=True, choices=("p", "pid", "lqr-fixed", "scheduled", "scheduled-gravity"),
                   help="p: Kp 35/60 PWM/deg; pid: thesis Table 3.4; lqr-fixed: model LQR/LQI at (0,0); "
                        "scheduled: gain-scheduled LQR/LQI + feedforward; scheduled-gravity: plus holding PWM")
    p.add_argument("--duration", type=float, help="simulated seconds (default: sine 6, step 3, target: recording)")
    p.add_argument("--trajectory", help="MTM recording CSV (unix_time,x,y,z in m) for --experiment target "
                                        "(default: the bundled figure-eight)")
    p.add_argument("--rate", type=float, default=400.0, help="controller rate in Hz (default 400)")
    p.add_argument("--pwm-limit", nargs=3, metavar=("ROLL", "PITCH", "INS"),
                   help="PWM saturation in counts (default 100 150 100)")
    p.add_argument("--skip", type=float, default=0.0,
                   help="leave the first S seconds out of the statistics (default 0; the sinusoid starts at "
                        "full speed)")
    p.add_argument("--noise-counts", type=float, default=0.0, help="encoder noise std in counts (default 0)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the encoder noise (default 0)")
    p.add_argument("--params", help="drive parameter TOML (default: the shipped calibrated set)")
    p.add_argument("--plot", metavar="DIR", help="write reference/measured/error plots (PNG) into DIR")
    p.add_argument("--json", action="store_true",
                   help='{"roll": {"max_error_deg", "mean_error_deg", "rms_error_deg", ...}, "pitch": {...}}')
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("sysid", help="transfer-function identification from telemetry logs (step or PRBS)",
                       epilog=EPILOG_SYSID, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("log", metavar="LOG", help="telemetry CSV (position = measured deg, velocity = PWM), or a "
                                             "folder of logs named ..._roll_R_pitch_P.csv")
    p.add_argument("--joint", required=True, choices=("roll", "pitch"))
    p.add_argument("--method", choices=("step", "prbs"),
                   help="step: trimmed open-loop step; prbs: whole record about its means (default: roll step, "
                        "pitch prbs)")
    p.add_argument("--order", type=int, help="number of poles (default 2 for step, 3 for prbs)")
    p.add_argument("--zeros", type=int, help="number of zeros (default order - 1)")
    p.add_argument("--samples", type=int, default=1000, help="step: samples kept from the step (default 1000)")
    p.add_argument("--segment", type=int,
                   help="prbs: samples per segment simulated from its own initial state (default 500)")
    p.add_argument("--pose", nargs=2, metavar=("ROLL", "PITCH"),
                   help="pose in deg for the physics comparison (default: from the file name)")
    p.add_argument("--params", help="drive parameter TOML of the physics model (default: the shipped set)")
    p.add_argument("--out", help="folder: write the per-pose table (CSV) when LOG is a folder")
    p.add_argument("--json", action="store_true",
                   help='{"num", "den", "fit_percent", "A", "B", "C", "D", ...}; a folder gives {"models": [...]}')
    p.set_defaults(func=cmd_sysid)

    p = sub.add_parser("greybox", help="fit extra inertia and friction to open-loop step logs by simulating the "
                                       "physics", epilog=EPILOG_GREYBOX,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("logs", nargs="+", metavar="LOG", help="step logs (telemetry CSV) or folders of them")
    p.add_argument("--joint", required=True, choices=("roll", "pitch"))
    p.add_argument("--samples", type=int, default=1000, help="samples kept from each step (default 1000)")
    p.add_argument("--params", help="starting drive parameter TOML (default: the shipped set)")
    p.add_argument("--out", help="write the fitted parameter set (TOML) to this file")
    p.add_argument("--json", action="store_true",
                   help='{"before", "after", "coulomb_per_log", "fit_percent_before", "fit_percent_after", ...}')
    p.set_defaults(func=cmd_greybox)

    p = sub.add_parser("view", help="meshcat view of a robot: served on localhost, or a self-contained HTML page",
                       epilog=EPILOG_VIEW, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("robot", help=f"robot name ({robots})")
    p.add_argument("--q", nargs="*", default=[], metavar="Q",
                   help="actuated joint values in 'info' order (rad, m; missing trailing values are 0)")
    p.add_argument("--deg", action="store_true", help="revolute values in degrees (prismatic stay in m)")
    p.add_argument("--frames", nargs="*", metavar="FRAME", help="frames to show as axis triads (e.g. rcm tool_tip)")
    p.add_argument("--html", metavar="FILE", help="write a self-contained page instead of serving")
    p.add_argument("--png", metavar="FILE", help="write a matplotlib drawing instead of serving")
    p.set_defaults(func=cmd_view)

    p = sub.add_parser("safety", help="CBF safety filter simulations and SOS barrier certificates",
                       epilog=EPILOG_SAFETY, formatter_class=argparse.RawDescriptionHelpFormatter)
    safety = p.add_subparsers(dest="safety_command", required=True, parser_class=_Parser)
    s = safety.add_parser("simulate", help="a scenario of the safety thesis with the CBF filter", epilog=EPILOG_SAFETY,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("scenario", choices=("ellipsoid", "slide", "heart", "psm"),
                   help="ellipsoid: 3-D no-go ellipsoid (radii 30/60/30 mm); slide: workspace [-0.10, 0.05] m; "
                        "heart: beating-heart fixture; psm: our PSM teleoperated towards a 1.5 mm no-go ellipsoid")
    s.add_argument("--filter", choices=("blend", "qp", "none"), default="blend",
                   help="blend: the thesis's sigma k0 + (1 - sigma) u; qp: CBF-QP (Clarabel); none (default blend)")
    s.add_argument("--kappa", type=float, help="aggressiveness of k0 in m (default 1; psm 0.01)")
    s.add_argument("--trajectory", help="psm: MTM recording CSV (default: the bundled figure-eight)")
    s.add_argument("--json", action="store_true", help='{"min_margin", "violations", ...}')
    s.set_defaults(func=cmd_safety_simulate)
    s = safety.add_parser("certify", help="SOS barrier certificate of one of the thesis's programs 1-4",
                          epilog=EPILOG_SAFETY, formatter_class=argparse.RawDescriptionHelpFormatter)
    s.add_argument("program", choices=("1", "2", "3", "4"),
                   help="1: slide first order, zero reference; 2: reference as a state; 3: first-order error "
                        "state; 4: second-order error state")
    s.add_argument("--delta", type=float, help="separation of the initial and unsafe sets in m (thesis: 0.001, "
                                               "0.015, 0.004, 0.005)")
    s.add_argument("--error-bound", type=float, help="programs 3-4: unsafe error beyond this in m (thesis 0.009, 0.008)")
    s.add_argument("--r-max", type=float, help="program 2: largest reference in m (thesis 0.017)")
    s.add_argument("--eps-bar", type=float, help="B on the unsafe set at least this (thesis 0.001, 0.1, 0.01, 0.05)")
    s.add_argument("--json", action="store_true", help='{"feasible", "certificate", "sampling_check", ...}')
    s.set_defaults(func=cmd_safety_certify)

    p = sub.add_parser("report", help="run the main job on the bundled models and write index.html",
                       epilog=EPILOG_REPORT)
    p.add_argument("--out", required=True, help="output folder (created)")
    p.add_argument("--data", help="folder of measured logs (psm-sysid layout): adds calibration, identification "
                                  "per pose and the grey-box fit, and uses its MTM recording for target following")
    p.add_argument("--map-points", type=int, default=61,
                   help="poses per axis of the holding-effort maps over +-30 deg (default 61)")
    p.set_defaults(func=cmd_report)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        args.func(args)
    except RcmKinError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("error: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())

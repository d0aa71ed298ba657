"""``rcm-kin report``: the main job on the bundled models, written as a browsable index.html.

Sections: model summary with pictures and meshcat pages of both robots, kinematic self-checks
(loop closure, constrained vs reduced model, RCM fixity, IK round trips), holding-effort maps
with the thesis Fig 4.6/4.7 curves, the drive parameters and the counterweight design, the
linear models per grid pose, the model-based gain schedule beside the thesis's tables, and the
thesis's tracking experiments (P against the scheduled controller) with animations. With a
data folder: calibration, identification per pose and the grey-box fit on the measured logs.
"""

from __future__ import annotations

import html
import importlib.util
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import yourdfpy

from rcm_kin.closure import constrained, reduced
from rcm_kin.errors import RcmKinError, output_folder
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.numeric_ik import solve_ik
from rcm_kin.kinematics.psm_ik import rcm_geometry, shaft_tip_ik
from rcm_kin.robot import load_robot

VIEW_POSES = {"psm": [np.radians(10.0), np.radians(-15.0), 0.10], "mtm": [0.3, 0.2, 0.4],
              "davinci": [0.0, 0.3, -0.4, 0.2, 0.0, 0.0, 0.2, 0.3, 0.05]}
VIEW_FRAMES = {"psm": ("rcm", "shaft_tip", "tool_tip"), "mtm": ("wrist_center", "tool_tip"),
               "davinci": ("rcm_base_link", "jaw_right_link")}


@dataclass(frozen=True)
class KinematicChecks:
    """Largest discrepancies over random configurations (SI units)."""

    samples: int
    loop_solve_vs_relations: float     # rad, passive joints: Newton solve vs linear relations
    closure_residual: float            # m
    gravity_constrained_vs_reduced: float   # N m
    mass_matrix_constrained_vs_reduced: float
    rcm_distance_to_shaft: float       # m
    psm_ik_round_trip: float           # m, shaft tip
    mtm_ik_round_trip: float           # m, wrist centre


def kinematic_checks(samples: int = 200, seed: int = 0) -> KinematicChecks:
    psm, mtm = load_robot("psm"), load_robot("mtm")
    rng = np.random.default_rng(seed)
    geom = rcm_geometry(psm)
    worst = dict(loop=0.0, res=0.0, grav=0.0, mass=0.0, rcm=0.0, psm_ik=0.0, mtm_ik=0.0)
    for _ in range(samples):
        q = rng.uniform(psm.lower, psm.upper)
        q_tree = constrained.solve_loops(psm, q)
        worst["loop"] = max(worst["loop"], np.max(np.abs(q_tree - reduced.tree_configuration(psm, q))))
        worst["res"] = max(worst["res"], np.max(np.abs(constrained.closure_residual(psm, q_tree))))
        g_tree = pin.computeGeneralizedGravity(psm.tree, psm.tree_data, q_tree)
        tau = constrained.project_torques(psm, q_tree, g_tree).tau
        worst["grav"] = max(worst["grav"], np.max(np.abs(tau - reduced.reduced_gravity(psm, q))))
        worst["mass"] = max(worst["mass"], np.max(np.abs(constrained.mass_matrix(psm, q_tree)
                                                         - reduced.reduced_mass_matrix(psm, q))))
        tip = frame_placement(psm, q, "shaft_tip")
        worst["rcm"] = max(worst["rcm"], np.linalg.norm(np.cross(geom.rcm - tip.translation, tip.rotation[:, 2])))
        q_ik = psm.check_q(shaft_tip_ik(psm, tip.translation), allow_short=True)
        worst["psm_ik"] = max(worst["psm_ik"], np.linalg.norm(
            frame_placement(psm, q_ik, "shaft_tip").translation - tip.translation))
    for _ in range(max(1, samples // 10)):
        qm = rng.uniform(mtm.lower, mtm.upper) * 0.6
        target = frame_placement(mtm, qm, "wrist_center").translation
        worst["mtm_ik"] = max(worst["mtm_ik"], solve_ik(mtm, "wrist_center", target, joints=("j1", "j2", "j3"))
                              .position_error)
    return KinematicChecks(samples, *(float(worst[k]) for k in ("loop", "res", "grav", "mass", "rcm", "psm_ik", "mtm_ik")))


def model_summary(name: str) -> dict:
    """Joints with limits and the mass of every link of a bundled robot (kg)."""
    robot = load_robot(name)
    urdf = yourdfpy.URDF.load(str(robot.description.urdf), build_scene_graph=False, load_meshes=False)
    masses = {link.name: link.inertial.mass for link in urdf.robot.links if link.inertial is not None}
    joints = []
    for jid in range(1, robot.tree.njoints):
        jname = robot.tree.names[jid]
        i = robot.tree.joints[jid].idx_q
        joints.append(dict(name=jname, kind=robot.joint_kind(jname),
                           role="actuated" if jname in robot.actuated else "passive",
                           lower=float(robot.tree.lowerPositionLimit[i]), upper=float(robot.tree.upperPositionLimit[i])))
    return dict(robot=name, joints=joints, link_masses=masses, total_mass=float(sum(masses.values())),
                loops=[c.loop.name for c in robot.constraints])


def gravity_section(out: Path, n: int = 61) -> list[str]:
    """Holding-effort maps (CSV, PNG), trend curves and the counterweight design."""
    from rcm_kin.statics.counterweights import design_counterweights, workspace_grid
    from rcm_kin.dynamics.drive import DriveParameters, load_drive_parameters
    from rcm_kin.statics.gravity_map import write_gravity_maps

    drive = load_drive_parameters()
    grid = np.linspace(-30, 30, n)
    write_gravity_maps(load_robot("psm"), drive, grid, grid, 0.08, out)

    without = load_robot("psm", counterweights=False)
    cad = DriveParameters(drive.joints, {})
    Q = workspace_grid(without)
    designs = [("roll only, DPM as osMDV built it", design_counterweights(without, cad, Q, 2.63, 1.65, weights=(1.0, 0.0),
                                                         dpm_position=(0.15010, np.radians(7.95)))),
               ("roll and pitch, both designed", design_counterweights(without, cad, Q, 2.63, 1.65))]
    rows = [[name, f"{d.main_mass:.2f} kg at {d.main_distance * 1e3:.1f} mm",
             f"{d.dpm_mass:.2f} kg at {d.dpm_distance * 1e3:.1f} mm, {np.degrees(d.dpm_angle):.2f} deg",
             f"{d.rms_pwm[0]:.2f} / {d.peak_pwm[0]:.2f}",
             f"{d.rms_pwm[1]:.2f} / {d.peak_pwm[1]:.2f}"]
            for name, d in designs]
    drive_rows = [[j, f"{d.gear_ratio:.4g}", f"{d.volts_per_pwm:.4g}", f"{d.pwm_per_torque:+.3f}",
                   f"{d.pwm_limit:g}", f"{d.coulomb:.3g}"] for j, d in drive.joints.items()]
    return [
        "<h2>Holding effort (gravity through the calibrated drive model), insertion 80 mm</h2>",
        '<p><img src="torque_map.png" width="700"><br><img src="trend_curves.png" width="700"><br>'
        '<img src="insertion_map.png" width="700"></p>',
        '<p>Data: <a href="torque_map.csv">torque_map.csv</a>, <a href="insertion_map.csv">insertion_map.csv</a>'
        f' ({n} x {n} poses; PWM with the hardware sign: positive decreases the angle).</p>',
        "<h3>Drive parameters</h3>",
        _table(drive_rows, ["joint", "gear ratio", "V per PWM", "PWM per N m (N)", "PWM limit", "Coulomb (N m, N)"]),
        f"<p>Source: {html.escape(drive.source)}; calibrated gravity offsets (kg m): "
        + html.escape(", ".join(f"{k} {np.round(v, 4).tolist()}" for k, v in drive.gravity_offsets.items())) + "</p>",
        "<h3>Counterweight design (CAD model, roll x pitch +-30 deg, 13 x 13 grid)</h3>",
        _table(rows, ["design", "main counterweight", "DPM counterweight", "roll RMS / peak PWM",
                      "pitch RMS / peak PWM"]),
        "<p>The osMDV values are 2.63 kg at 200.28 mm and 1.65 kg at 150.10 mm, 7.95 deg. Holding the DPM "
        "counterweight where osMDV put it, the roll-balancing main counterweight comes out as above. Balancing "
        "pitch too needs the DPM counterweight about twice as far out: the parallelogram as built is not balanced "
        "in pitch, as the large measured pitch holding effort shows.</p>",
    ]


def schedule_section(out: Path) -> tuple:
    """Model-based gain schedule on the thesis grid, its export, and the thesis's tables beside it."""
    from rcm_kin.control.firmware_export import write_gain_schedule
    from rcm_kin.control.thesis_comparison import THESIS_K_PITCH, THESIS_K_ROLL, compare_with_thesis
    from rcm_kin.dynamics.state_space import driven_dynamics
    from rcm_kin.report.figures import stability_maps

    model = driven_dynamics(load_robot("psm"), coulomb=False)
    c = compare_with_thesis(model)
    s = c.model
    folder = output_folder(out / "gain_schedule")
    write_gain_schedule(s, folder, c.ours, gravity_feedforward=True)
    stability_maps({"model-based schedule": c.ours, "thesis gains": c.thesis,
                    "thesis gains, Kd sign flipped": c.thesis_damping_flipped}, out / "stability_maps.png")
    names = [("roll Kp (PWM/deg)", s.k_roll[..., 0], THESIS_K_ROLL[..., 0]),
             ("roll Kd (PWM/(deg/s))", s.k_roll[..., 1], THESIS_K_ROLL[..., 1]),
             ("pitch Kp (PWM/deg)", s.k_pitch[..., 0], THESIS_K_PITCH[..., 0]),
             ("pitch Kd (PWM/(deg/s))", s.k_pitch[..., 1], THESIS_K_PITCH[..., 1]),
             ("pitch Ki (PWM/(deg s))", s.k_pitch[..., 2], THESIS_K_PITCH[..., 2])]
    rows = []
    for name, ours, theirs in names:
        for j, pitch in enumerate(s.pitch_deg):
            rows.append([name if j == 0 else "", f"{pitch:g}"] + [f"{v:.4g}" for v in ours[j]]
                        + [f"{v:.4g}" for v in theirs[j]])
    roll_labels = [f"roll {r:g}" for r in s.roll_deg]
    verdict = [[title, "yes" if v.stable else "NO", f"{v.max_real.max():+.3g}",
                f"{-np.log(v.spectral_radius.max()) * 400:+.3g}", f"{v.min_damping.min():.3f}"]
               for title, v in (("model-based schedule", c.ours), ("thesis tables", c.thesis),
                                ("thesis tables, Kd sign flipped", c.thesis_damping_flipped))]
    poles = ", ".join(f"{p.real:+.3g}{p.imag:+.3g}j" for p in c.thesis_on_identified_roll)
    w = s.weights
    spread = max(np.ptp(t) / np.abs(t).mean() for t in (s.k_roll[..., 0], s.k_pitch[..., 0]))
    home = (len(s.pitch_deg) // 2, len(s.roll_deg) // 2)
    roll_damping = -s.A[home][3, 3]
    return s, [
        "<h2>Gain schedule: roll LQR, pitch LQI, from the linearised model (insertion 80 mm)</h2>",
        f"<p>Bryson budgets: roll error {w.roll_error_deg:g} deg, rate {w.roll_rate_deg_s:g} deg/s, "
        f"PWM {w.roll_pwm:g}; pitch error {w.pitch_error_deg:g} deg, rate {w.pitch_rate_deg_s:g} deg/s, "
        f"integral {w.pitch_integral_deg_s:g} deg s, PWM {w.pitch_pwm:g}. Firmware units and signs "
        "(u = -(Kp e + Kd v [+ Ki int e]), e = r - y, positive PWM lowers the angle). Files: "
        '<a href="gain_schedule/gains.json">gains.json</a>, <a href="gain_schedule/gains.csv">gains.csv</a>, '
        '<a href="gain_schedule/gain_schedule.h">gain_schedule.h</a>.</p>',
        _table(rows, ["gain", "pitch (deg)"] + [f"model, {r}" for r in roll_labels]
               + [f"thesis, {r}" for r in roll_labels]),
        "<h3>Stability on the model, frozen interpolated gains on 21 x 21 poses</h3>",
        _table(verdict, ["gains", "stable", "max Re (continuous, 1/s)", "slowest decay, 400 Hz loop (1/s)",
                         "least damping, 400 Hz loop"]),
        '<p><img src="stability_maps.png" width="900"></p>',
        f"<p>What differs and why. (1) The model's gains hardly vary over the grid ({100 * spread:.1f} % at most): "
        "the closed-loop "
        "stiffness (Kp times the drive gain) is at least 50 times the gravity stiffness, and gravity is better "
        "handled by the holding-PWM feedforward (exported as u_hold) than by re-tuning. The thesis's table "
        "variations (roll Kp 130-138, pitch Kp 151-195) come from identifying each point separately. "
        "(2) The model's Kd is negative in the firmware's sign: with positive PWM lowering the angle, a "
        "positive Kd feeds the velocity back with the accelerating sign. The thesis's positive Kd is "
        "anti-damping on the model. There the roll and pitch loops go unstable, unless the real drive "
        "damps far more than the model (the thesis's identified roll damping is 6.1/s, the model's "
        f"{roll_damping:.2g}/s at roll = pitch = 0). "
        "(3) The thesis's Ki (about 0.15) puts the integrator pole near -0.001/s: in effect no integral "
        "action. The model-based Ki (300) removes an offset in about 0.25 s. (4) On the thesis's own "
        f"identified roll model G(s), which has a right-half-plane zero at +2.06 rad/s, its (0, 0) gains "
        f"give closed-loop poles {poles} rad/s. The identified transfer functions cannot be the loop the "
        "firmware actually closed. (5) The least-damped mode of the model-based loop is the firmware's "
        "insertion P loop (nominal drive constants, not scheduled here). The roll's velocity filter (EMA "
        "0.9) and the sampling lower the damping the continuous design gives.</p>",
    ]


def robots_section(out: Path) -> list[str]:
    """A drawing and a self-contained meshcat page of each robot."""
    from rcm_kin.visualization.drawing import robot_drawing
    from rcm_kin.visualization.views import robot_view, show, write_html

    parts = ["<h2>The robots</h2><p>"]
    for name, q in VIEW_POSES.items():
        robot = load_robot(name)
        robot_drawing(robot, q, out / f"{name}.png", title=name.upper())
        viz = robot_view(robot, frames=VIEW_FRAMES[name])
        show(viz, robot, q)
        write_html(viz, out / f"{name}_view.html")
        parts.append(f'<a href="{name}_view.html"><img src="{name}.png" width="300" '
                     f'title="{name}: open the 3-D view"></a>')
    parts.append("</p><p>Click a picture for its meshcat page (self-contained; drag to turn, scroll to zoom). "
                 "PSM: parallelogram bars blue, brass counterweights, the RCM red; the frames rcm, shaft_tip "
                 "and tool_tip are drawn. The third robot is the first-generation da Vinci patient-side arm of "
                 "the safety thesis (its mimic parallelogram in blue).</p>")
    return parts


def linear_models_section(out: Path, schedule) -> list[str]:
    """The linear models of the schedule's grid: JSON with A, B per pose, and their poles."""
    models, rows = [], []
    for j, pitch in enumerate(schedule.pitch_deg):
        for i, roll in enumerate(schedule.roll_deg):
            A, B = schedule.A[j, i], schedule.B[j, i]
            models.append({"roll_deg": float(roll), "pitch_deg": float(pitch), "insertion_m": schedule.insertion,
                           "A": A.tolist(), "B": B.tolist(), "u_hold_pwm": schedule.u_hold[j, i].tolist()})
            poles = np.linalg.eigvals(A)
            rows.append([f"{roll:g}", f"{pitch:g}", f"{B[3, 0]:+.4g}", f"{B[4, 1]:+.4g}",
                         " ".join(f"{p.real:+.3g}{p.imag:+.2g}j" if abs(p.imag) > 1e-9 else f"{p.real:+.3g}"
                                  for p in sorted(poles, key=lambda p: p.real))])
    (out / "linear_models.json").write_text(json.dumps(models, indent=1))
    return ["<h2>Linear models per grid pose (Coulomb friction left out)</h2>",
            "<p>State [roll, pitch, insertion, their rates] (rad, m, rad/s, m/s), input the three PWMs. "
            'All matrices: <a href="linear_models.json">linear_models.json</a>.</p>',
            _table(rows, ["roll (deg)", "pitch (deg)", "B roll (rad/s^2 per PWM)", "B pitch", "poles of A (1/s)"])]


def tracking_section(out: Path, schedule, trajectory=None) -> list[str]:
    """The thesis's sinusoid and target following: P against the scheduled controllers."""
    from rcm_kin.report.figures import error_comparison_figure, tracking_figure
    from rcm_kin.simulation.controllers import make_controller
    from rcm_kin.simulation.experiments import experiment_reference, psm_plant_and_schedule
    from rcm_kin.simulation.firmware import FirmwareSettings
    from rcm_kin.simulation.loop import si_units, simulate, tracking_metrics
    from rcm_kin.visualization.views import animate, frame_path, robot_view, scalar_trail, write_html

    settings = FirmwareSettings()
    step, _ = psm_plant_and_schedule(period=settings.period)
    psm = load_robot("psm")
    thesis = {("p", "roll"): "1.17 / 0.62", ("p", "pitch"): "2.31 / 1.52",
              ("scheduled", "roll"): "0.41 / 0.21", ("scheduled", "pitch"): "0.35 / 0.12"}
    folder = output_folder(out / "tracking")
    rows, parts = [], []
    for experiment in ("sine", "target"):
        reference = experiment_reference(experiment, settings.period, trajectory=trajectory)
        results = [simulate(step, make_controller(name, schedule), reference, settings)
                   for name in ("p", "scheduled", "scheduled-gravity")]
        for r in results:
            tracking_figure(r, folder / f"{experiment}_{r.controller}.png", title=f"{experiment}, {r.controller}:")
            whole, settled = tracking_metrics(r), tracking_metrics(r, skip=0.5)
            for axis in ("roll", "pitch"):
                m = whole[axis]
                rows.append([experiment, r.controller, axis, f"{m.max_error_deg:.3f} / {m.mean_error_deg:.3f}",
                             f"{settled[axis].max_error_deg:.3f} / {settled[axis].mean_error_deg:.3f}",
                             f"{m.rms_error_deg:.3f}", f"{m.rms_pwm:.1f}", f"{m.saturation_s:.3f}",
                             thesis.get((r.controller, axis), "") if experiment == "sine" else ""])
        error_comparison_figure(results, folder / f"{experiment}_errors.png", title=f"{experiment}:")
        # animation of the scheduled run, the tool-tip path coloured by the pitch PWM
        run = results[-1]
        Q = np.zeros((len(run.time), psm.nq))
        Q[:, :3] = si_units(run.position)
        viz = robot_view(psm)
        every = 8
        animate(viz, psm, Q, settings.period, every=every)
        scalar_trail(viz, "pitch_pwm", frame_path(psm, Q[::every], "tool_tip"), run.pwm[::every, 1])
        write_html(viz, folder / f"{experiment}_animation.html")
        parts.append(f'<h3>{experiment}</h3><p><img src="tracking/{experiment}_errors.png" width="800"><br>'
                     + " ".join(f'<a href="tracking/{experiment}_{r.controller}.png">{r.controller}</a>'
                                for r in results)
                     + f' (reference, measured, error and PWM); <a href="tracking/{experiment}_animation.html">'
                     "3-D animation</a> of the scheduled-gravity run, the tool-tip path coloured by the pitch PWM "
                     "(blue negative, red positive).</p>")
    source = "the MTM recording given" if trajectory else "the bundled figure-eight MTM trajectory"
    return ["<h2>Tracking experiments on the model (thesis Ch. 5)</h2>",
            "<p>The 400 Hz firmware loop on the nonlinear model (friction, encoder counts, EMA velocity, "
            f"PWM saturation and whole counts). Sinusoid: roll 20 deg and pitch 15 deg, 3 s period; target: {source} "
            "through the teleoperation map and the PSM IK. Errors max / mean in deg, over the run and from "
            "0.5 s on (the sinusoid starts at full speed); the thesis's are measured on the robot.</p>",
            _table(rows, ["experiment", "controller", "axis", "max / mean", "from 0.5 s", "RMS", "PWM RMS",
                          "saturated (s)", "thesis max / mean"])] + parts


def safety_section(out: Path) -> list[str]:
    """The CBF scenarios with each filter, the RCM of the three RCM chains, and the SOS
    certificates when cvxpy is installed."""
    from rcm_kin.report.figures import barrier_figure
    from rcm_kin.kinematics.rcm_scatter import rcm_scatter
    from rcm_kin.safety.scenarios import FILTERS, run_scenario

    runs, rows = {}, []
    for scenario in ("ellipsoid", "slide", "heart", "psm"):
        runs[scenario] = {}
        for name in FILTERS:
            run = run_scenario(scenario, name)
            summary = run.summary()
            runs[scenario][name] = run.reference if scenario == "psm" else run
            rows.append([scenario, name, f"{summary['min_margin']:+.4g}", summary["violations"], summary["samples"]])
    barrier_figure({k: v for k, v in runs.items() if k != "psm"}, out / "safety_barriers.png")
    rcm_rows = []
    for name in ("psm", "davinci", "davinci_rcm"):
        rcm = load_robot(name).description.rcm
        scatter = rcm_scatter(load_robot(name), rcm.shaft_frame, rcm.joints, rcm.base_frame)
        rcm_rows.append([name, f"{np.round(scatter.point, 4).tolist()} ({rcm.base_frame or 'base'})",
                         f"{scatter.max_distance * 1e3:.3g}", f"{scatter.rms_distance * 1e3:.3g}"])
    parts = ["<h2>Safety (the da Vinci safety thesis)</h2>",
             "<p>Control-barrier-function filters on a nominal controller; B &lt;= 0 is safe, the margin is "
             "-max B over the run. For the PSM the margin is that of the 1.5 mm no-go ellipsoid at the shaft "
             "tip the simulated 400 Hz loop reached (the filter guards it with 1 mm for the tracking error).</p>",
             _table(rows, ["scenario", "filter", "min margin", "unsafe samples", "samples"]),
             '<p><img src="safety_barriers.png" width="900"></p>',
             "<h3>Remote centre of motion of each chain</h3>",
             _table(rcm_rows, ["robot", "RCM point (m)", "shaft lines within (mm)", "RMS (mm)"])]
    if importlib.util.find_spec("cvxpy") is None:
        return parts + ["<p>SOS barrier certificates: install the optional extra (pip install 'rcm-kin[sos]') "
                        "to add them here.</p>"]
    from rcm_kin.safety.sos import PROGRAMS, check_by_sampling, find_certificate, thesis_program

    cert_rows = []
    for number in PROGRAMS:
        program = thesis_program(number)
        c = find_certificate(program)
        check = check_by_sampling(c.B, program) if c.B else None
        cert_rows.append([number, program.name, "yes" if c.feasible else "no", c.status,
                          "passed" if check and check.passed else "-"])
    return parts + ["<h3>SOS barrier certificates, the thesis's programs with its margins</h3>",
                    _table(cert_rows, ["program", "closed loop", "certificate", "solver", "sampling check"])]


def data_section(out: Path, data: Path) -> list[str]:
    """Calibration, identification per pose and the grey-box fit on a folder of measured logs."""
    from rcm_kin.statics.calibration import calibrate, calibration_logs, holding_points
    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.dynamics.state_space import driven_dynamics
    from rcm_kin.report.figures import greybox_figure
    from rcm_kin.identification.greybox import fit_greybox, step_logs, write_greybox_parameters
    from rcm_kin.identification.pose_models import identify_folder, pose_table_rows, write_pose_table

    params = load_drive_parameters()
    parts = [f"<h2>Measured data: {html.escape(str(data))}</h2>"]
    points = holding_points(calibration_logs(data))
    cal = calibrate(load_robot("psm"), params, points)
    parts += ["<h3>Calibration on the holding efforts</h3>",
              _table([[n, f"{v:+.4g}", f"{sd:.2g}"] for n, v, sd in zip(cal.names, cal.values, cal.std)],
                     ["parameter", "value", "std"]),
              f"<p>{len(points)} holding points; residual RMS roll {cal.residual_rms[0]:.2f}, pitch "
              f"{cal.residual_rms[1]:.2f} PWM.</p>"]
    model = driven_dynamics(load_robot("psm"), params, coulomb=False)
    folder = output_folder(out / "identification")
    for sub, joint in (("roll-step", "roll"), ("pitch-prbs", "pitch")):
        logs = sorted(data.glob(f"**/{sub}"))
        if not logs:
            continue
        models = identify_folder(logs[0], joint, model)
        path = write_pose_table(models, folder / f"{joint}_pose_models.csv")
        rows = [[r["file"], f"{r['fit_percent']:.1f}", f"{r['dc_gain']:+.4f}", r["poles"],
                 f"{r.get('physics_dc_gain', float('nan')):+.4f}", r.get("physics_poles", "")]
                for r in pose_table_rows(models)]
        parts += [f"<h3>Identified {joint} models per pose ({'step, 2 poles' if joint == 'roll' else 'PRBS, 3 poles'})"
                  "</h3>", _table(rows, ["log", "fit %", "DC (deg/PWM)", "poles (1/s)", "physics DC", "physics poles"]),
                  f'<p><a href="identification/{path.name}">{path.name}</a></p>']
        if joint == "roll":
            fit = fit_greybox(params, "roll", step_logs(sorted(logs[0].glob("*.csv")), "roll"))
            write_greybox_parameters(fit, folder / "roll_greybox.toml")
            greybox_figure(fit, folder / "roll_greybox.png")
            parts += ["<h4>Grey-box fit of the roll (extra inertia, viscous, Coulomb and its width)</h4>",
                      _table([[n, f"{b:.4g}", f"{a:.4g}"] for n, b, a in zip(fit.names, fit.before, fit.after)],
                             ["parameter", "starting set", "fitted"]),
                      '<p><img src="identification/roll_greybox.png" width="900"><br>'
                      '<a href="identification/roll_greybox.toml">roll_greybox.toml</a></p>']
    return parts


def _table(rows: list[list], header: list[str]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def write_report(out: str | Path, data: str | Path | None = None, map_points: int = 61,
                 progress: bool = False) -> Path:
    """Run the pipeline on the bundled models (and, with ``data``, on a folder of measured logs);
    ``map_points`` per axis of the holding-effort maps. Returns the path of index.html."""
    from tqdm import tqdm

    if map_points < 2:
        raise RcmKinError("the effort maps need at least 2 points per axis")
    if data is not None and not Path(data).is_dir():
        raise RcmKinError(f"no data folder at {data}")
    out = output_folder(out)
    bar = tqdm(total=8 if data is None else 9, desc="report", unit="step", disable=not progress)

    def step(name):
        bar.set_postfix_str(name)
        bar.update()

    summaries = [model_summary(n) for n in ("psm", "mtm")]
    checks = kinematic_checks()
    step("models checked")
    (out / "model_summary.json").write_text(json.dumps(summaries, indent=1))
    (out / "kinematic_checks.json").write_text(json.dumps(asdict(checks), indent=1))

    parts = ["<h1>rcm-kin report</h1>", "<p>All quantities SI (rad, m, kg, N m).</p>"]
    parts += robots_section(out)
    step("robot views")
    for s in summaries:
        parts.append(f"<h2>Model: {s['robot']}</h2><p>Loop closures: {', '.join(s['loops']) or 'none'}; "
                     f"total link mass {s['total_mass']:.3f} kg.</p>")
        parts.append(_table([[j["name"], j["kind"], j["role"], f"{j['lower']:.4f}", f"{j['upper']:.4f}"]
                             for j in s["joints"]], ["joint", "type", "role", "lower", "upper"]))
        parts.append(_table([[k, f"{v:.4f}"] for k, v in s["link_masses"].items()], ["link", "mass (kg)"]))
    parts.append(f"<h2>Kinematic self-checks ({checks.samples} random PSM configurations)</h2>")
    parts.append(_table([[k, f"{v:.2e}"] for k, v in asdict(checks).items() if k != "samples"],
                        ["largest discrepancy", "value (SI)"]))
    parts.append('<p>Data: <a href="model_summary.json">model_summary.json</a>, '
                 '<a href="kinematic_checks.json">kinematic_checks.json</a></p>')
    parts += gravity_section(out, map_points)
    step("effort maps")
    schedule, schedule_parts = schedule_section(out)
    step("gain schedule")
    parts += linear_models_section(out, schedule) + schedule_parts
    step("linear models")
    parts += tracking_section(out, schedule, _mtm_recording(data))
    step("tracking experiments")
    parts += safety_section(out)
    step("safety")
    if data is not None:
        parts += data_section(out, Path(data))
        step("measured data")
    style = "<style>body{font-family:sans-serif;max-width:60em;margin:2em auto}td,th{padding:2px 8px}</style>"
    index = out / "index.html"
    index.write_text(f"<!doctype html><html><head><meta charset='utf-8'><title>rcm-kin report</title>{style}"
                     f"</head><body>{''.join(parts)}</body></html>\n")
    step("index.html")
    bar.close()
    return index


def _mtm_recording(data) -> Path | None:
    """The MTM recording of a data folder (``mtm_target_trajectory.csv``), if there is one."""
    found = sorted(Path(data).glob("**/mtm_target_trajectory.csv")) if data is not None else []
    return found[0] if found else None

"""Gravity torques, drive model, maps, counterweight design and calibration (the gravity issue)."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from rcm_kin import RcmKinError, load_robot
from rcm_kin.atomic import MANIFEST
from rcm_kin.cli import main
from rcm_kin.csv_table import format_rows_numpy
from rcm_kin.dynamics.drive import DriveParameters, JointDrive, drive_effort, load_drive_parameters, pwm_to_torque
from rcm_kin.model import constrained
from rcm_kin.model.gravity import gravity_batch, gravity_torque, point_mass_gravity_batch
from rcm_kin.statics.counterweights import design_counterweights, workspace_grid
from rcm_kin.statics.maps import gravity_map, parse_range

TOL = 1e-9


def random_poses(robot, n, seed):
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.nq))


@pytest.mark.parametrize("name", ["psm", "mtm"])
@pytest.mark.parametrize("counterweights", [True, False])
def test_three_gravity_computations_agree(name, counterweights):
    robot = load_robot(name, counterweights)
    Q = random_poses(robot, 40, 1)
    batch = gravity_batch(robot, Q)
    for q, g in zip(Q, batch):
        np.testing.assert_allclose(g, gravity_torque(robot, q, "reduced"), atol=TOL)
        if robot.constraints:
            np.testing.assert_allclose(g, gravity_torque(robot, q, "constrained"), atol=TOL)


def test_counterweights_are_point_masses_of_their_mass():
    with_cw, without = load_robot("psm"), load_robot("psm", counterweights=False)
    Q = random_poses(with_cw, 20, 2)
    added = (2.63 * point_mass_gravity_batch(without, Q, "main_counterweight", np.zeros(3))
             + 1.65 * point_mass_gravity_batch(without, Q, "dpm_counterweight", np.zeros(3)))
    np.testing.assert_allclose(gravity_batch(with_cw, Q) - gravity_batch(without, Q), added, atol=TOL)
    total = lambda r: sum(i.mass for i in r.tree.inertias)  # noqa: E731
    assert total(with_cw) - total(without) == pytest.approx(2.63 + 1.65, abs=1e-12)


def test_offsets_are_the_gradient_of_their_potential():
    """A first moment h in a link adds V = -g . (R_link h); its torque is dV/dq (central differences)."""
    robot = load_robot("psm")
    offsets = {"drive_link": np.array([0.05, 0.01, -0.03]), "roll_link": np.array([0.0, 0.02, 0.04])}
    data = robot.reduced.createData()

    def potential(q):
        pin.framesForwardKinematics(robot.reduced, data, robot.to_reduced(q))
        g = robot.reduced.gravity.linear
        return -sum(g @ (data.oMf[robot.reduced.getFrameId(link)].rotation @ h) for link, h in offsets.items())

    h = 1e-6
    for q in random_poses(robot, 5, 3):
        fd = np.array([(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(robot.nq)])
        extra = gravity_batch(robot, q[None], offsets)[0] - gravity_batch(robot, q[None])[0]
        np.testing.assert_allclose(extra, fd, atol=1e-8)


def test_static_equilibrium_of_the_closed_chain():
    """Holding torques on the actuated joints (passive joints free) give zero acceleration:
    the KKT system of the open tree with the loop constraints, at zero velocity."""
    robot = load_robot("psm")
    for q in random_poses(robot, 10, 4):
        q_tree = constrained.solve_loops(robot, q)
        tau_tree = np.zeros(robot.tree.nv)
        tau_tree[robot.tree_q_actuated] = gravity_torque(robot, q)
        M = pin.crba(robot.tree, robot.tree_data, q_tree, pin.Convention.WORLD)
        M = np.triu(M) + np.triu(M, 1).T
        nle = pin.rnea(robot.tree, robot.tree_data, q_tree, np.zeros(robot.tree.nv), np.zeros(robot.tree.nv))
        J = constrained.constraint_jacobian(robot, q_tree)
        kkt = np.block([[M, -J.T], [J, np.zeros((len(J), len(J)))]])
        qdd = np.linalg.solve(kkt, np.concatenate([tau_tree - nle, np.zeros(len(J))]))[:robot.tree.nv]
        # judged as the inertial force M qdd (N m): the wrist links' inertias (~1e-8 kg m^2)
        # turn round-off torques into accelerations of ~1e-9 rad/s^2
        np.testing.assert_allclose(M @ qdd, 0.0, atol=1e-12)
        # and a torque 1 % off does accelerate it
        tau_tree[robot.tree_q_actuated[1]] *= 1.01
        qdd = np.linalg.solve(kkt, np.concatenate([tau_tree - nle, np.zeros(len(J))]))[:robot.tree.nv]
        assert np.max(np.abs(qdd)) > 1e-4


def _drive(**kw) -> DriveParameters:
    d = dict(gear_ratio=20.0, torque_constant=0.03, resistance=0.6, volts_per_pwm=0.1, pwm_sign=-1.0,
             pwm_limit=100.0, rotor_inertia=1e-6, viscous=0.0, coulomb=0.0)
    d.update(kw)
    return DriveParameters({j: JointDrive(**d) for j in ("roll", "pitch", "insertion")}, {})


def test_drive_chain_by_hand():
    """1 N m at a 20:1 joint: 0.05 N m motor, 1.6667 A, 1.0 V, -10 PWM (positive PWM decreases)."""
    e = drive_effort(_drive(), [1.0, 0.0, 0.0])
    assert e.motor_torque[0] == pytest.approx(0.05, abs=1e-15)
    assert e.current[0] == pytest.approx(0.05 / 0.03, abs=1e-12)
    assert e.voltage[0] == pytest.approx(1.0, abs=1e-12)
    assert e.pwm[0] == pytest.approx(-10.0, abs=1e-12)
    # back-EMF at 1 rad/s: k_t * N * v = 0.6 V more
    assert drive_effort(_drive(), [1.0, 0, 0], [1.0, 0, 0]).voltage[0] == pytest.approx(1.6, abs=1e-12)
    assert drive_effort(_drive(), [20.0, 0, 0]).saturated[0]
    np.testing.assert_allclose(pwm_to_torque(_drive(), e.pwm), [1.0, 0, 0], atol=1e-12)


def test_shipped_drive_parameters_load():
    params = load_drive_parameters()
    assert params["roll"].gear_ratio == 20.0 and params["pitch"].gear_ratio == pytest.approx(160 / 12)
    assert params["insertion"].gear_ratio == pytest.approx(2 * np.pi / 0.060)
    assert params["roll"].pwm_sign == -1.0 and params["pitch"].pwm_sign == -1.0


def test_pwm_limits_are_the_firmwares_and_old_files_with_them_still_load(tmp_path):
    """The firmware's saturation lives in rcm_kin.hardware: a loaded set carries it, a written
    file leaves it out, and an older file that still has the key loads when it agrees."""
    from rcm_kin.dynamics.drive import DEFAULT_PARAMETERS, write_parameters
    from rcm_kin.hardware import PWM_LIMIT

    params = load_drive_parameters()
    assert [params[j].pwm_limit for j in ("roll", "pitch", "insertion")] == PWM_LIMIT.tolist()
    assert "pwm_limit" not in write_parameters(params, tmp_path / "new.toml").read_text()
    text = DEFAULT_PARAMETERS.read_text()
    old = text.replace("pwm_sign = -1.0\n", "pwm_sign = -1.0\npwm_limit = 100.0\n", 1)
    (tmp_path / "old.toml").write_text(old.replace("[pitch]\n", "[pitch]\npwm_limit = 150.0\n"))
    assert load_drive_parameters(tmp_path / "old.toml").joints == params.joints
    (tmp_path / "other.toml").write_text(old.replace("pwm_limit = 100.0", "pwm_limit = 120.0"))
    with pytest.raises(RcmKinError, match="differs from the firmware"):
        load_drive_parameters(tmp_path / "other.toml")


def test_bad_parameter_file(tmp_path):
    (tmp_path / "bad.toml").write_text("robot = \"psm\"\n[roll]\ngear_ratio = 20\n")
    with pytest.raises(RcmKinError, match=r"\[roll\] needs"):
        load_drive_parameters(tmp_path / "bad.toml")


def test_cad_trends_of_thesis_figures():
    """CAD model, no calibration: roll effort grows with |roll| (Fig 4.6), pitch effort falls
    from -30 to +30 deg (Fig 4.7), each depending on the other joint."""
    robot = load_robot("psm")
    cad = DriveParameters(load_drive_parameters().joints, {})
    grid = np.linspace(-30, 30, 61)
    gmap = gravity_map(robot, cad, grid, grid, [0.08])
    roll_at_pitch0 = np.abs(gmap.effort.voltage[30, :, 0, 0])
    assert np.all(np.diff(roll_at_pitch0[30:]) > 0) and np.all(np.diff(roll_at_pitch0[:31]) < 0)
    for j in (0, 30, 60):
        pitch_curve = gmap.effort.voltage[:, j, 0, 1]
        assert np.all(np.diff(pitch_curve) < 0)
    assert not np.allclose(gmap.effort.voltage[:, 0, 0, 1], gmap.effort.voltage[:, 30, 0, 1])   # coupled
    assert not np.allclose(gmap.effort.voltage[0, :, 0, 0], gmap.effort.voltage[30, :, 0, 0])


def test_calibrated_pitch_trend():
    gmap = gravity_map(load_robot("psm"), load_drive_parameters(), [0.0], np.linspace(-30, 30, 31), [0.08])
    assert np.all(np.diff(gmap.effort.voltage[:, 0, 0, 1]) < 0)


def test_map_matches_pointwise_and_rejects_bad_ranges():
    robot, drive = load_robot("psm"), load_drive_parameters()
    gmap = gravity_map(robot, drive, [-20.0, 10.0], [5.0, 25.0], [0.05, 0.1])
    q = np.array([np.radians(10.0), np.radians(25.0), 0.1, 0, 0, 0, 0])
    tau = gravity_batch(robot, q[None], drive.gravity_offsets)[0, :3]
    np.testing.assert_allclose(gmap.effort.tau[1, 1, 1], tau, atol=1e-12)
    with pytest.raises(RcmKinError, match="outside the joint limits"):
        gravity_map(robot, drive, [40.0], [0.0], [0.08])
    with pytest.raises(RcmKinError, match="LO:HI:N"):
        parse_range("1:2", "--roll")


def test_counterweight_design_reproduces_osmdv_main_counterweight():
    """osMDV sized the main counterweight to balance roll with the DPM counterweight where it
    is (1.65 kg at 150.10 mm, 7.95 deg). The roll-balancing distance for 2.63 kg must fall in
    the span of osMDV's own gravity fits (arm lever 227.12 mm at d = 0 to 200.83 mm at d = 160,
    giving 181-218 mm); osMDV chose 200.28 mm."""
    robot = load_robot("psm", counterweights=False)
    drive = DriveParameters(load_drive_parameters().joints, {})
    design = design_counterweights(robot, drive, workspace_grid(robot), 2.63, 1.65, weights=(1.0, 0.0),
                                   dpm_position=(0.15010, np.radians(7.95)))
    low, high = [(3.606 * lever - 1.65 * 0.15010) / 2.63 for lever in (0.20083, 0.22712)]
    assert low < design.main_distance < high
    assert design.rms_pwm[0] < 3.0


def test_counterweight_design_is_optimal():
    robot = load_robot("psm", counterweights=False)
    drive = DriveParameters(load_drive_parameters().joints, {})
    Q = workspace_grid(robot)
    best = design_counterweights(robot, drive, Q, 2.63, 1.65)
    held = design_counterweights(robot, drive, Q, 2.63, 1.65, dpm_position=(0.15010, np.radians(7.95)))
    assert np.sum(best.rms_pwm**2) < np.sum(held.rms_pwm**2)
    # moving the designed DPM counterweight (within the 0.3 m bounds) only makes it worse
    for dr, dphi in ((-0.01, 0.0), (-0.01, 0.05), (-0.01, -0.05)):
        worse = design_counterweights(robot, drive, Q, 2.63, 1.65,
                                      dpm_position=(best.dpm_distance + dr, best.dpm_angle + dphi))
        assert np.sum(worse.rms_pwm**2) > np.sum(best.rms_pwm**2)


def test_gravity_cli_contract(capsys):
    assert main(["gravity", "psm", "10", "-15", "0.08", "--deg", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["joints"][:3] == ["roll", "pitch", "insertion"]
    assert len(out["tau"]) == 7 and len(out["pwm"]) == 3 and len(out["voltage"]) == 3
    drive = load_drive_parameters()
    q = np.array([np.radians(10), np.radians(-15), 0.08, 0, 0, 0, 0])
    tau = gravity_batch(load_robot("psm"), q[None], drive.gravity_offsets)[0]
    np.testing.assert_allclose(out["tau"], tau, atol=1e-12)
    np.testing.assert_allclose(out["pwm"], drive_effort(drive, tau[:3]).pwm, atol=1e-9)


def test_torque_map_cli(tmp_path, capsys):
    assert main(["torque-map", "psm", "--roll=-30:30:7", "--pitch=-30:30:5", "--out", str(tmp_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["poses"] == 35
    for name in ("torque_map.csv", "torque_map.png", "trend_curves.png", "insertion_map.csv", "insertion_map.png"):
        assert (tmp_path / name).stat().st_size > 0
    rows = (tmp_path / "torque_map.csv").read_text().splitlines()
    assert len(rows) == 36 and rows[0].startswith("roll_deg,pitch_deg,insertion_m,tau_roll")


def test_torque_map_npz_holds_the_csv_numbers(tmp_path, capsys):
    """--format npz: one array per CSV column, rows in the CSV's order, at full precision: the CSV
    is exactly those numbers written by the NumPy formatter (the command's CSV uses the compiled
    one), and within the 9-decimal rounding of them read back."""
    grid = ["--roll=-30:30:7", "--pitch=-20:25:5", "--insertion", "0.1", "--json"]
    assert main(["torque-map", "psm", *grid, "--out", str(tmp_path / "csv")]) == 0
    assert main(["torque-map", "psm", *grid, "--out", str(tmp_path / "npz"), "--format", "npz", "--no-figures"]) == 0
    out = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert out == {"files": [str(tmp_path / "npz" / "torque_map.npz"), str(tmp_path / "npz" / "insertion_map.npz")],
                   "poses": 35, "model": "calibration psm_drive.toml"}
    written = sorted(p.name for p in (tmp_path / "npz").iterdir() if p.name != MANIFEST)
    assert written == ["insertion_map.npz", "torque_map.npz"]
    for name, poses in (("torque_map", 35), ("insertion_map", 6 * 81)):
        text = (tmp_path / "csv" / f"{name}.csv").read_bytes()
        header = text.split(b"\r\n", 1)[0].decode().split(",")
        with np.load(tmp_path / "npz" / f"{name}.npz") as npz:
            assert npz.files == header
            table = np.column_stack([npz[c] for c in header])
        assert table.shape == (poses, 12) and table.dtype == float
        assert text == ",".join(header).encode() + b"\r\n" + format_rows_numpy(table)
        back = np.array([[float(v) for v in line.split(",")] for line in text.decode().splitlines()[1:]])
        assert np.all(np.abs(back - table) <= 0.5e-9 + 4 * np.finfo(float).eps * np.abs(table))
    # the npz's numbers are the map's own (full precision): pose 3 of the first pitch row
    with np.load(tmp_path / "npz" / "torque_map.npz") as npz:
        assert (npz["roll_deg"][3], npz["pitch_deg"][3], npz["insertion_m"][3]) == (0.0, -20.0, 0.1)
        tau = gravity_batch(load_robot("psm"), np.array([[0.0, np.radians(-20.0), 0.1, 0, 0, 0, 0]]),
                            load_drive_parameters().gravity_offsets)[0]
        np.testing.assert_allclose([npz[f"tau_{j}"][3] for j in ("roll", "pitch", "insertion")], tau[:3],
                                   rtol=0, atol=1e-12)


def test_write_npz_writes_the_path_it_returns(tmp_path):
    """Whatever the suffix, the file is the one named and returned (np.savez alone would append
    ".npz" to another), and it loads as the table."""
    from rcm_kin.statics.maps import gravity_map, table_header, write_npz

    gmap = gravity_map(load_robot("psm"), load_drive_parameters(), [0.0, 10.0], [0.0], [0.1])
    path = write_npz(gmap, tmp_path / "map.bin")
    assert path == tmp_path / "map.bin" and path.is_file() and not (tmp_path / "map.bin.npz").exists()
    with np.load(path) as npz:
        assert npz.files == table_header() and npz["roll_deg"].tolist() == [0.0, 10.0]


def test_torque_map_refuses_an_unknown_table_format(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["torque-map", "psm", "--roll=0:10:2", "--format", "parquet", "--out", str(tmp_path / "m")])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count("\n") == 1
    assert err.startswith("error: argument --format: invalid choice: 'parquet' (choose from 'csv', 'npz')")
    assert not (tmp_path / "m").exists()


def test_calibration_reproduces_measured_holding(shared_data, tmp_path):
    from rcm_kin.identification.calibration import calibrate, calibration_logs, holding_points, predict_pwm

    robot, shipped = load_robot("psm"), load_drive_parameters()
    points = holding_points(calibration_logs(shared_data))
    assert len(points) >= 10
    measured = np.array([[p.pwm_roll, p.pwm_pitch] for p in points])
    predicted = predict_pwm(robot, shipped, points)
    rms = np.sqrt(np.mean((predicted - measured) ** 2, axis=0))
    assert rms[0] < 3.0 and rms[1] < 8.0          # PWM counts (measured holds scatter by +-13 in pitch)
    # the shipped parameters are what a fresh calibration gives
    fresh = calibrate(robot, shipped, points)
    np.testing.assert_allclose(fresh.parameters["pitch"].volts_per_pwm, shipped["pitch"].volts_per_pwm, rtol=1e-4)
    # and the uncalibrated CAD model does much worse on the same data
    cad = DriveParameters(shipped.joints, {})
    cad_rms = np.sqrt(np.mean((predict_pwm(robot, cad, points) - measured) ** 2, axis=0))
    assert np.all(cad_rms > 2 * rms)


def test_calibration_generalises_to_logs_it_did_not_see(shared_data):
    from rcm_kin.identification.calibration import calibrate, calibration_logs, holding_points, predict_pwm

    robot, base = load_robot("psm"), load_drive_parameters()
    points = holding_points(calibration_logs(shared_data))
    steps = [p for p in points if "step" in p.source]
    prbs = [p for p in points if "prbs" in p.source]
    fit = calibrate(robot, base, steps)
    error = predict_pwm(robot, fit.parameters, prbs) - np.array([[p.pwm_roll, p.pwm_pitch] for p in prbs])
    rms = np.sqrt(np.mean(error**2, axis=0))
    assert rms[0] < 4.0 and rms[1] < 15.0


def test_not_a_telemetry_log(tmp_path, capsys):
    from rcm_kin.identification.telemetry import load_telemetry

    (tmp_path / "x.csv").write_text("a,b\n1,2\n3,4\n")
    with pytest.raises(RcmKinError, match="not a telemetry log"):
        load_telemetry(tmp_path / "x.csv")
    (tmp_path / "roll-step").mkdir()
    (tmp_path / "roll-step" / "roll_step_x.csv").write_text("time,pitch_position,pitch_velocity\n0,1,2\n1,1,2\n2,1,2\n")
    assert main(["calibrate", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and "roll/position" in err and err.count("\n") == 1


def test_compiled_map_equals_numpy_gravity_and_blockwise_drive(psm, params):
    """The map's compiled driven gravity against the NumPy batch (independent code) at 1e-12,
    and the drive model in blocks against one call."""
    from rcm_kin.statics.maps import drive_effort_blocks, driven_gravity

    rng = np.random.default_rng(3)
    i = [psm.actuated.index(j) for j in ("roll", "pitch", "insertion")]
    Q = rng.uniform(psm.lower[i], psm.upper[i], (50, 3))
    Q7 = np.zeros((50, psm.nq))
    Q7[:, :3] = Q
    expect = gravity_batch(psm, Q7, params.gravity_offsets)[:, :3]
    np.testing.assert_allclose(driven_gravity(psm, params, Q, block=16), expect, rtol=0, atol=1e-12)
    tau = expect.reshape(5, 10, 1, 3)
    blocks, whole = drive_effort_blocks(params, tau, block=7), drive_effort(params, tau)
    for name in ("tau", "motor_torque", "current", "voltage", "pwm", "saturated"):
        np.testing.assert_array_equal(getattr(blocks, name), getattr(whole, name))

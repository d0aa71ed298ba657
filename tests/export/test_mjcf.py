"""MJCF export checked by MuJoCo itself: the file loads cleanly, MuJoCo's kinematics closes the loops
at our keyframes, motors holding our gravity torques keep the arm at rest (and it falls without
them), and a free swing in MuJoCo follows our closed-chain dynamics."""

from __future__ import annotations

import numpy as np
import pytest

from rcm_kin.cli import main
from rcm_kin.dynamics.drive import robot_drive
from rcm_kin.export.calibrated import calibrated_robot
from rcm_kin.export.mjcf import keyframes, write_mjcf
from rcm_kin.export.mujoco_check import (
    actuated_q,
    at_keyframe,
    closed_chain_swing,
    drive_terms,
    hold_speeds,
    mujoco_swing,
)
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.model import load_robot
from rcm_kin.model.gravity import gravity_torque

mujoco = pytest.importorskip("mujoco", reason="MuJoCo is the optional extra [mujoco]")

INSTRUMENT = ("instrument_roll", "wrist_pitch", "wrist_yaw", "jaw")
GRID = [f"roll{r}_pitch{p}" for r in (-30, 0, 30) for p in (-30, 0, 30)]


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """``rcm-kin export ROBOT --mjcf`` of each robot, loaded by MuJoCo; MuJoCo's messages captured."""
    folder = tmp_path_factory.mktemp("mjcf")
    return {name: folder / f"{name}.xml" for name in ("psm", "mtm", "davinci")
            if main(["export", name, "--mjcf", str(folder / f"{name}.xml")]) == 0}


@pytest.fixture(scope="module")
def psm_model(exported):
    return mujoco.MjModel.from_xml_path(str(exported["psm"]))


@pytest.mark.parametrize("name", ["psm", "mtm", "davinci"])
def test_export_loads_in_mujoco_without_warnings(exported, name, capfd):
    robot = load_robot(name)
    model = mujoco.MjModel.from_xml_path(str(exported[name]))
    data = at_keyframe(model, "home")
    for _ in range(100):
        mujoco.mj_step(model, data)
    assert capfd.readouterr().err == "" and data.warning.number.sum() == 0
    assert [model.actuator(i).name for i in range(model.nu)] == list(robot.actuated)
    np.testing.assert_array_equal(model.actuator_gear[:, 0], 1.0)
    assert model.neq == (len(robot.description.loops) or len(robot.description.passive))
    assert all(model.eq(i).type == (mujoco.mjtEq.mjEQ_CONNECT if robot.description.loops else mujoco.mjtEq.mjEQ_JOINT)
               for i in range(model.neq))
    # every joint with Pinocchio's limits and home position, every moving body with Pinocchio's mass
    home = at_keyframe(model, "home")
    for j in range(1, robot.tree.njoints):
        i = robot.tree.joints[j].idx_q
        assert home.qpos[model.joint(robot.tree.names[j]).qposadr[0]] == keyframes(robot)[0].q_tree[i]
        np.testing.assert_array_equal(model.joint(robot.tree.names[j]).range,
                                      [robot.tree.lowerPositionLimit[i], robot.tree.upperPositionLimit[i]])
        if robot.tree.inertias[j].mass > 0:
            body = model.body(model.joint(robot.tree.names[j]).bodyid[0])
            assert body.mass[0] == pytest.approx(robot.tree.inertias[j].mass, rel=1e-15)


def test_psm_keyframes_are_home_and_the_thesis_grid(psm_model):
    assert [psm_model.key(i).name for i in range(psm_model.nkey)] == ["home"] + GRID
    psm = load_robot("psm")
    data = at_keyframe(psm_model, "roll-30_pitch30")
    np.testing.assert_allclose(actuated_q(psm_model, data, psm)[:3], [np.radians(-30), np.radians(30), 0.08],
                               rtol=0, atol=1e-15)
    calibrated = calibrated_robot(psm, robot_drive(psm))
    for i in range(psm_model.nkey):     # each keyframe's controls hold it: the calibrated gravity, the loop-solve way
        q = actuated_q(psm_model, at_keyframe(psm_model, psm_model.key(i).name), psm)
        np.testing.assert_allclose(psm_model.key(i).ctrl, gravity_torque(calibrated, q, method="constrained"),
                                   rtol=0, atol=1e-9)


@pytest.mark.parametrize("key", ["home"] + GRID)
def test_mujoco_kinematics_closes_the_loops_and_places_our_frames(psm_model, key):
    """MuJoCo's forward kinematics at a keyframe: the two sites of each loop coincide (the passive
    joints are closed) and the frames of interest sit where our FK puts them."""
    psm = load_robot("psm")
    data = at_keyframe(psm_model, key)
    for loop in psm.description.loops:
        np.testing.assert_allclose(data.site(f"{loop.name}_a").xpos, data.site(f"{loop.name}_b").xpos,
                                   rtol=0, atol=1e-12)
    q = actuated_q(psm_model, data, psm)
    for frame in psm.description.frames:
        np.testing.assert_allclose(data.site(frame).xpos, frame_placement(psm, q, frame).translation,
                                   rtol=0, atol=1e-12)


@pytest.mark.parametrize("key", ["home"] + GRID)
def test_motors_holding_our_gravity_torques_keep_the_arm_at_rest(psm_model, key):
    """Controls = the exported model's gravity torques (the shipped calibration; Pinocchio's
    constrained method on the calibrated inertias: loop solve + projection). The arm (roll,
    pitch, insertion and the parallelogram joints) stays under 1e-3 rad/s (m/s) for 0.5 s; without the
    motors it falls (the insertion slides out at about 1 m/s; the calibrated gravity, up to 5 N m,
    overcomes the drives' Coulomb friction, 1.1-1.3 N m, on roll and pitch but where pitch rests on
    its +-30 deg limits). The instrument is held too at home; elsewhere its 6 g
    wrist is an unstable equilibrium (growth rate up to 18 /s by our linearisation, e^9 in 0.5 s) that
    the start-up
    transient of MuJoCo's soft loop constraints tips over, so it is not asserted there."""
    psm = load_robot("psm")
    calibrated = calibrated_robot(psm, robot_drive(psm))
    q = actuated_q(psm_model, at_keyframe(psm_model, key), psm)
    held = hold_speeds(psm_model, at_keyframe(psm_model, key, gravity_torque(calibrated, q, method="constrained")),
                       0.5)
    arm = {j: v for j, v in held.items() if j not in INSTRUMENT or key == "home"}
    assert max(arm.values()) < 1e-3, arm
    fallen = hold_speeds(psm_model, at_keyframe(psm_model, key, np.zeros(psm.nq)), 0.5)
    assert max(v for j, v in fallen.items() if j not in INSTRUMENT) > 0.05


@pytest.mark.parametrize("model_of, seconds", [("calibration", 0.2), ("cad", 1.0)])
def test_free_swing_follows_our_dynamics(exported, tmp_path, model_of, seconds):
    """From rest at home, no motor torque, joint limits off (ours has none), Coulomb friction off
    (MuJoCo's frictionloss is a hard dry friction, ours a tanh law): MuJoCo's RK4 (0.5 ms) and our
    closed-chain dynamics of the same model (the calibrated export beside Pinocchio on the
    calibrated inertias, with the drives' armature and damping; the CAD export beside the URDF's
    model) agree to 1e-4 of each joint's travel. Why 1e-4: MuJoCo's loop constraints are soft,
    regularised by (1 - d)/d = 1e-4 of their inertia at our impedance d = 0.9999; the difference
    does not shrink with the step (0.5, 0.25, 0.1 ms agree to 3 digits), so it is that
    regularisation, not the integration. The calibrated arm falls fast: 0.2 s (pitch 0.33 rad);
    past about 0.35 s it leaves the joint ranges (pitch -83 deg, insertion 0.67 m at 0.4 s) and the
    two part there. Without the loop constraints MuJoCo's arm leaves ours by far more: the
    comparison sees the loops."""
    psm = load_robot("psm")
    drive = robot_drive(psm) if model_of == "calibration" else None
    path = exported["psm"] if drive else write_mjcf(psm, tmp_path / "cad.xml", "cad")
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_LIMIT
    model.dof_frictionloss[:] = 0.0
    times = np.arange(0.0, seconds + 1e-9, 0.01)
    theirs = mujoco_swing(model, at_keyframe(model, "home", np.zeros(psm.nq)), psm, times)
    ours = closed_chain_swing(calibrated_robot(psm, drive), theirs[0], times, *drive_terms(psm, drive))
    travel = np.max(np.abs(ours - ours[0]), axis=0)
    assert travel[psm.actuated.index("pitch")] > 0.3          # it does swing
    np.testing.assert_array_less(np.max(np.abs(theirs - ours), axis=0), 1e-4 * travel + 1e-12)
    model.eq_active0[:] = 0
    open_tree = mujoco_swing(model, at_keyframe(model, "home", np.zeros(psm.nq)), psm, times)
    assert np.max(np.abs(open_tree - ours)[:, psm.actuated.index("pitch")]) > 100 * 1e-4 * travel[1]


def test_report_section_tabulates_the_runs(tmp_path):
    from rcm_kin.report.render import render_section
    from rcm_kin.report.sections.mujoco import mujoco_section

    section = mujoco_section(tmp_path)
    assert (tmp_path / section.model).is_file()
    assert [row[0] for row in section.holding.rows] == ["home"] + GRID
    assert all(float(row[1]) < 1e-3 for row in section.holding.rows)          # the arm held everywhere
    differences = np.array([row[1:] for row in section.swing.rows[:-1]], dtype=float)
    assert np.all(differences < 1e-4 * np.array(section.swing.rows[-1][1:], dtype=float))
    assert "The PSM in MuJoCo" in render_section(section)

"""Dynamics and linear models of robots no code names: the MTM (torque input, no drive file), a
UR5 from example-robot-data, and a renamed, re-massed PSM copy with a drive file of its own. Each is
checked against plain Pinocchio on the same URDF or against finite differences of Pinocchio's ABA."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from oracles.dyn_robots import DRIVE_KEYS, drive_text, ur5_urdf, write_mypsm, write_ur5

import rcm_kin as rk
from rcm_kin import RcmKinError
from rcm_kin.control.linearization import linearize, linearize_grid, linearize_pinocchio
from rcm_kin.dynamics.drive import drive_effort, load_drive_parameters, pwm_to_torque
from rcm_kin.dynamics.state_space import check_state, driven_dynamics
from rcm_kin.model.loading import urdf_dir


def plain_tree(urdf: Path, sidecar: dict) -> tuple[pin.Model, np.ndarray]:
    """The URDF's open tree by Pinocchio alone and the map ``S`` (tree nq x actuated) of the
    sidecar's ``actuated`` joints and ``[[passive]]`` relations (q_tree = S q, zero offsets here)."""
    model = pin.buildModelFromUrdf(str(urdf))
    actuated = sidecar["actuated"]
    S = np.zeros((model.nq, len(actuated)))
    for k, name in enumerate(actuated):
        S[model.joints[model.getJointId(name)].idx_q, k] = 1.0
    for rel in sidecar.get("passive", []):
        assert rel.get("offset", 0.0) == 0.0
        S[model.joints[model.getJointId(rel["joint"])].idx_q, actuated.index(rel["follows"])] = rel["multiplier"]
    return model, S


def plain_equilibrium_model(model: pin.Model, S: np.ndarray, q: np.ndarray, cols: list[int],
                            inertia=0.0, gain=1.0, damping=0.0):
    """``(u0, A, B)`` at rest at actuated pose ``q`` for the joints ``cols``: at an equilibrium
    ``A = [[0, I], [-M^-1 dg/dq, -M^-1 D]]``, ``B = [0; M^-1 K]``, from CRBA and gravity derivatives."""
    data = model.createData()
    Sd, q_tree = S[:, cols], S @ q
    M = Sd.T @ pin.crba(model, data, q_tree) @ Sd
    M = np.triu(M) + np.triu(M, 1).T + np.diag(np.broadcast_to(inertia, len(cols)))
    g = Sd.T @ pin.computeGeneralizedGravity(model, data, q_tree)
    dg = Sd.T @ pin.computeGeneralizedGravityDerivatives(model, data, q_tree) @ Sd
    n, Minv = len(cols), np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ dg, -Minv @ np.diag(np.broadcast_to(damping, n))]])
    return g / gain, A, np.vstack([np.zeros((n, n)), Minv @ np.diag(np.broadcast_to(gain, n))])


# --- the MTM: torque input, finite differences of Pinocchio's ABA ---------------------------------------
def mtm_forward(mtm, q_fixed, cols):
    """xdot(x, tau) of the MTM's joints ``cols`` by ``pin.aba``, the other joints locked at
    ``q_fixed`` (Pinocchio's ``buildReducedModel`` of its open tree)."""
    locked = [mtm.tree.getJointId(mtm.actuated[k]) for k in range(mtm.nq) if k not in cols]
    tree = pin.buildReducedModel(mtm.tree, locked, q_fixed[np.argsort(mtm.tree_q_actuated)]) if locked else mtm.tree
    data = tree.createData()
    index = [tree.joints[tree.getJointId(mtm.actuated[k])].idx_q for k in cols]

    def f(x, u):
        n = len(cols)
        q, v, tau = np.zeros(tree.nq), np.zeros(tree.nv), np.zeros(tree.nv)
        q[index], v[index], tau[index] = x[:n], x[n:], u
        return np.r_[x[n:], pin.aba(tree, data, q, v, tau)[index]]
    return f


@pytest.mark.parametrize("joints", [None, ("j1", "j2", "j3")])
def test_mtm_linear_model_equals_finite_differences_of_pinocchio_aba(mtm, joints):
    model = driven_dynamics(mtm, joints=joints)
    cols = [mtm.actuated.index(j) for j in model.joints]
    assert model.input_unit.startswith("torque") and model.model_label == "CAD (URDF inertias)"
    rng = np.random.default_rng(11)
    for _ in range(4):
        q_all = rng.uniform(mtm.lower, mtm.upper) * 0.8
        q_fixed = q_all.copy()
        model = driven_dynamics(mtm, joints=joints, q_fixed=q_fixed)
        lin = linearize(model, q_all[cols])
        f = mtm_forward(mtm, q_fixed, cols)
        np.testing.assert_allclose(f(lin.x0, lin.u0), 0, atol=1e-9)     # u0 holds the pose (N m)
        h, n = 1e-6, len(cols)
        A = np.column_stack([(f(lin.x0 + h * e, lin.u0) - f(lin.x0 - h * e, lin.u0)) / (2 * h) for e in np.eye(2 * n)])
        B = np.column_stack([(f(lin.x0, lin.u0 + e) - f(lin.x0, lin.u0 - e)) / 2 for e in np.eye(n)])
        for ours, theirs in ((lin.A, A), (lin.B, B)):
            np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-6 * max(1.0, np.abs(theirs).max()))


def test_mtm_shoulder_and_elbow_model_refuses_bad_joints(mtm):
    with pytest.raises(RcmKinError, match="distinct actuated joints of mtm"):
        driven_dynamics(mtm, joints=("j1", "elbow"))
    with pytest.raises(RcmKinError, match="distinct actuated joints"):
        driven_dynamics(mtm, joints=("j1", "j1"))
    model = driven_dynamics(mtm, joints=("j2", "j3"))
    with pytest.raises(RcmKinError, match="4 values"):
        check_state(np.zeros(3), np.zeros(2), model)
    check_state(np.zeros(4), [400.0, -400.0], model)       # torque: no PWM range


# --- the UR5: plain Pinocchio computeABADerivatives on the same URDF --------------------------------------
@pytest.fixture(scope="module")
def ur5(tmp_path_factory):
    return rk.load_robot(write_ur5(tmp_path_factory.mktemp("ur5"))), ur5_urdf()


def test_ur5_linear_model_equals_pinocchio_aba_derivatives(ur5):
    robot, urdf = ur5
    plain = pin.buildModelFromUrdf(str(urdf))
    data = plain.createData()
    model = driven_dynamics(robot)
    rng = np.random.default_rng(12)
    Q = rng.uniform(-2.5, 2.5, (6, robot.nq))
    grid = linearize_grid(model, Q, compile=False)
    for k, q in enumerate(Q):
        lin = linearize(model, q)
        g = pin.computeGeneralizedGravity(plain, data, q)
        da_dq, da_dv, Minv = pin.computeABADerivatives(plain, data, q, np.zeros(6), g)
        Minv = np.triu(Minv) + np.triu(Minv, 1).T
        A = np.block([[np.zeros((6, 6)), np.eye(6)], [da_dq, da_dv]])
        B = np.vstack([np.zeros((6, 6)), Minv])
        np.testing.assert_allclose(lin.u0, g, rtol=0, atol=1e-9)
        for ours in (lin.A, grid.A[k]):
            np.testing.assert_allclose(ours, A, rtol=0, atol=1e-9 * max(1.0, np.abs(A).max()))
        for ours in (lin.B, grid.B[k]):
            np.testing.assert_allclose(ours, B, rtol=0, atol=1e-9 * max(1.0, np.abs(B).max()))
    # away from rest too: CasADi AD against the analytic derivatives through rcm_kin's Pinocchio path
    x, u = np.r_[Q[0], rng.normal(size=6)], rng.normal(size=6)
    A_pin, B_pin = linearize_pinocchio(robot, model, {}, x, u)
    A_ad, B_ad = (np.array(m) for m in model.jacobians(x, u))
    np.testing.assert_allclose(A_ad, A_pin, rtol=0, atol=1e-9 * max(1.0, np.abs(A_pin).max()))
    np.testing.assert_allclose(B_ad, B_pin, rtol=0, atol=1e-9)


def test_ur5_to_ss_labels_are_torques(ur5):
    pytest.importorskip("control")
    robot, _ = ur5
    sys = linearize(driven_dynamics(robot), np.zeros(6)).to_ss()
    assert sys.input_labels[0] == "shoulder_pan_joint torque [N m]"
    assert sys.state_labels[6] == "shoulder_pan_joint rate [rad/s]"
    assert sys.output_labels[1] == "shoulder_lift_joint [rad]"


# --- a renamed, re-massed PSM copy with its own drive file ------------------------------------------------
@pytest.fixture(scope="module")
def mypsm(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mypsm")
    sidecar, joints = write_mypsm(folder)
    return rk.load_robot(sidecar), folder, joints


def test_renamed_psm_copy_runs_on_its_own_physics_and_drive(mypsm, params):
    robot, folder, joints = mypsm
    model = driven_dynamics(robot)
    assert model.model_label == "calibration mypsm_drive.toml" and model.joints == ("roll", "pitch", "insertion")
    sidecar = tomllib.loads((folder / "mypsm.toml").read_text())
    plain, S = plain_tree(folder / "mypsm.urdf", sidecar)
    d = [joints[j] for j in model.joints]
    gain = np.array([x["pwm_sign"] * x["torque_constant"] * x["gear_ratio"] * x["volts_per_pwm"] / x["resistance"]
                     for x in d])
    inertia = np.array([x["rotor_inertia"] * x["gear_ratio"] ** 2 for x in d])
    damping = np.array([x["torque_constant"] ** 2 * x["gear_ratio"] ** 2 / x["resistance"] + x["viscous"]
                        + x["coulomb"] / x["coulomb_velocity"] for x in d])
    shipped = driven_dynamics(rk.load_robot("psm"))
    for q3 in ([0.1, -0.2, 0.08], [-0.3, 0.4, 0.12], [0.0, 0.0, 0.05]):
        q = np.r_[q3, np.zeros(4)]
        u0, A, B = plain_equilibrium_model(plain, S, q, [0, 1, 2], inertia, gain, damping)
        lin = linearize(model, q3)
        np.testing.assert_allclose(lin.u0, u0, rtol=0, atol=1e-9)
        np.testing.assert_allclose(lin.A, A, rtol=0, atol=1e-9 * max(1.0, np.abs(A).max()))
        np.testing.assert_allclose(lin.B, B, rtol=0, atol=1e-9 * max(1.0, np.abs(B).max()))
        # the shipped calibration (first moments, roll gear) is not in it: the PSM's holding PWM differs
        assert np.abs(linearize(shipped, q3).u0 - lin.u0).max() > 1.0
    with pytest.raises(RcmKinError, match="describes robot 'psm', not 'mypsm'"):
        driven_dynamics(robot, params)


# --- drive files over the joints they name ------------------------------------------------------------------
def test_a_drive_file_of_another_robot_uses_its_joints_and_pwm_limits(tmp_path, mtm):
    values = {k: 1.0 for k in DRIVE_KEYS} | {"coulomb": 0.0, "viscous": 0.0, "rotor_inertia": 1e-6}
    path = tmp_path / "mtm_drive.toml"
    path.write_text(drive_text("mtm", {"j2": values, "j3": values | {"pwm_sign": -1.0}}, limit=200.0))
    params = load_drive_parameters(path)
    assert params.driven == ("j2", "j3") and params["j3"].pwm_limit == 200.0
    effort = drive_effort(params, np.array([[1.0, 2.0]]))
    assert effort.pwm.shape == (1, 2)
    np.testing.assert_allclose(pwm_to_torque(params, effort.pwm), [[1.0, 2.0]], rtol=1e-12)
    model = driven_dynamics(mtm, params)
    assert model.joints == ("j2", "j3") and model.pwm_input and model.model_label == "calibration mtm_drive.toml"
    u0 = linearize(model, [0.3, -0.4]).u0
    g = driven_dynamics(mtm, joints=("j2", "j3")).gravity([0.3, -0.4])
    np.testing.assert_allclose(pwm_to_torque(params, u0), np.array(g).ravel(), rtol=1e-12)
    path.write_text(path.read_text().replace("pwm_limit = 200.0\n", "", 1))
    with pytest.raises(RcmKinError, match=r"\[j2\] needs pwm_limit \(") as missing:   # the missing key only
        load_drive_parameters(path)
    assert "gear_ratio" not in str(missing.value)


@pytest.mark.parametrize("edit, message", [
    (("[j3]", "[elbow]"), "joints elbow are not actuated joints of mtm"),
    (('robot = "mtm"', 'robot = "ur5"'), "describes robot 'ur5', not 'mtm'"),
])
def test_a_drive_file_naming_a_missing_joint_or_another_robot_is_refused(tmp_path, mtm, edit, message):
    values = {k: 1.0 for k in DRIVE_KEYS}
    path = tmp_path / "drive.toml"
    path.write_text(drive_text("mtm", {"j2": values, "j3": values}).replace(*edit))
    with pytest.raises(RcmKinError, match=message):
        driven_dynamics(mtm, load_drive_parameters(path))


def test_drive_train_must_name_a_joint_of_the_file(tmp_path):
    values = {k: 1.0 for k in DRIVE_KEYS}
    path = tmp_path / "drive.toml"
    path.write_text(drive_text("mtm", {"j2": values}) + "[drive_train.j3]\nviscous = 1.0\n")
    with pytest.raises(RcmKinError, match=r"\[drive_train.j3\] is not a joint of the file \(j2\)"):
        load_drive_parameters(path)


def test_massless_urdf_is_refused(tmp_path):
    text = (urdf_dir() / "mtm.urdf").read_text()
    (tmp_path / "bare.urdf").write_text(re.sub(r"<inertial>.*?</inertial>", "", text, flags=re.S))
    sidecar = (urdf_dir() / "mtm.toml").read_text().replace('robot = "mtm"', 'robot = "bare"')
    (tmp_path / "bare.toml").write_text(sidecar.replace('urdf = "mtm.urdf"', 'urdf = "bare.urdf"'))
    with pytest.raises(RcmKinError, match="needs masses: links"):
        driven_dynamics(rk.load_robot(tmp_path / "bare.toml"))


@pytest.mark.parametrize("coulomb", [True, False])
def test_rest_form_equals_ad_on_every_model(psm, params, mtm, coulomb):
    """linearize_grid's closed form at rest and CasADi's AD give the same (A, B, u0), with a drive
    (the PSM, Coulomb slope included) and without (the MTM)."""
    rng = np.random.default_rng(13)
    for model in (driven_dynamics(psm, params, coulomb=coulomb), driven_dynamics(mtm, coulomb=coulomb)):
        Q = rng.uniform(model.lower, model.upper, (9, len(model.joints))) * 0.9
        ad, rest = (linearize_grid(model, Q, compile=False, method=m) for m in ("ad", "rest"))
        np.testing.assert_allclose(rest.u0, ad.u0, rtol=0, atol=1e-12 * max(1.0, np.abs(ad.u0).max()))
        np.testing.assert_allclose(rest.A, ad.A, rtol=0, atol=1e-10 * max(1.0, np.abs(ad.A).max()))
        np.testing.assert_allclose(rest.B, ad.B, rtol=0, atol=1e-10 * max(1.0, np.abs(ad.B).max()))
    with pytest.raises(RcmKinError, match="'ad' or 'rest'"):
        linearize_grid(model, Q, method="fd")


def test_drive_file_of_another_robot_round_trips_with_its_pwm_limits(tmp_path):
    from rcm_kin.dynamics.drive import write_parameters

    values = {k: 1.0 for k in DRIVE_KEYS}
    (tmp_path / "a.toml").write_text(drive_text("arm", {"shoulder": values, "elbow": values}, limit=180.0))
    params = load_drive_parameters(tmp_path / "a.toml")
    again = load_drive_parameters(write_parameters(params, tmp_path / "b.toml"))
    assert again.joints == params.joints and again.driven == ("shoulder", "elbow") and again.robot == "arm"
    assert "pwm_limit = 180.0" in (tmp_path / "b.toml").read_text()

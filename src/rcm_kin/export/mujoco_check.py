"""The exported MJCF run in MuJoCo beside our own closed-chain dynamics (needs the ``[mujoco]`` extra).

- :func:`model_text`: the model an exported file holds (its ``<custom>`` text);
- :func:`allowed_acceleration`: MuJoCo's acceleration along the motions its loops allow (does a
  set of torques hold the arm?);
- :func:`hold_speeds`: MuJoCo from rest at a keyframe under constant motor controls; the largest
  speed of each joint (rad/s, m/s);
- :func:`mujoco_swing` and :func:`closed_chain_swing`: a motion from rest without motor torque
  in MuJoCo and in our reduced model (mimic joints: Pinocchio's RNEA and CRBA), plus the drives'
  armature and viscous damping, ``(M(q) + diag(armature)) a = -rnea(q, v, 0) - damping v``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp
from scipy.linalg import null_space

from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.export.mjcf import MODEL_TEXT
from rcm_kin.model.reduced import reduced_mass_matrix

if TYPE_CHECKING:
    from rcm_kin.model import Robot


def at_keyframe(model, key: str, ctrl=None):
    """MuJoCo data reset to keyframe ``key`` (its ctrl replaced by ``ctrl`` when given), forwarded."""
    import mujoco

    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, model.key(key).id)
    if ctrl is not None:
        data.ctrl[:] = ctrl
    mujoco.mj_forward(model, data)
    return data


def model_text(model, name: str = MODEL_TEXT) -> str:
    """The ``<custom><text name=name>`` of a MuJoCo model: for an rcm-kin export, the model it holds."""
    import mujoco

    i = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_TEXT, name)
    if i < 0:
        return ""
    start = model.text_adr[i]
    return bytes(model.text_data[start:start + model.text_size[i] - 1]).decode()


def allowed_acceleration(model, data) -> np.ndarray:
    """The part of ``data.qacc`` (after ``mj_forward``) along the motions the equality constraints
    allow: its M-orthogonal projection onto the null space N of their Jacobian J, ``N (N'MN)^-1 N'M
    qacc`` (nv,), rad/s^2 or m/s^2. MuJoCo's soft constraints leave an acceleration error
    ``M^-1 J' df`` (df: the regularised force's shortfall); N'M of it is N'J' df = 0, so this part is
    the acceleration of the exactly closed chain, ``N (N'MN)^-1 N' qfrc_smooth``, whatever the
    constraints' softness. No equality constraint: qacc itself."""
    import mujoco

    mass, column = np.zeros((model.nv, model.nv)), np.zeros(model.nv)
    for i, unit in enumerate(np.eye(model.nv)):      # mj_mulM: one signature in MuJoCo 3 and 4
        mujoco.mj_mulM(model, data, column, unit)
        mass[:, i] = column
    rows = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    if not np.any(rows):
        return data.qacc.copy()
    if mujoco.mj_isSparse(model):
        jac = np.zeros((data.nefc, model.nv))
        mujoco.mju_sparse2dense(jac, data.efc_J, data.efc_J_rownnz, data.efc_J_rowadr, data.efc_J_colind)
    else:
        jac = data.efc_J.reshape(data.nefc, model.nv)
    basis = null_space(jac[rows])
    return basis @ np.linalg.solve(basis.T @ mass @ basis, basis.T @ mass @ data.qacc)


def actuated_q(model, data, robot: Robot) -> np.ndarray:
    """MuJoCo's positions of ``robot``'s actuated joints, actuated order (rad, m)."""
    return np.array([data.qpos[model.joint(name).qposadr[0]] for name in robot.actuated])


def hold_speeds(model, data, seconds: float) -> dict[str, float]:
    """Step ``data`` for ``seconds``; the largest |speed| of every joint on the way (rad/s, m/s)."""
    import mujoco

    speed = np.zeros(model.nv)
    for _ in range(round(seconds / model.opt.timestep)):
        mujoco.mj_step(model, data)
        speed = np.maximum(speed, np.abs(data.qvel))
    return {model.joint(j).name: float(speed[model.joint(j).dofadr[0]]) for j in range(model.njnt)}


def mujoco_swing(model, data, robot: Robot, times: np.ndarray) -> np.ndarray:
    """Actuated positions (len(times), nq) while MuJoCo steps ``data`` from times[0]; ``times`` must
    be multiples of the model's step."""
    import mujoco

    out = [actuated_q(model, data, robot)]
    for dt in np.diff(times):
        for _ in range(round(dt / model.opt.timestep)):
            mujoco.mj_step(model, data)
        out.append(actuated_q(model, data, robot))
    return np.array(out)


def drive_terms(robot: Robot, params: DriveParameters | None) -> tuple[np.ndarray, np.ndarray]:
    """Armature (reflected drive inertia, kg m^2 or kg) and viscous damping (N m s/rad, N s/m) per
    actuated joint: the driven joints of ``params``, 0 elsewhere (everywhere for None, a CAD export)."""
    armature, damping = np.zeros(robot.nq), np.zeros(robot.nq)
    for joint in () if params is None else params.driven:
        i = robot.actuated.index(joint)
        armature[i], damping[i] = params[joint].reflected_inertia, params[joint].viscous
    return armature, damping


def closed_chain_swing(robot: Robot, q0: np.ndarray, times: np.ndarray, armature: np.ndarray,
                       damping: np.ndarray) -> np.ndarray:
    """Our free motion from rest at actuated ``q0``, sampled at ``times`` (len(times), nq); DOP853
    at relative tolerance 1e-10."""
    def xdot(_, x):
        q, v = x[:robot.nq], x[robot.nq:]
        bias = robot.from_reduced(pin.rnea(robot.reduced, robot.reduced_data, robot.to_reduced(q),
                                           robot.to_reduced(v), np.zeros(robot.reduced.nv)))
        return np.concatenate([v, np.linalg.solve(reduced_mass_matrix(robot, q) + np.diag(armature),
                                                  -bias - damping * v)])
    solution = solve_ivp(xdot, (times[0], times[-1]), np.concatenate([q0, np.zeros(robot.nq)]), t_eval=times,
                         method="DOP853", rtol=1e-10, atol=1e-12)
    return solution.y[:robot.nq].T

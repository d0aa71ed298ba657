"""Grey-box fit: the drive parameters the CAD cannot give, from open-loop step logs.

Per step log of one joint (the others held by their controllers at their measured angles),
the physics model of that joint alone is simulated against the measured angle:

    (M_ii(q) + J) qdd = k_u (u_hold(q0) + du) - (d_i + b) qd - F_c tanh(qd / v_c) - g_i(q)

from rest at the log's angle ``q0``, with ``du`` the measured PWM step. ``M_ii``, ``g_i``,
``k_u`` and ``d_i`` (back-EMF) are the model's; starting from the model's own holding PWM
``u_hold(q0)`` keeps the static calibration out of the dynamic fit. The unknowns, shared by
all logs, are the extra inertia ``J`` (kg m^2, beyond the CAD and the rotor), the viscous
friction ``b`` (N m s/rad) and the Coulomb law's smoothing width ``v_c`` (rad/s, at least
0.002: a narrower law sticks better but makes the ODE stiffer); the Coulomb friction ``F_c``
(N m) is fitted per log. RK4 (:func:`rcm_kin.symbolic.integrators.rk4_map`) with steps of at
most 0.5 ms is unrolled in CasADi over each record, so the residual's Jacobian is exact (AD),
and ``scipy.optimize.least_squares`` solves the bounded problem. The insertion is held at the
home insertion (:data:`rcm_kin.hardware.HOME_INSERTION`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np
from scipy.optimize import least_squares
from tqdm import tqdm

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters, with_joint, write_parameters
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.identification.records import Record, step_record
from rcm_kin.identification.telemetry import load_telemetry
from rcm_kin.identification.transfer_function import fit_percent
from rcm_kin.model import load_robot
from rcm_kin.symbolic.integrators import rk4_map

PARAMETERS = ("extra_inertia", "viscous", "coulomb", "coulomb_velocity")
LOWER = np.array([0.0, 0.0, 0.0, 0.002])
UPPER = np.array([2.0, 10.0, 5.0, 0.05])
NEUTRAL_WIDTH = 0.02       # rad/s: Coulomb width of the neutral start
MAX_STEP = 5e-4             # s: RK4 step bound (the friction's slope F_c / v_c makes the ODE stiff)


@dataclass(frozen=True)
class StepLog:
    name: str
    record: Record
    held: np.ndarray        # (3,) the driven joints' angles (rad, rad, m) the step started from


@dataclass(frozen=True)
class GreyBoxFit:
    joint: str
    names: tuple[str, ...]              # PARAMETERS
    before: np.ndarray                  # parameter values of the starting set
    after: np.ndarray                   # fitted values
    logs: tuple[str, ...]
    coulomb_per_log: np.ndarray         # N m, each log's own Coulomb friction
    fit_before: np.ndarray              # fit percentage per log, starting set
    fit_after: np.ndarray               # fit percentage per log, fitted set (median Coulomb)
    fit_per_log_friction: np.ndarray    # fit percentage per log with its own Coulomb
    params: DriveParameters             # the starting set with the fitted values
    responses: tuple[dict, ...]         # per log: time, measured, starting set, fitted set, own Coulomb (deg)

    def as_dict(self) -> dict:
        per_log = lambda values: dict(zip(self.logs, np.asarray(values).tolist()))  # noqa: E731
        return {"joint": self.joint,
                "before": dict(zip(self.names, self.before.tolist())),
                "after": dict(zip(self.names, self.after.tolist())),
                "coulomb_per_log": per_log(self.coulomb_per_log),
                "fit_percent_before": per_log(self.fit_before),
                "fit_percent_after": per_log(self.fit_after),
                "fit_percent_per_log_friction": per_log(self.fit_per_log_friction)}


def step_logs(paths, joint: str, samples: int = 1000) -> list[StepLog]:
    """Trimmed step records with the pose they started from (other joints: their mean measured
    angle over the record; the insertion: the home insertion, the logs' insertion column being
    unusable, a wrong conversion)."""
    out = []
    for path in paths:
        log = load_telemetry(path)
        record = step_record(log, joint, samples)
        held = np.array([0.0, 0.0, HOME_INSERTION])
        for k, other in enumerate(("roll", "pitch")):
            if other in log.position:
                held[k] = np.radians(np.mean(log.position[other]))
        held[DRIVEN.index(joint)] = np.radians(record.y0)
        out.append(StepLog(Path(path).name, record, held))
    if not out:
        raise RcmKinError("the grey-box fit needs at least one step log")
    return out


def _residual_function(params: DriveParameters, joint: str, log: StepLog) -> ca.Function:
    """``theta -> (residual (N,) deg, d residual / d theta)`` of one log."""
    i = DRIVEN.index(joint)
    base = driven_dynamics(load_robot("psm"), with_joint(params, joint, extra_inertia=0.0, viscous=0.0), coulomb=False)
    d = base.drive
    q, v, u = ca.SX.sym("q"), ca.SX.sym("v"), ca.SX.sym("u")
    theta = ca.SX.sym("theta", len(PARAMETERS))
    pose = ca.SX(ca.DM(log.held))
    pose[i] = q
    u_hold = holding_pwm(base, log.held, allow_outside_limits=True)[i]   # a log may rest on a stop
    tau = (d.input_gain[i] * (u_hold + u) - (d.damping[i] + theta[1]) * v
           - theta[2] * ca.tanh(v / theta[3]) - base.gravity(pose)[i])
    xdot = ca.vertcat(v, tau / (base.mass_matrix(pose)[i, i] + theta[0]))
    f = ca.Function("f", [ca.vertcat(q, v), u, theta], [xdot], ["x", "u", "theta"], ["xdot"])
    n = log.record.u.size
    run = rk4_map(f, log.record.period, int(np.ceil(log.record.period / MAX_STEP)), "step").mapaccum(n)
    p = ca.MX.sym("theta", len(PARAMETERS))
    q0 = log.held[i]
    states = run(ca.DM([q0, 0.0]), ca.DM(log.record.u).T, ca.repmat(p, 1, n))
    # the state after sample k-1's hold is the angle at sample k; sample 0 is the start
    y = ca.vertcat(0.0, (states[0, :-1].T - q0) * np.degrees(1.0))   # rad -> deg
    r = y - ca.DM(log.record.y)
    return ca.Function("residual", [p], [r, ca.jacobian(r, p)])


def fit_greybox(params: DriveParameters, joint: str, logs: list[StepLog], progress: bool = False) -> GreyBoxFit:
    """Fit the extra inertia, viscous friction and Coulomb width of ``joint`` shared by all step
    logs, with a Coulomb friction per log (it varies with the pose: the steps are barely larger
    than the friction, so a few per cent of it decide how far each one moves). The fitted set
    takes the median Coulomb; ``fit_after`` is that set's fit, ``fit_per_log_friction`` the
    fit with each log's own value. ``progress``: a bar (stderr) counting the simulations of the
    logs (the least-squares iterations have no known total)."""
    if joint not in ("roll", "pitch"):
        raise RcmKinError(f"the grey-box fit is for the roll or the pitch, not '{joint}'")
    functions = [_residual_function(params, joint, log) for log in logs]
    n = len(logs)
    start_set = np.clip([getattr(params[joint], name) for name in PARAMETERS], LOWER, UPPER)
    shared = [0, 1, 3]                                    # extra inertia, viscous, width

    def theta_of(z, k):                                   # z = [shared (3), coulomb per log (n)]
        return np.array([z[0], z[1], z[3 + k], z[2]])

    cache: dict[bytes, list] = {}

    def evaluate(z):
        key = np.asarray(z, dtype=float).tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = [(np.array(r).ravel(), np.array(j)) for r, j in (f(theta_of(z, k))
                                                                          for k, f in enumerate(functions))]
        return cache[key]

    def jacobian(z):
        rows = []
        for k, (_, j) in enumerate(evaluate(z)):
            block = np.zeros((j.shape[0], 3 + n))
            block[:, :3] = j[:, shared]
            block[:, 3 + k] = j[:, 2]
            rows.append(block)
        return np.vstack(rows)

    lower = np.r_[LOWER[shared], np.full(n, LOWER[2])]
    upper = np.r_[UPPER[shared], np.full(n, UPPER[2])]
    # friction makes local minima: start from the given set and from a neutral one (no extra
    # inertia or viscous friction, a wide Coulomb law), keep the better
    starts = [start_set, np.array([0.0, 0.0, start_set[2], NEUTRAL_WIDTH])]
    with tqdm(desc="greybox", unit="simulation", disable=not progress) as bar:
        def residual(z):
            bar.update(n)
            return np.concatenate([r for r, _ in evaluate(z)])

        solutions = [least_squares(residual, np.clip(np.r_[s[shared], np.full(n, s[2])], lower, upper), jac=jacobian,
                                   bounds=(lower, upper), x_scale="jac") for s in starts]
    z = min(solutions, key=lambda sol: sol.cost).x
    per_log = z[3:]
    fitted = np.array([z[0], z[1], float(np.median(per_log)), z[2]])

    def simulated(theta_for):
        return [log.record.y + np.array(f(theta_for(k))[0]).ravel() for k, (log, f) in enumerate(zip(logs, functions))]

    runs = {"starting": simulated(lambda k: start_set), "fitted": simulated(lambda k: fitted),
            "own_coulomb": simulated(lambda k: theta_of(z, k))}
    fits = {key: np.array([fit_percent(log.record.y, y) for log, y in zip(logs, ys)]) for key, ys in runs.items()}
    responses = tuple({"time": np.arange(log.record.y.size) * log.record.period, "measured": log.record.y,
                       **{key: ys[k] for key, ys in runs.items()}} for k, log in enumerate(logs))
    return GreyBoxFit(joint, PARAMETERS, start_set, fitted, tuple(log.name for log in logs), per_log,
                      fits["starting"], fits["fitted"], fits["own_coulomb"],
                      with_joint(params, joint, **dict(zip(PARAMETERS, map(float, fitted)))), responses)


def write_greybox_parameters(fit: GreyBoxFit, path: str | Path) -> Path:
    """The fitted set as a drive parameter file, with the before/after fits in its header."""
    lines = [f"GREY-BOX FIT of the {fit.joint} (rcm-kin greybox) on {len(fit.logs)} step logs:"]
    lines += [f"  {n}: {b:.6g} -> {a:.6g}" for n, b, a in zip(fit.names, fit.before, fit.after)]
    lines += ["  (coulomb: the median of the per-log values; fit with the starting set -> this set -> each log's own)"]
    lines += [f"  {name}: coulomb {c:.4g} N m; fit {b:.1f} % -> {a:.1f} % -> {p:.1f} %" for name, c, b, a, p in
              zip(fit.logs, fit.coulomb_per_log, fit.fit_before, fit.fit_after, fit.fit_per_log_friction)]
    lines += ["Other values as in the starting set " + Path(fit.params.source).name + "."]
    return write_parameters(fit.params, path, "\n".join(lines))

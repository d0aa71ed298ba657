"""One joint's excitation problem: its identification regressor, its limits, and the search for
the Fourier coefficients that condition the regressor best (the method is described in
:mod:`rcm_kin.identification.excitation`). Angles in rad, torques in N m, PWM in counts."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from rcm_kin.dynamics.drive import DRIVEN, DriveParameters
from rcm_kin.dynamics.stick_slip import axis_plant
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import PWM_LIMIT
from rcm_kin.identification.fourier import Fourier, basis
from rcm_kin.identification.replay import HOLD_POSE

PARAMETERS = ("inertia", "damping", "coulomb", "gravity_sin", "gravity_cos")   # theta
JOINT_MARGIN = np.radians(5.0)       # rad inside the URDF limits
VELOCITY_LIMIT = np.radians(60.0)    # rad/s
PWM_FRACTION = 0.8                   # of the firmware's PWM_LIMIT for the feedforward
EQUATION_NOISE = 1.0                 # PWM counts RMS: assumed error of the torque equation
NOISE_BANDWIDTH = 10.0               # Hz: derivative filter; its noise is independent every 1/(2 x 10) s
STARTS = 6                           # random starts per joint
MAX_ITERATIONS = 150                 # SLSQP's, per start
KS_SHARPNESS = 200.0                 # of the limits' smooth envelope (fractions of the limits)
GRID = 256                           # optimisation samples per period (at least 16 per harmonic)


def regressor(q, qd, qdd, coulomb_velocity: float) -> np.ndarray:
    """``Y`` (n, 5): ``k_u u = Y theta`` with ``theta`` as :data:`PARAMETERS` (the Coulomb law
    smoothed as the shipped model smooths it, ``tanh(qd / coulomb_velocity)``)."""
    return np.c_[qdd, qd, np.tanh(qd / coulomb_velocity), np.sin(q), np.cos(q)]


@dataclass(frozen=True)
class AxisModel:
    """The rigid body with smooth friction along one joint, the others held at :data:`HOLD_POSE`."""

    joint: str
    input_gain: float            # k_u, N m per count (hardware sign)
    theta: np.ndarray            # (J, D, F_c, A, B) shipped, SI
    coulomb_velocity: float      # rad/s: the Coulomb law's smoothing, F_c tanh(qd / v_c)
    grid: np.ndarray             # rad
    gravity: np.ndarray          # N m over the grid (the rigid body's, calibrated offsets included)
    inertia: np.ndarray          # kg m^2 over the grid: link, reflected rotor and extra
    lower: float                 # rad: the allowed range (URDF less the margin)
    upper: float
    pwm_limit: float             # counts allowed to the feedforward

    def regressor(self, q, qd, qdd) -> np.ndarray:
        return regressor(q, qd, qdd, self.coulomb_velocity)

    def pwm(self, q, qd, qdd) -> np.ndarray:
        """The feedforward (counts) that makes the model follow ``q`` (rad), ``qd``, ``qdd``."""
        D, Fc = self.theta[1:3]
        torque = np.interp(q, self.grid, self.inertia) * qdd + D * qd + Fc * np.tanh(qd / self.coulomb_velocity)
        return (torque + np.interp(q, self.grid, self.gravity)) / self.input_gain

    def condition_number(self, q, qd, qdd) -> float:
        """Of ``Y diag(theta)`` (see the module notes)."""
        s = np.linalg.svd(self.regressor(q, qd, qdd) * self.theta, compute_uv=False)
        return float(s[0] / s[-1]) if s[-1] > 0 else float("inf")

    def standard_errors(self, q, qd, qdd, duration: float) -> dict[str, float]:
        """Of ``theta`` (SI) with the assumed equation error, the samples ``q``... spanning ``duration`` s."""
        Y = self.regressor(q, qd, qdd)
        independent = max(duration * 2 * NOISE_BANDWIDTH, 1.0)
        s = abs(self.input_gain) * EQUATION_NOISE
        cov = s**2 * np.linalg.pinv(Y.T @ Y) * (Y.shape[0] / independent)
        return dict(zip(PARAMETERS, map(float, np.sqrt(np.clip(np.diag(cov), 0.0, None)))))

    def violation(self, q, qd, pwm) -> float:
        """How far (as a fraction of the limit) the worst sample is beyond the limits; <= 0 within them."""
        return float(max(np.max((q - self.upper) / self.upper), np.max((self.lower - q) / -self.lower),
                         np.max(np.abs(qd)) / VELOCITY_LIMIT - 1, np.max(np.abs(pwm)) / self.pwm_limit - 1))


def axis_model(model, params: DriveParameters, joint: str) -> AxisModel:
    """The :class:`AxisModel` of ``joint`` from the rigid-body ``model`` (built without identified
    extras, :func:`rcm_kin.identification.identify.base_model`) and the shipped smooth friction."""
    i = DRIVEN.index(joint)
    plant = axis_plant(model, joint, HOLD_POSE)
    drive = params[joint]
    inertia = plant.inertia + plant.rotor_inertia + drive.extra_inertia
    gravity_fit = np.linalg.lstsq(np.c_[np.sin(plant.grid), np.cos(plant.grid)], plant.gravity, rcond=None)[0]
    theta = np.r_[np.mean(inertia), plant.back_emf + drive.viscous, drive.coulomb, gravity_fit]
    if np.any(np.abs(theta) < 1e-9):   # the regressor is scaled by them
        zero = [n for n, v in zip(PARAMETERS, theta) if abs(v) < 1e-9]
        raise RcmKinError(f"the {joint}'s {', '.join(zero)} is 0 in the drive parameters: the design weighs each "
                          "term by its value (give a nominal one)")
    return AxisModel(joint, plant.input_gain, theta, drive.coulomb_velocity, plant.grid, plant.gravity, inertia,
                     float(model.lower[i] + JOINT_MARGIN), float(model.upper[i] - JOINT_MARGIN),
                     float(PWM_FRACTION * PWM_LIMIT[i]))


def _sech2(x):
    """``1 / cosh(x)^2`` without overflow."""
    e = np.exp(-2.0 * np.abs(x))
    return 4.0 * e / (1.0 + e) ** 2


class _Problem:
    """The optimisation of one axis on ``samples`` points of a period: log condition number
    (with its analytic gradient), the limits as inequalities (with their Jacobian), the start at
    rest as equalities."""

    def __init__(self, axis: AxisModel, period: float, harmonics: int, samples: int):
        self.axis = axis
        self.P = basis(period, harmonics, np.arange(samples) * period / samples)
        self.slope = np.gradient(axis.gravity, axis.grid)
        k = np.arange(1, harmonics + 1, dtype=float)
        self.equal = np.zeros((2, 2 * harmonics))
        self.equal[0, :harmonics], self.equal[1, harmonics:] = 1.0, k
        self._envelope = {}

    def motion(self, x):
        return tuple(P @ x for P in self.P)

    def objective(self, x) -> tuple[float, np.ndarray]:
        q, qd, qdd = self.motion(x)
        a = self.axis
        U, s, Vt = np.linalg.svd(a.regressor(q, qd, qdd) * a.theta, full_matrices=False)
        if not s[-1] > 1e-12 * s[0]:
            return 50.0, np.zeros(x.size)
        # d log(s_max / s_min) = u1' dW v1 / s1 - un' dW vn / sn, W's columns as functions of x
        G = np.outer(U[:, 0], a.theta * Vt[0]) / s[0] - np.outer(U[:, -1], a.theta * Vt[-1]) / s[-1]
        Pq, Pd, Pdd = self.P
        smooth = _sech2(qd / a.coulomb_velocity) / a.coulomb_velocity
        grad = (Pdd.T @ G[:, 0] + Pd.T @ (G[:, 1] + G[:, 2] * smooth)
                + Pq.T @ (G[:, 3] * np.cos(q) - G[:, 4] * np.sin(q)))
        return float(np.log(s[0] / s[-1])), grad

    def margins(self, x) -> tuple[np.ndarray, np.ndarray]:
        """Every sample's excess over each limit as a fraction of it (<= 0 inside), and its Jacobian."""
        q, qd, qdd = self.motion(x)
        a = self.axis
        Pq, Pd, Pdd = self.P
        u = a.pwm(q, qd, qdd)
        damping = a.theta[1] + a.theta[2] * _sech2(qd / a.coulomb_velocity) / a.coulomb_velocity
        du = (np.interp(q, a.grid, a.inertia)[:, None] * Pdd + damping[:, None] * Pd
              + np.interp(q, a.grid, self.slope)[:, None] * Pq) / a.input_gain
        values = np.concatenate([q / a.upper - 1, q / a.lower - 1, qd / VELOCITY_LIMIT - 1, -qd / VELOCITY_LIMIT - 1,
                                 u / a.pwm_limit - 1, -u / a.pwm_limit - 1])
        jacobian = np.concatenate([Pq / a.upper, Pq / a.lower, Pd / VELOCITY_LIMIT, -Pd / VELOCITY_LIMIT,
                                   du / a.pwm_limit, -du / a.pwm_limit])
        return values, jacobian

    def inequality(self, x) -> tuple[float, np.ndarray]:
        """``-KS(margins)``, >= 0 only inside every limit: the Kreisselmeier-Steinhauser envelope
        ``max + log(sum exp(rho (m - max))) / rho`` of all the margins, one smooth constraint
        instead of one per sample (above the largest margin by at most ``log(n) / rho``)."""
        key = x.tobytes()
        if key not in self._envelope:   # SLSQP asks for the value and the gradient separately
            values, jacobian = self.margins(x)
            top = np.max(values)
            weights = np.exp(KS_SHARPNESS * (values - top))
            total = np.sum(weights)
            self._envelope = {key: (-(top + np.log(total) / KS_SHARPNESS), -(weights / total) @ jacobian)}
        return self._envelope[key]

    def start(self, rng: np.random.Generator) -> np.ndarray:
        """A random feasible point: coefficients falling as 1/k, at rest at t = 0, shrunk into the limits."""
        n = self.equal.shape[1] // 2
        k = np.arange(1, n + 1)
        x = rng.normal(size=2 * n) / np.r_[k, k]
        x -= np.linalg.pinv(self.equal) @ (self.equal @ x)
        x *= 0.5 * VELOCITY_LIMIT / max(np.max(np.abs(self.P[1] @ x)), 1e-12)
        while self.inequality(x)[0] < 0:
            x *= 0.7
        return x


def optimise_axis(axis: AxisModel, period: float, harmonics: int, rng: np.random.Generator,
                  starts: int = STARTS, progress=None) -> Fourier:
    """The Fourier coefficients of least condition number within the limits (SLSQP from
    ``starts`` random feasible starts; ``progress()`` after each)."""
    problem = _Problem(axis, period, harmonics, max(GRID, 16 * harmonics))
    constraints = [{"type": "eq", "fun": lambda x: problem.equal @ x, "jac": lambda x: problem.equal},
                   {"type": "ineq", "fun": lambda x: problem.inequality(x)[0],
                    "jac": lambda x: problem.inequality(x)[1]}]
    best, best_value = None, np.inf
    for _ in range(starts):
        x0 = problem.start(rng)
        found = minimize(problem.objective, x0, jac=True, method="SLSQP", constraints=constraints,
                         options={"maxiter": MAX_ITERATIONS, "ftol": 1e-10})
        for x in (found.x, x0):   # the start if the search ended outside the limits
            value = problem.objective(x)[0]
            feasible = problem.inequality(x)[0] >= -1e-9 and np.max(np.abs(problem.equal @ x)) < 1e-9
            if feasible and value < best_value:
                best, best_value = x, value
        if progress:
            progress()
    return Fourier(period, best[:harmonics].copy(), best[harmonics:].copy())

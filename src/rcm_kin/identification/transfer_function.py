"""Continuous-time transfer-function fits of sampled input/output data (MATLAB ``tfest`` style).

``G(s) = (b_m s^m + ... + b_0) / (s^n + a_{n-1} s^{n-1} + ... + a_0)`` is fitted to a uniformly
sampled record with the input held between samples (the firmware's PWM is):

1. a start by the state-variable-filter least squares (Young's SVF: ``u`` and ``y`` filtered by
   ``1 / (s + lam)^n`` give their derivatives, in which the model is linear), for a few ``lam``;
2. output-error refinement with ``scipy.optimize.least_squares``: simulate ``G`` exactly (ZOH
   discretisation, ``scipy.signal.lfilter``) and minimise the output residual.

A record that starts at rest (a trimmed step) is simulated whole from rest. A record that does
not (closed-loop PRBS about a pose, where the plant may be unstable on its own) is cut into
segments of ``segment`` samples, each simulated from its own initial state; the states enter
the output linearly and are eliminated by least squares inside the residual (variable
projection), so the fit is a multiple-shooting output error with that horizon.

The fit percentage is MATLAB's ``100 (1 - |y - y_hat| / |y - mean(y)|)`` (NRMSE), of the
simulated output (per segment, from its estimated initial state).

:meth:`TransferFunctionFit.to_tf` hands a fit to python-control, which gives its poles and DC gain.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import control
import numpy as np
from scipy import signal
from scipy.optimize import least_squares

from rcm_kin.control.linearization import zero_order_hold
from rcm_kin.errors import RcmKinError


@dataclass(frozen=True)
class TransferFunctionFit:
    """A fitted ``num(s) / den(s)`` (descending powers, ``den`` monic) and how well it fits."""

    num: np.ndarray
    den: np.ndarray
    fit_percent: float
    period: float               # s, the record's sample period
    segment: int | None         # samples per simulated segment (None: whole record from rest)
    y_fit: np.ndarray           # simulated output on the record (trailing partial segment dropped)

    def to_tf(self, input: str = "PWM [counts]", output: str = "angle [deg]") -> control.TransferFunction:
        """The fit as a continuous-time python-control ``TransferFunction`` (time in s), its
        signals named ``input`` and ``output`` (by default the units of the identification records)."""
        return control.tf(self.num, self.den, inputs=input, outputs=output)

    @property
    def poles(self) -> np.ndarray:
        """Poles (1/s)."""
        return self.to_tf().poles()

    @property
    def dc_gain(self) -> float:
        """``G(0)`` (output per input unit); infinite for a model with an integrator."""
        return dc_gain(self.to_tf())

    def state_space(self) -> tuple[np.ndarray, ...]:
        """``(A, B, C, D)`` in controller canonical form (MATLAB's ``ss(tf)`` up to scaling)."""
        return signal.tf2ss(self.num, self.den)

    def as_dict(self) -> dict:
        A, B, C, D = self.state_space()
        return {"num": self.num.tolist(), "den": self.den.tolist(), "fit_percent": self.fit_percent,
                "A": A.tolist(), "B": B.tolist(), "C": C.tolist(), "D": D.tolist(),
                "poles": [[p.real, p.imag] for p in self.poles], "dc_gain": self.dc_gain,
                "period_s": self.period, "segment_samples": self.segment}


def dc_gain(G: control.TransferFunction) -> float:
    """``G(0)`` of a SISO continuous-time transfer function; ``inf`` for one with an integrator."""
    gain = complex(G.dcgain())
    return gain.real if np.isfinite(gain) else float("inf")


def fit_percent(y: np.ndarray, y_hat: np.ndarray) -> float:
    """MATLAB's fit percentage (NRMSE): 100 for a perfect fit, 0 for the mean, negative below."""
    spread = np.linalg.norm(y - np.mean(y))
    if spread == 0:
        raise RcmKinError("the output is constant: nothing to fit")
    return float(100.0 * (1.0 - np.linalg.norm(y - y_hat) / spread))


def polynomial_text(coefficients, variable: str = "s") -> str:
    """``[a, b, c]`` (descending powers) as ``a s^2 + b s + c``, five significant digits."""
    n = len(coefficients) - 1
    text = ""
    for k, c in enumerate(coefficients):
        power = f" {variable}^{n - k}" if n - k > 1 else f" {variable}" if n - k == 1 else ""
        text += (f"{'-' if c < 0 else ''}{abs(c):.5g}" if k == 0 else f" {'-' if c < 0 else '+'} {abs(c):.5g}") + power
    return text


def _discrete(num, den, period: float):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", signal.BadCoefficients)
        A, B, C, D = signal.tf2ss(num, den)
    Ad, Bd = zero_order_hold(A, B, period)
    return Ad, Bd, C, D


def _forced_response(Ad, Bd, Cd, Dd, u: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():                  # leading numerator zeros of a strictly proper model
        warnings.simplefilter("ignore", signal.BadCoefficients)
        num_d, den_d = signal.ss2tf(Ad, Bd, Cd, Dd)
    return signal.lfilter(num_d[0], den_d, u, axis=-1)


def _free_responses(Ad, Cd, samples: int) -> np.ndarray:
    """``(samples, n)``: the output ``C Ad^k e_i`` from each unit initial state (controller form)."""
    out = np.empty((samples, Ad.shape[0]))
    power = np.eye(Ad.shape[0])
    for k in range(samples):
        out[k] = Cd[0] @ power
        power = Ad @ power
    return out


def simulate_transfer_function(num, den, u: np.ndarray, period: float) -> np.ndarray:
    """Output of ``num/den`` for the input ``u`` (last axis: time) held over each ``period``
    (exact ZOH), from rest."""
    return _forced_response(*_discrete(num, den, period), u)


def _segments(u: np.ndarray, y: np.ndarray, segment: int | None):
    if segment is None:
        return u[None], y[None]
    count = u.size // segment
    return u[:count * segment].reshape(count, segment), y[:count * segment].reshape(count, segment)


def _simulate_segments(num, den, period, U, Y, free: bool):
    """Simulated output per segment; with ``free``, from the least-squares initial states."""
    Ad, Bd, Cd, Dd = _discrete(num, den, period)          # once per evaluation: the fit's hot path
    Yf = _forced_response(Ad, Bd, Cd, Dd, U)
    if free:
        Phi = _free_responses(Ad, Cd, U.shape[1])
        X0, *_ = np.linalg.lstsq(Phi, (Y - Yf).T, rcond=None)
        Yf = Yf + (Phi @ X0).T
    return Yf


def _svf_start(u: np.ndarray, y: np.ndarray, period: float, n: int, m: int, lam: float) -> np.ndarray:
    """Least-squares ``[b_m..b_0, a_{n-1}..a_0]`` from state-variable-filtered derivatives."""
    den = np.poly(np.full(n, -lam))
    Y = np.column_stack([simulate_transfer_function(np.eye(n + 1)[n - k], den, y, period) for k in range(n + 1)])
    U = np.column_stack([simulate_transfer_function(np.eye(n + 1)[n - k], den, u, period) for k in range(m + 1)])
    # (s^k / (s + lam)^n) filtered signals; s^n y = sum b_k s^k u - sum a_k s^k y
    regressors = np.column_stack([U[:, ::-1], -Y[:, n - 1::-1]])
    theta, *_ = np.linalg.lstsq(regressors, Y[:, n], rcond=None)
    return theta


def fit_transfer_function(u, y, period: float, poles: int, zeros: int | None = None,
                          segment: int | None = None, bandwidths=None) -> TransferFunctionFit:
    """Fit ``poles`` poles and ``zeros`` zeros (default ``poles - 1``) to the record ``u -> y``
    sampled every ``period`` s (input held between samples). ``segment``: samples per segment
    with its own initial state (None: the record starts at rest). ``bandwidths`` (rad/s): the
    state-variable-filter poles tried for the start (default 2, 10, 50)."""
    u, y = np.asarray(u, dtype=float), np.asarray(y, dtype=float)
    zeros = poles - 1 if zeros is None else zeros
    if not (1 <= poles <= 8 and 0 <= zeros <= poles):
        raise RcmKinError(f"the model order needs 1..8 poles and 0..poles zeros, got {poles} and {zeros}")
    if u.shape != y.shape or u.ndim != 1 or u.size < 10 * (poles + zeros + 1):
        raise RcmKinError(f"the record needs matching input and output with at least {10 * (poles + zeros + 1)} "
                          f"samples, got {u.size} and {y.size}")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))) or np.ptp(u) == 0:
        raise RcmKinError("the record must be finite and the input must vary")
    if segment is not None and not (4 * poles <= segment <= u.size):
        raise RcmKinError(f"segments need {4 * poles}..{u.size} samples, got {segment}")
    n, m = poles, zeros
    U, Y = _segments(u, y, segment)
    free = segment is not None

    def unpack(p):
        return p[:m + 1], np.r_[1.0, p[m + 1:]]

    def residual(p):
        num, den = unpack(p)
        if not np.all(np.isfinite(den)) or np.any(np.abs(np.roots(den)) > 0.5 / period):
            return np.full(Y.size, 1e6)          # beyond the sampling's reach
        with np.errstate(all="ignore"):
            r = (_simulate_segments(num, den, period, U, Y, free) - Y).ravel()
        return np.where(np.isfinite(r), np.clip(r, -1e6, 1e6), 1e6)

    best = None
    for lam in (bandwidths if bandwidths is not None else (2.0, 10.0, 50.0)):
        start = _svf_start(u, y, period, n, m, lam)
        if not np.all(np.isfinite(start)):
            continue
        sol = least_squares(residual, start, x_scale="jac", max_nfev=100 * start.size)
        if best is None or sol.cost < best.cost:
            best = sol
    if best is None:
        raise RcmKinError("no usable start for the transfer-function fit (is the record informative?)")
    num, den = unpack(best.x)
    try:
        with np.errstate(all="ignore"):
            y_fit = _simulate_segments(num, den, period, U, Y, free)
    except np.linalg.LinAlgError:                 # a model with non-finite coefficients: diverged
        y_fit = np.full(Y.shape, np.inf)
    if not np.all(np.isfinite(y_fit)) or np.any(np.abs(y_fit) >= 1e6):
        raise RcmKinError("the transfer-function fit diverged (try another order or a shorter `segment`)",
                          parameter="segment")
    return TransferFunctionFit(num, den, fit_percent(Y.ravel(), y_fit.ravel()), period, segment, y_fit.ravel())

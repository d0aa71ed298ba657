"""The safety thesis's scenarios, simulated with the CBF filter on a nominal controller.

- ``ellipsoid``: the 3-D Cartesian tool tip, first order per axis (tau = 70.088, 100.288,
  40.114 ms), pole-placed at -15 (K_i = 15 tau_i - 1, N_i = 1 + K_i), sent through waypoints on
  both sides of a no-go ellipsoid centred at 0 with radii (30, 60, 30) mm; eps = 0.778 (1 cm
  along x), kappa 1.
- ``slide``: the instrument slide, first order (tau 0.11 s, K 9, N 10), references beyond the
  workspace [-0.10, 0.05] m; the thesis's parabola barrier, eps = 0.00249.
- ``heart``: the beating-heart fixture: the tool (first order, K 9, N 10) follows the heart
  surface (harmonic, period 1.1 s, 3 cm amplitude) at a distance that switches from 3 cm to
  -1 cm (into the heart) at 2 s; B = surface - tool, eps = 0.01.
- ``psm``: our PSM following an MTM recording through the teleoperation map towards a no-go
  ellipsoid on its path (:func:`psm_run`).

Each runs at 2 kHz with the input held over the step (exact discretisation of the linear
plant) and the input clamped as on the robot (+-0.1 m). ``filter`` picks the thesis's blend of
``k0`` (continuous-time Lie derivatives, as the thesis), the CBF-QP (on the sampled plant), or
none.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rcm_kin.control.linearization import zero_order_hold
from rcm_kin.errors import RcmKinError
from rcm_kin.kinematics.fk import frame_placement
from rcm_kin.kinematics.psm_ik import shaft_tip_ik
from rcm_kin.kinematics.teleop import default_teleop_map, psm_targets
from rcm_kin.model import load_robot
from rcm_kin.safety.barriers import Barrier, Ellipsoid, MovingPlane, Slab, band_width
from rcm_kin.safety.cbf import (
    barrier_terms,
    blended_control,
    cbf_qp_problem,
    solve_cbf_qp,
)
from rcm_kin.simulation.controllers import make_controller
from rcm_kin.simulation.experiments import (
    closed_loop,
    psm_plant_and_schedule,
    start_hold,
)
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.loop import si_units
from rcm_kin.simulation.references import Reference, load_mtm_trajectory

SCENARIOS = ("ellipsoid", "slide", "heart", "psm")
FILTERS = ("blend", "qp", "none")
MAX_KAPPA = 100.0                                           # m: k0's aggressiveness; the thesis uses 0.01 to 1
CARTESIAN_TAU = np.array([0.070088, 0.100288, 0.040114])   # s, thesis Appendix F.2
SLIDE_TAU = 0.11                                            # s
HEART_PERIOD = 1.1                                          # s (Duindam and Sastry)
U_MAX = 0.1                                                 # m, command clamp on the robot
QP_ALPHA = 20.0                                             # 1/s, class-K gain of the CBF-QP


@dataclass(frozen=True)
class SafetyRun:
    scenario: str
    filter: str
    time: np.ndarray          # (N,) s
    state: np.ndarray         # (N, n)
    command: np.ndarray       # (N, m) sent (after the filter and the clamp)
    barrier: np.ndarray       # (N,) B along the run (<= 0 safe)
    sigma: np.ndarray         # (N,) blend weight (blend filter); 1 where the QP changed the input

    def summary(self) -> dict:
        """``min_margin`` = -max B (>= 0: never unsafe), ``violations`` = samples with B > 0 or B not
        a number (a NaN never reads as safe)."""
        return {"min_margin": float(-self.barrier.max()), "violations": int(np.count_nonzero(~(self.barrier <= 0))),
                "max_barrier": float(self.barrier.max()), "samples": int(self.time.size),
                "filter_active_s": float(np.count_nonzero(self.sigma > 0) * (self.time[1] - self.time[0]))}


def run_linear(name: str, A, B, barriers: Sequence[Barrier], eps: float,
               nominal: Callable[[float, np.ndarray], np.ndarray], x0, duration: float, filter: str = "blend",
               kappa: float = 1.0, dt: float = 5e-4, u_max: float = U_MAX) -> SafetyRun:
    """Simulate ``xdot = A x + B u`` with ``u = filter(nominal(t, x))`` clamped to ``+-u_max``. The
    blend uses the first barrier of ``barriers`` (the thesis's single-barrier law)."""
    if filter not in FILTERS:
        raise RcmKinError(f"unknown filter '{filter}' (choose from {', '.join(FILTERS)})")
    Ad, Bd = zero_order_hold(A, B, dt)
    n_steps = int(round(duration / dt))
    x = np.asarray(x0, dtype=float)
    xs, us, bs, ss = [], [], [], []
    qp = cbf_qp_problem(B.shape[1], len(barriers), u_max) if filter == "qp" else None
    for k in range(n_steps):
        t = k * dt
        u_nom = nominal(t, x)
        terms = [barrier_terms(b, x, A @ x, B) for b in barriers]
        sigma = 0.0
        if filter == "blend":
            u, sigma = blended_control(u_nom, terms[0], kappa, eps)
        elif filter == "qp":
            # the sampled condition (B(x+) - B(x)) / dt <= -alpha B, B linearised about x: safe for
            # the concave ellipsoid and the affine plane, second order for the slab
            sampled = [barrier_terms(b, x, (Ad @ x - x) / dt, Bd / dt) for b in barriers]
            u = solve_cbf_qp(qp, u_nom, sampled, QP_ALPHA)
            sigma = float(np.linalg.norm(u - np.clip(u_nom, -u_max, u_max)) > 1e-6)
        else:
            u = u_nom
        u = np.clip(u, -u_max, u_max)
        xs.append(x)
        us.append(u)
        bs.append(max(t_.value for t_ in terms))
        ss.append(sigma)
        x = Ad @ x + Bd @ u
    return SafetyRun(name, filter, np.arange(n_steps) * dt, np.array(xs), np.array(us), np.array(bs), np.array(ss))


def ellipsoid_run(filter: str = "blend", x0=(0.06, 0.0, 0.0), waypoints=None, duration: float = 3.0,
                  kappa: float = 1.0) -> SafetyRun:
    """The 3-D no-go ellipsoid; ``waypoints`` (k, 3) m visited 0.5 s each (default: across it)."""
    tau = CARTESIAN_TAU
    K = 15 * tau - 1
    N = 1 + K
    A, B = np.diag(-1 / tau), np.diag(1 / tau)
    ellipsoid = Ellipsoid(np.zeros(3), np.array([0.03, 0.06, 0.03]))
    eps = band_width(ellipsoid, [0.04, 0.0, 0.0])          # 1 cm outside along x: 0.778
    points = np.array(waypoints if waypoints is not None else
                      [[-0.06, 0.01, 0.005], [0.06, -0.01, 0.0], [0.0, 0.0, -0.07], [0.0, 0.02, 0.06],
                       [-0.05, 0.0, 0.0], [0.05, 0.03, -0.01]], dtype=float)
    hold = duration / len(points)
    nominal = lambda t, x: N * points[min(int(t / hold), len(points) - 1)] - K * x  # noqa: E731
    return run_linear("ellipsoid", A, B, [ellipsoid], eps, nominal, x0, duration, filter, kappa)


def slide_run(filter: str = "blend", duration: float = 2.0, kappa: float = 1.0) -> SafetyRun:
    """The slide against its workspace limits [-0.10, 0.05] m."""
    K, N = 9.0, 10.0
    A, B = np.array([[-1 / SLIDE_TAU]]), np.array([[1 / SLIDE_TAU]])
    slab = Slab(0, -0.10, 0.05)
    eps = band_width(slab, [0.04])                          # the soft limit: 0.00249
    references = [(0.0, 0.0), (0.2, 0.08), (1.0, -0.15), (1.6, 0.03)]
    nominal = lambda t, x: N * np.array([[r for s, r in references if s <= t][-1]]) - K * x  # noqa: E731
    return run_linear("slide", A, B, [slab], eps, nominal, [0.0], duration, filter, kappa)


def heart_run(filter: str = "blend", duration: float = 5.0, kappa: float = 1.0) -> SafetyRun:
    """The beating heart: state [tool, surface, surface rate / omega] (m)."""
    K, N = 9.0, 10.0
    w = 2 * np.pi / HEART_PERIOD
    A = np.array([[-1 / SLIDE_TAU, 0, 0], [0, 0, w], [0, -w, 0]])
    B = np.array([[1 / SLIDE_TAU], [0.0], [0.0]])
    plane = MovingPlane(tool=0, surface=1)
    nominal = lambda t, x: np.array([N * (x[1] + (0.03 if t < 2.0 else -0.01)) - K * x[0]])  # noqa: E731
    return run_linear("heart", A, B, [plane], 0.01, nominal, [0.05, -0.03, 0.0], duration, filter, kappa)


@dataclass(frozen=True)
class PsmSafetyRun:
    """The filtered teleoperation of the PSM: the reference the filter let through and the
    shaft tip the 400 Hz loop achieved, both against the no-go ellipsoid."""

    reference: SafetyRun      # filtered shaft-tip target (state: position, m)
    tip: np.ndarray           # (N, 3) m, shaft tip of the simulated robot (true joints, FK)
    tip_barrier: np.ndarray   # (N,) B of the true ellipsoid at the achieved tip
    ellipsoid: Ellipsoid
    allowance: float          # m, added to the radii the filter guards (tracking error)

    def summary(self) -> dict:
        return {"min_margin": float(-self.tip_barrier.max()),
                "violations": int(np.count_nonzero(~(self.tip_barrier <= 0))),   # NaN counts as unsafe
                "reference_min_margin": float(-self.reference.barrier.max()),
                "min_distance_mm": float(1e3 * _ellipsoid_distance_lower_bound(self.ellipsoid, self.tip)),
                "samples": int(self.tip_barrier.size)}


def _ellipsoid_distance_lower_bound(e: Ellipsoid, points: np.ndarray) -> float:
    """A lower bound of the distance (m) from the points outside to the ellipsoid: a point on the
    copy scaled by its normalised radius ``rho`` is at least ``(rho - 1) r_min`` away (negative:
    inside)."""
    rho = np.sqrt(np.sum(((points - e.center) / e.radii) ** 2, axis=1))
    return float(np.min((rho - 1) * np.min(e.radii)))


def psm_run(filter: str = "blend", trajectory=None, controller: str = "scheduled-gravity",
            radii=(0.0015, 0.0015, 0.0015), allowance: float = 0.001, smoothing: float = 0.02,
            kappa: float = 0.01) -> PsmSafetyRun:
    """Teleoperation of the PSM towards a forbidden region.

    The MTM recording (default the bundled figure-eight) goes through the teleoperation map to
    shaft-tip targets. A no-go ellipsoid (``radii``, m) sits on the unfiltered path at its
    lowest point. The targets drive a first-order reference state (``smoothing`` s) through the
    CBF filter, which guards the ellipsoid grown by ``allowance`` for the tracking error (the
    filter works in coordinates centred on the ellipsoid, where ``k0`` does not depend on where
    the robot's base is; ``kappa`` in m, scaled to the millimetre geometry); the
    PSM IK maps the filtered tip to roll, pitch and insertion (the RCM by construction, the
    joint limits checked), and the 400 Hz loop with ``controller`` tracks it (the compiled loop,
    :func:`rcm_kin.simulation.experiments.closed_loop`). The margin is
    measured on the true ellipsoid at the tip the simulated robot reaches."""
    from scipy.interpolate import CubicSpline


    psm = load_robot("psm")
    settings = FirmwareSettings()
    T = settings.period
    t_raw, displacement = load_mtm_trajectory(trajectory)
    targets = CubicSpline(t_raw, psm_targets(default_teleop_map(psm), displacement))
    time = np.arange(int(round(t_raw[-1] / T)) + 1) * T
    path = targets(time)
    centre = path[np.argmin(path[:, 2])]
    ellipsoid = Ellipsoid(centre, np.asarray(radii, dtype=float))
    guarded = Ellipsoid(np.zeros(3), ellipsoid.radii + allowance)      # centred coordinates
    eps = band_width(guarded, [guarded.radii[0] + 0.5e-3, 0.0, 0.0])
    A, B = -np.eye(3) / smoothing, np.eye(3) / smoothing
    nominal = lambda t, x: targets(min(t, t_raw[-1])) - centre  # noqa: E731
    sub = 5                                   # the filter runs at 5 x 400 Hz, the loop takes every 5th sample
    centred = run_linear("psm", A, B, [guarded], eps, nominal, path[0] - centre, time[-1] + T, filter, kappa,
                         dt=T / sub, u_max=1.0)
    reference = SafetyRun("psm", filter, centred.time[::sub], centred.state[::sub] + centre,
                          centred.command[::sub] + centre, centred.barrier[::sub], centred.sigma[::sub])
    try:
        joints = np.array([shaft_tip_ik(psm, p) for p in reference.state])   # RCM and joint limits held
    except RcmKinError as exc:
        raise RcmKinError(f"the filtered reference leaves the PSM's reach: {exc}") from None
    q = np.zeros(psm.nq)
    spline = CubicSpline(reference.time, joints)
    ref = Reference(reference.time, joints, spline(reference.time, 1), spline(reference.time, 2))
    plant, schedule = psm_plant_and_schedule(period=T, fast=True)
    run = closed_loop(plant, make_controller(controller, schedule), ref, settings, hold=start_hold(ref))
    tip = []
    for true in si_units(run.position):       # the simulated robot's true joints, not the encoder counts
        q[:3] = true
        tip.append(frame_placement(psm, q, "shaft_tip").translation)
    tip = np.array(tip)
    return PsmSafetyRun(reference, tip, np.array([ellipsoid.value(p) for p in tip]), ellipsoid, allowance)


def run_scenario(name: str, filter: str = "blend", **options):
    """A scenario by name (:data:`SCENARIOS`)."""
    runs = {"ellipsoid": ellipsoid_run, "slide": slide_run, "heart": heart_run, "psm": psm_run}
    if name not in runs:
        raise RcmKinError(f"unknown scenario '{name}' (choose from {', '.join(SCENARIOS)})")
    kappa = options.get("kappa", 1.0)
    if not (np.isfinite(kappa) and 0 < kappa <= MAX_KAPPA):
        raise RcmKinError(f"kappa is a length in (0, {MAX_KAPPA:g}] m, got {kappa}")
    return runs[name](filter, **options)

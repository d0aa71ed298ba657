"""The plants a design is judged on: parameter sets drawn from what the identification does not
know, each with what the tuning needs of it, built once.

A :class:`DrawSet` holds, per draw (``SeedSequence(seed).spawn(n)[i]``, the robustness study's
draws, :func:`rcm_kin.robustness.sampling.draw`): the drawn
:class:`~rcm_kin.dynamics.drive.DriveParameters` (the roll's drive train one of the file's
jackknife-inflated fold sets or its own, the ranges the logs leave open drawn uniformly, the
drivers' volts per PWM and the calibrated first moments by their spreads), its compiled plant
(:func:`rcm_kin.robustness.task.sample_plant`), the steady hold each experiment starts from on
that plant, and the frozen-gain firmware loop of its smooth model at every pose of a
``points x points`` roll x pitch grid in the loop's affine form :class:`LoopFamily`:
``Phi(k) = F0 + sum_i k_i F_i``, exact because :func:`rcm_kin.control.stability.firmware_loop_matrix`
is linear in the five gains (roll Kp, Kd; pitch Kp, Kd, Ki). The eigenvalues of every pose and draw
for a gain set are then one batched call (:meth:`LoopFamily.spectral_radius`).

Draws the robot's own holds rule out are not drawn (``consistent``): a drawn set whose holding PWM
of roll or pitch at the thesis grid's nine poses (80 mm) differs from the nominal set's by more
than the measured holding band's half-width (:func:`rcm_kin.statics.holding_band.conformal_half_width`
of the file's leave-one-hold-out residuals at :data:`HOLDING_LEVEL`) is skipped, and the next seed
of the sequence taken: the default spreads of the drivers' volts per PWM and of the first moments
(15 and 20 %) otherwise draw pitches that need nearly the whole PWM range to hold (about 140 of 150
counts where the robot held about 70), which no controller tracks and the holds contradict.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import replace as dataclass_replace

import numpy as np
from tqdm import tqdm

from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG
from rcm_kin.control.linearization import linearize_grid, zero_order_hold
from rcm_kin.control.stability import firmware_loop_matrix
from rcm_kin.dynamics.drive import DriveParameters
from rcm_kin.dynamics.state_space import driven_dynamics, holding_pwm
from rcm_kin.errors import RcmKinError
from rcm_kin.hardware import HOME_INSERTION
from rcm_kin.model import load_robot
from rcm_kin.robustness.sampling import draw, sample_seeds, uncertain_parameters, with_values
from rcm_kin.robustness.task import INSERTION_STATES, sample_model, sample_plant
from rcm_kin.simulation.controllers import Hold
from rcm_kin.simulation.experiments import experiment_reference, start_hold
from rcm_kin.simulation.firmware import FirmwareSettings
from rcm_kin.simulation.references import Reference
from rcm_kin.statics.holding_band import conformal_half_width, residuals_of

EXPERIMENTS = ("sine", "target")        # the thesis's tracking experiments (Sec. 5.2.1, 5.2.2)
LOOP_POINTS = 41                        # poses per axis of the final stability check (the schedule's default)
HOLDING_LEVEL = 0.9                     # the holding band's level (the drive file's holds support it)
MAX_TRIES = 8                           # seeds tried per kept draw before the draws are refused,
MIN_TRIES = 64                          # and at least these (a few draws would give up by chance)
GAIN_NAMES = ("roll_kp", "roll_kd", "pitch_kp", "pitch_kd", "pitch_ki")   # the loop's gains, firmware units


def _gains(k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return k[:2], k[2:]


@dataclass(frozen=True)
class LoopFamily:
    """The 400 Hz frozen-gain loops of many linear models as ``Phi(k) = F0 + sum_i k_i F_i``.

    ``F0`` (m, 10, 10) the loop with every gain 0, ``F`` (5, m, 10, 10) the change per unit of
    each gain of :data:`GAIN_NAMES`; ``roll_deg``/``pitch_deg`` (m,) the pose of each model."""

    F0: np.ndarray
    F: np.ndarray
    roll_deg: np.ndarray
    pitch_deg: np.ndarray

    def matrices(self, gains: np.ndarray) -> np.ndarray:
        """``Phi`` (m, 10, 10) for per-model gains ``gains`` (m, 5) or one set (5,)."""
        gains = np.broadcast_to(np.asarray(gains, dtype=float), (self.F0.shape[0], len(GAIN_NAMES)))
        return self.F0 + np.einsum("mi,imjk->mjk", gains, self.F)

    def spectral_radius(self, gains: np.ndarray) -> np.ndarray:
        """Largest ``|z|`` (m,) of each model's roll and pitch modes (the insertion's own modes, the
        same firmware P loop under every law, left out as :func:`rcm_kin.robustness.task.roll_pitch_modes`
        does; without pitch integral action its integrator, a mode nothing depends on, too)."""
        gains = np.broadcast_to(np.asarray(gains, dtype=float), (self.F0.shape[0], len(GAIN_NAMES)))
        phi = self.matrices(gains)
        w, V = np.linalg.eig(phi)
        physical = np.abs(V[:, :6]) ** 2
        total = physical.sum(axis=1)
        insertion = physical[:, INSERTION_STATES].sum(axis=1)
        keep = insertion <= 0.5 * total
        no_integral = gains[:, 4] == 0
        integrator = np.isclose(w, 1.0, rtol=0.0, atol=1e-12) & no_integral[:, None]
        return np.where(keep & ~integrator, np.abs(w), 0.0).max(axis=1)


def loop_family(model, roll_deg: np.ndarray, pitch_deg: np.ndarray, insertion: float,
                period: float) -> LoopFamily:
    """The :class:`LoopFamily` of ``model`` (smooth, Coulomb friction left out) at every pose of the
    roll x pitch grid (deg), built from :func:`~rcm_kin.control.stability.firmware_loop_matrix`
    itself at zero and unit gains (the feedback rows once, the model's sampled input matrix per pose)."""
    P, R = np.meshgrid(pitch_deg, roll_deg, indexing="ij")
    Q = np.column_stack([np.radians(R.ravel()), np.radians(P.ravel()), np.full(R.size, insertion)])
    grid = linearize_grid(model, Q, compile=False)          # a drawn model's functions: compiled once for all
    held = [zero_order_hold(A, B, period) for A, B in zip(grid.A, grid.B)]
    F0 = np.array([firmware_loop_matrix(A, B, *_gains(np.zeros(5)), period, discrete=d)
                   for A, B, d in zip(grid.A, grid.B, held)])
    # the feedback rows u = G(k) xi do not depend on the pose: read G from the same function with
    # (Ad, Bd) = (0, [I; 0]), whose first rows are then G itself; the pose enters as Bd G
    probe = (np.zeros((6, 6)), np.eye(6, 3))
    G = np.array([firmware_loop_matrix(None, None, *_gains(k), period, discrete=probe)[:3]
                  for k in np.vstack([np.zeros(len(GAIN_NAMES)), np.eye(len(GAIN_NAMES))])])
    Bd = np.array([d[1] for d in held])
    F = np.zeros((len(GAIN_NAMES),) + F0.shape)
    F[:, :, :6] = np.einsum("mjc,icn->imjn", Bd, G[1:] - G[0])
    return LoopFamily(F0, F, R.ravel(), P.ravel())


@dataclass(frozen=True)
class Draw:
    """One drawn plant (``index``: its seed's place in ``SeedSequence(seed).spawn``): its parameters,
    compiled plant, the steady hold of each experiment's first
    pose (its own smooth model's holding PWM) and its frozen-gain loops (:class:`LoopFamily`)."""

    index: int
    params: DriveParameters
    plant: object
    holds: dict[str, Hold]
    loops: LoopFamily


@dataclass(frozen=True)
class DrawSet:
    """The draws a design is tuned or judged on (see the module's notes), with the experiments'
    references at the firmware period."""

    seed: int
    draws: tuple[Draw, ...]
    references: dict[str, Reference]
    settings: FirmwareSettings
    points: int

    rejected: int = 0                     # drawn sets skipped as inconsistent with the holds

    def __len__(self) -> int:
        return len(self.draws)

    def subset(self, samples: int, points: int) -> DrawSet:
        """The first ``samples`` draws with their loops on every k-th pose, ``points`` per axis
        (``points - 1`` must divide this set's ``points - 1``): a cheaper set to tune on."""
        step, rest = divmod(self.points - 1, points - 1) if points >= 2 else (0, 1)
        if rest or not 1 <= samples <= len(self):
            raise RcmKinError(f"a subset of 1 to {len(self)} draws on a grid of n points with (n - 1) dividing "
                              f"{self.points - 1}, got {samples} draws on {points}", parameter=("samples", "points"))
        keep = np.zeros((self.points, self.points), dtype=bool)
        keep[::step, ::step] = True
        keep = keep.ravel()
        draws = tuple(dataclass_replace(d, loops=LoopFamily(d.loops.F0[keep], d.loops.F[:, keep],
                                                             d.loops.roll_deg[keep], d.loops.pitch_deg[keep]))
                      for d in self.draws[:samples])
        return dataclass_replace(self, draws=draws, points=points)


def holding_check(params: DriveParameters, psm):
    """``model -> bool``: whether the smooth model of a drawn set holds roll and pitch at the thesis
    grid's poses with a PWM within the measured holding band about ``params``' own (see the module's
    notes)."""
    P, R = np.meshgrid(np.radians(THESIS_PITCH_DEG), np.radians(THESIS_ROLL_DEG), indexing="ij")
    Q = np.column_stack([R.ravel(), P.ravel(), np.full(R.size, HOME_INSERTION)])

    def holds(model) -> np.ndarray:
        return np.array([holding_pwm(model, q)[:2] for q in Q])

    residuals = residuals_of(params)
    width = np.array([conformal_half_width(residuals[j], HOLDING_LEVEL) if j in residuals else np.inf
                      for j in ("roll", "pitch")])
    nominal = holds(driven_dynamics(psm, params, coulomb=False))
    return lambda model: bool(np.all(np.abs(holds(model) - nominal) <= width))


def build_draws(params: DriveParameters, samples: int, seed: int, points: int = 9,
                experiments: tuple[str, ...] = EXPERIMENTS, progress: bool = False,
                nominal_first: bool = False, consistent: bool = True) -> DrawSet:
    """``samples`` drawn plants of ``params`` (see the module's notes), their loops on a ``points x
    points`` grid over the thesis grid's span (roll -20..20, pitch -15..15 deg, insertion 80 mm);
    ``nominal_first``: draw 0 is ``params`` itself; ``consistent``: skip the sets the holds rule out
    (seeds of ``SeedSequence(seed)`` taken in order until ``samples`` are kept). About 0.1 s a draw
    (a compiled plant each; the first run of a set compiles it, about 0.5 s)."""
    if not 1 <= samples <= 4096:
        raise RcmKinError(f"the number of draws is 1 to 4096, got {samples}", parameter="samples")
    if not 2 <= points <= 201:
        raise RcmKinError(f"the stability grid has 2 to 201 points per axis, got {points}", parameter="points")
    unknown = [e for e in experiments if e not in EXPERIMENTS]
    if unknown or not experiments:
        raise RcmKinError(f"experiments are {', '.join(EXPERIMENTS)}, got {list(experiments)}",
                          parameter="experiments")
    settings = FirmwareSettings()
    references = {e: experiment_reference(e, settings.period) for e in experiments}
    uncertain = uncertain_parameters(params)
    rolls = np.linspace(THESIS_ROLL_DEG[0], THESIS_ROLL_DEG[-1], points)
    pitches = np.linspace(THESIS_PITCH_DEG[0], THESIS_PITCH_DEG[-1], points)
    psm = load_robot("psm")
    check = holding_check(params, psm) if consistent else (lambda model: True)
    tries = max(samples * MAX_TRIES, MIN_TRIES)
    seeds, out, rejected = iter(enumerate(sample_seeds(seed, tries))), [], 0
    bar = tqdm(total=samples, desc="draw plants", unit="plant", disable=not progress, leave=False)
    while len(out) < samples:
        i, s = next(seeds, (None, None))
        if s is None:
            raise RcmKinError(f"fewer than {samples} of {tries} drawn sets agree with the measured holds (the holding "
                              "band): the spreads are too wide for the file's holds; check its "
                              "[uncertainty.holding_residuals] (rcm-kin calibrate writes them)", parameter="params")
        drawn = params if (nominal_first and not out) else with_values(params, uncertain, draw(uncertain, s))
        model = sample_model(drawn)      # the check's model, and the draw's (one compiled model for all)
        if not check(model):
            rejected += 1
            continue
        bar.update(1)
        holds = {e: start_hold(r, model=model) for e, r in references.items()}
        out.append(Draw(i, drawn, sample_plant(drawn, settings.period), holds,
                        loop_family(model, rolls, pitches, HOME_INSERTION, settings.period)))
    bar.close()
    return DrawSet(seed, tuple(out), references, settings, points, rejected)

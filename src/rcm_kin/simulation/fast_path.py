"""The closed loop's fast path: the same arithmetic as the readable controllers and plants, with
the per-tick overheads taken out. The readable classes (:mod:`rcm_kin.simulation.controllers`,
:mod:`rcm_kin.simulation.plant`) stay the reference; ``tests/simulation/test_simulation.py`` runs both and
compares them tick for tick.

- :func:`fast_controller`: the gain-scheduled controllers with their tables stacked into one
  array, interpolated once per pose (the firmware's bilinear rule, operation for operation, so
  the gains are the same numbers), on Python floats instead of small NumPy arrays;
- :func:`fast_plant`: the drive-train plant with its mass matrix and bias forces compiled to C
  (:mod:`rcm_kin.symbolic.compiled`) and called through bound buffers; the stick-slip axes are
  advanced by the same numba kernel (the plant's own ``step``);
- :func:`compiled_period_map`: the smooth model's RK4 period compiled the same way.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from rcm_kin import thesis as thesis_reference
from rcm_kin.control.gain_schedule import THESIS_PITCH_DEG, THESIS_ROLL_DEG
from rcm_kin.simulation.controllers import (Controller, Hold, Sample, StateFeedbackController, ThesisController,
                                          _conditional_integral, _insertion)
from rcm_kin.simulation.plant import DriveTrainPlant
from rcm_kin.symbolic.compiled import compiled, single_call


@dataclass(frozen=True)
class StackedTable:
    """Tables on one roll x pitch grid (degrees), stacked along the last axis: ``values[j, i]`` at
    pitch ``pitch[j]``, roll ``roll[i]``."""

    roll: tuple[float, ...]
    pitch: tuple[float, ...]
    values: np.ndarray          # (n_pitch, n_roll, k)

    def at(self, roll_deg: float, pitch_deg: float) -> list[float]:
        """All k values at a pose: the firmware's clamped bilinear rule (along roll on the two
        pitch rows, then along pitch), as :func:`rcm_kin.control.gain_schedule.bilinear`."""
        i, r = _cell(self.roll, roll_deg)
        j, p = _cell(self.pitch, pitch_deg)
        r0, r1, p0, p1 = self.roll[i], self.roll[i + 1], self.pitch[j], self.pitch[j + 1]
        fr, fp = (r - r0) / (r1 - r0), (p - p0) / (p1 - p0)
        v = self.values
        low = v[j, i] + (v[j, i + 1] - v[j, i]) * fr
        high = v[j + 1, i] + (v[j + 1, i + 1] - v[j + 1, i]) * fr
        return (low + (high - low) * fp).tolist()


def _cell(grid: tuple[float, ...], x: float) -> tuple[int, float]:
    """Cell index and clamped coordinate (``gain_schedule._cell`` on a tuple)."""
    x = min(max(x, grid[0]), grid[-1])
    return min(max(bisect.bisect_right(grid, x) - 1, 0), len(grid) - 2), x


def stacked(roll, pitch, *tables: np.ndarray) -> StackedTable:
    return StackedTable(tuple(float(x) for x in roll), tuple(float(x) for x in pitch),
                        np.concatenate([np.asarray(t, dtype=float) for t in tables], axis=-1))


def _pitch_law(integral: float, error: float, period: float, limit: float, k_e: float, k_v: float, k_i: float,
               v: float, feedforward: float) -> tuple[float, float]:
    """``_conditional_integral`` with the pitch law ``-(k_e e + k_v v + k_i E) + feedforward``."""
    def law(E: float) -> float:
        return -(k_e * error + k_v * v + k_i * E) + feedforward
    return _conditional_integral(integral, error, period, law, limit)


@dataclass(frozen=True)
class FastStateFeedback:
    """:class:`StateFeedbackController` (gains, feedforward, holding PWM, friction) on stacked tables."""

    reference: StateFeedbackController
    gains: StackedTable           # k_roll (2), k_pitch (3), ff_pitch (2)
    hold: StackedTable | None     # u_hold (2)

    @property
    def name(self) -> str:
        return self.reference.name

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        return self.reference.initial_memory(hold)

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        c = self.reference
        position, reference = sample.position.tolist(), sample.reference.tolist()
        at = position[:2] if c.scheduled else [0.0, 0.0]
        kr_p, kr_d, kp_p, kp_d, kp_i, ff_v, ff_a = self.gains.at(at[0], at[1])
        e0, e1 = reference[0] - position[0], reference[1] - position[1]
        rdot = sample.reference_velocity.tolist()
        w0, w1 = sample.velocity[0], sample.velocity[1]
        if c.track_velocity:
            w0, w1 = w0 - rdot[0], w1 - rdot[1]
        hold = self.hold.at(reference[0], reference[1]) if self.hold is not None else [0.0, 0.0]
        if c.friction:
            friction = c.schedule.friction.feedforward(sample.reference_velocity[:2])
            hold = [hold[0] + friction[0], hold[1] + friction[1]]
        u0 = -(kr_p * e0 + kr_d * w0) + hold[0]
        feedforward = ff_v * rdot[1] + ff_a * sample.reference_acceleration[1] + hold[1]
        u1, integral = _pitch_law(float(memory[0]), e1, sample.period, sample.pwm_limit[1], kp_p, kp_d, kp_i,
                                  w1, feedforward)
        return np.array([u0, u1, _insertion(sample)]), np.array([integral])


@dataclass(frozen=True)
class FastThesis:
    """:class:`ThesisController` on one stacked table of its gains."""

    gains: StackedTable           # K_ROLL (2), K_PITCH (3)
    name: str = "thesis"

    def initial_memory(self, hold: Hold | None = None) -> np.ndarray:
        return ThesisController().initial_memory(hold)

    def command(self, memory: np.ndarray, sample: Sample) -> tuple[np.ndarray, np.ndarray]:
        position, reference = sample.position.tolist(), sample.reference.tolist()
        kr_p, kr_d, kp_p, kp_d, kp_i = self.gains.at(position[0], position[1])
        e0, e1 = reference[0] - position[0], reference[1] - position[1]
        v0, v1 = sample.velocity[0], sample.velocity[1]
        u0 = -(kr_p * e0 + kr_d * v0)
        u1, integral = _pitch_law(float(memory[0]), e1, sample.period, sample.pwm_limit[1], kp_p, kp_d, kp_i, v1, 0.0)
        return np.array([u0, u1, _insertion(sample)]), np.array([integral])


def fast_controller(controller: Controller) -> Controller:
    """The fast path of ``controller``: the scheduled and thesis controllers on stacked tables;
    the P and PID controllers (no tables) as they are."""
    if isinstance(controller, StateFeedbackController):
        s = controller.schedule
        return FastStateFeedback(controller, stacked(s.roll_deg, s.pitch_deg, s.k_roll, s.k_pitch, s.ff_pitch),
                                 stacked(s.roll_deg, s.pitch_deg, s.u_hold) if controller.gravity else None)
    if isinstance(controller, ThesisController):
        return FastThesis(stacked(THESIS_ROLL_DEG, THESIS_PITCH_DEG, thesis_reference.K_ROLL,
                                  thesis_reference.K_PITCH))
    return controller


class _BufferedFunction:
    """A compiled CasADi function called through bound buffers; returns NumPy arrays (what
    ``np.array(f(...))`` gives for the plant's uses: dense, column vectors as (n, 1))."""

    def __init__(self, fn: ca.Function):
        self._call = single_call(compiled(fn))
        self._columns = [fn.size2_out(i) == 1 for i in range(fn.n_out())]

    def __call__(self, *args):
        out = self._call(*args)
        shaped = [o.reshape(-1, 1) if column else o for o, column in zip(out, self._columns)]
        return shaped[0] if len(shaped) == 1 else tuple(shaped)


def fast_plant(plant: DriveTrainPlant) -> DriveTrainPlant:
    """The drive-train plant with its model's mass matrix and bias compiled (the plant's own
    ``step``, unchanged, calls them)."""
    model = replace(plant.model, mass_matrix=_BufferedFunction(plant.model.mass_matrix),
                    bias=_BufferedFunction(plant.model.bias))
    return replace(plant, model=model)


def compiled_period_map(period_map: ca.Function):
    """``(x, u) -> x(T)`` (flat arrays) of a smooth period map, compiled."""
    call = single_call(compiled(period_map))
    return lambda x, u: call(x, u)[0]

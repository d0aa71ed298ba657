"""What a controller hands the compiled kernel (:mod:`rcm_kin.simulation.kernel`): its law as
arrays, a :class:`LoopLaw`.

A controller that has a kernel form says so itself, with the optional method
``kernel_law(hold) -> LoopLaw | None`` of the :class:`~rcm_kin.simulation.controllers.Controller`
protocol; the kernel knows four laws (:data:`P`, :data:`PID`, :data:`STATE_FEEDBACK`,
:data:`THESIS`), and a new controller whose law is one of them, with its own gains or tables,
runs compiled without any change here. Plain data, no numba: the readable controllers import it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rcm_kin.errors import RcmKinError

P, PID, STATE_FEEDBACK, THESIS = 0, 1, 2, 3          # LoopLaw.kind
KINDS = (P, PID, STATE_FEEDBACK, THESIS)


def _floats(shape) -> np.ndarray:
    return np.zeros(shape)


@dataclass(frozen=True)
class LoopLaw:
    """A controller law as the kernel takes it (roll and pitch; the insertion is always the
    firmware's P loop). Fields a kind does not read keep their defaults.

    - ``P``: ``u = -Kp e``, ``gains[:2]`` = Kp (roll, pitch), no memory;
    - ``PID``: ``gains`` = Kp (2), Ki (2), Kd (2); memory: integrals (2), previous errors (2);
    - ``THESIS``: ``table`` k_roll (2), k_pitch (3) at the measured pose; memory: pitch integral;
    - ``STATE_FEEDBACK``: ``table`` k_roll (2), k_pitch (3), ff_pitch (2), ``flags`` scheduled,
      gravity (``hold`` the u_hold table), track_velocity, friction (``friction``: amplitudes
      roll, pitch in counts, ramp in deg/s); memory: pitch integral.
    """

    kind: int                    # P, PID, STATE_FEEDBACK, THESIS
    memory: np.ndarray           # the controller's initial memory, initial_memory(hold)
    gains: np.ndarray = field(default_factory=lambda: _floats(6))
    flags: np.ndarray = field(default_factory=lambda: np.zeros(4, dtype=bool))
    roll_deg: np.ndarray = field(default_factory=lambda: _floats(2))        # (nr,) table grid
    pitch_deg: np.ndarray = field(default_factory=lambda: _floats(2))       # (np,)
    table: np.ndarray = field(default_factory=lambda: _floats((2, 2, 7)))   # (np, nr, 7)
    hold: np.ndarray = field(default_factory=lambda: _floats((2, 2, 2)))    # (np, nr, 2)
    friction: np.ndarray = field(default_factory=lambda: _floats(3))

    def __post_init__(self):
        """Every array as the kernel's types (contiguous floats, bool flags), so that one
        compiled specialisation serves every law; the gains padded to 6 and the table to 7 values."""
        if self.kind not in KINDS:
            raise RcmKinError(f"unknown kernel law kind {self.kind} (one of P, PID, STATE_FEEDBACK, THESIS)")
        gains = np.zeros(6)
        given = np.asarray(self.gains, dtype=float).ravel()
        gains[:given.size] = given
        table = np.asarray(self.table, dtype=float)
        if table.shape[-1] < 7:
            table = np.concatenate([table, np.zeros(table.shape[:2] + (7 - table.shape[-1],))], axis=-1)
        arrays = {"memory": np.asarray(self.memory, dtype=float).ravel(), "gains": gains, "table": table,
                  "flags": np.asarray(self.flags, dtype=bool).ravel()}
        for name in ("roll_deg", "pitch_deg", "hold", "friction"):
            arrays[name] = np.asarray(getattr(self, name), dtype=float)
        for name, value in arrays.items():
            object.__setattr__(self, name, np.ascontiguousarray(value))


def stacked(roll, pitch, *tables) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(roll grid, pitch grid, values)`` of tables on one roll x pitch grid (degrees), stacked
    along the last axis: ``values[j, i]`` at pitch ``pitch[j]``, roll ``roll[i]``."""
    return (np.asarray(roll, dtype=float), np.asarray(pitch, dtype=float),
            np.concatenate([np.asarray(t, dtype=float) for t in tables], axis=-1))

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
from typing import ClassVar

import numpy as np

from rcm_kin.errors import RcmKinError

P, PID, STATE_FEEDBACK, THESIS = 0, 1, 2, 3          # LoopLaw.kind
KINDS = (P, PID, STATE_FEEDBACK, THESIS)
KIND_NAMES = ("P", "PID", "STATE_FEEDBACK", "THESIS")
MEMORY = {P: 0, PID: 4, STATE_FEEDBACK: 1, THESIS: 1}   # values of memory each law reads and writes
GAINS = {P: (2, 6), PID: (6,)}                         # sizes of gains a law reads (others: unread, <= 6)
TABLE_VALUES = {STATE_FEEDBACK: 7, THESIS: 5}          # values per grid point a law reads (padded to 7)


def _floats(shape) -> np.ndarray:
    return np.zeros(shape)


def _refuse(name: str, message: str) -> RcmKinError:
    return RcmKinError(f"LoopLaw `{name}`: {message}", parameter=name)


def _grid(name: str, grid: np.ndarray) -> np.ndarray:
    """``grid`` as a table axis the kernel can index: >= 2 finite, strictly increasing points."""
    if grid.ndim != 1 or grid.size < 2 or not np.all(np.isfinite(grid)) or np.any(np.diff(grid) <= 0):
        raise _refuse(name, f"a grid of at least 2 finite, strictly increasing degrees, got {grid.tolist()}")
    return grid


def _finite(name: str, value: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(value)):
        raise _refuse(name, "values must be finite")
    return value


@dataclass(frozen=True)
class LoopLaw:
    """A controller law as the kernel takes it (roll and pitch; the insertion is always the
    firmware's P loop). Fields a kind does not read keep their defaults.

    - ``P``: ``u = -Kp e``, ``gains[:2]`` = Kp (roll, pitch), no memory;
    - ``PID``: ``gains`` = Kp (2), Ki (2), Kd (2); memory: integrals (2), previous errors (2, NaN
      before the first sample);
    - ``THESIS``: ``table`` k_roll (2), k_pitch (3) at the measured pose; memory: pitch integral;
    - ``STATE_FEEDBACK``: ``table`` k_roll (2), k_pitch (3), ff_pitch (2), ``flags`` scheduled,
      gravity (``hold`` the u_hold table), track_velocity, friction (``friction``: amplitudes
      roll, pitch in counts, ramp in deg/s); memory: pitch integral.

    The kinds are named ``LoopLaw.P``, ``LoopLaw.PID``, ``LoopLaw.STATE_FEEDBACK`` and
    ``LoopLaw.THESIS``. The kernel does no bounds checks, so every shape it indexes is checked
    here: a field that does not fit its kind raises :class:`~rcm_kin.errors.RcmKinError` naming it.
    """

    P: ClassVar[int] = P
    PID: ClassVar[int] = PID
    STATE_FEEDBACK: ClassVar[int] = STATE_FEEDBACK
    THESIS: ClassVar[int] = THESIS

    kind: int                    # P, PID, STATE_FEEDBACK, THESIS
    memory: np.ndarray           # the controller's initial memory, initial_memory(hold)
    gains: np.ndarray = field(default_factory=lambda: _floats(6))
    flags: np.ndarray = field(default_factory=lambda: np.zeros(4, dtype=bool))
    roll_deg: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))    # (nr,) table grid
    pitch_deg: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0]))   # (np,)
    table: np.ndarray = field(default_factory=lambda: _floats((2, 2, 7)))   # (np, nr, 7)
    hold: np.ndarray = field(default_factory=lambda: _floats((2, 2, 2)))    # (np, nr, 2)
    friction: np.ndarray = field(default_factory=lambda: _floats(3))

    def __post_init__(self):
        """Every array checked against what the kind reads (sizes, shapes against the grids,
        finite values) and stored as the kernel's types (contiguous floats, bool flags), so that
        one compiled specialisation serves every law; the gains padded to 6 and the table to 7 values."""
        if isinstance(self.kind, bool) or self.kind not in KINDS:
            raise _refuse("kind", f"unknown kernel law kind {self.kind} (one of {', '.join(KIND_NAMES)})")
        kind = int(self.kind)
        arrays = {"memory": self._memory(kind), "gains": self._gains(kind), "flags": self._flags()}
        arrays["roll_deg"] = _grid("roll_deg", np.asarray(self.roll_deg, dtype=float))
        arrays["pitch_deg"] = _grid("pitch_deg", np.asarray(self.pitch_deg, dtype=float))
        grid = (arrays["pitch_deg"].size, arrays["roll_deg"].size)
        arrays["table"] = self._table(kind, grid)
        arrays["hold"] = self._hold(kind, grid, arrays["flags"])
        arrays["friction"] = self._friction(kind, arrays["flags"])
        object.__setattr__(self, "kind", kind)
        for name, value in arrays.items():
            object.__setattr__(self, name, np.ascontiguousarray(value))

    def _memory(self, kind: int) -> np.ndarray:
        memory = np.asarray(self.memory, dtype=float).ravel()
        if memory.size != MEMORY[kind]:
            raise _refuse("memory", f"the {KIND_NAMES[kind]} law keeps {MEMORY[kind]} values, got {memory.size}")
        integrals = memory[:2] if kind == PID else memory          # the PID's previous errors may be NaN (none yet)
        if not np.all(np.isfinite(integrals)) or np.any(np.isinf(memory)):
            raise _refuse("memory", "values must be finite (NaN only as the PID's previous errors)")
        return memory

    def _gains(self, kind: int) -> np.ndarray:
        given = _finite("gains", np.asarray(self.gains, dtype=float).ravel())
        sizes = GAINS.get(kind, tuple(range(7)))
        if given.size not in sizes:
            raise _refuse("gains", f"the {KIND_NAMES[kind]} law reads {' or '.join(map(str, sizes))} gains, "
                                   f"got {given.size}" if kind in GAINS else f"at most 6 gains, got {given.size}")
        gains = np.zeros(6)
        gains[:given.size] = given
        return gains

    def _flags(self) -> np.ndarray:
        flags = np.asarray(self.flags).ravel()
        if flags.size != 4:
            raise _refuse("flags", f"4 flags (scheduled, gravity, track_velocity, friction), got {flags.size}")
        return flags.astype(bool)

    def _table(self, kind: int, grid: tuple[int, int]) -> np.ndarray:
        table = _finite("table", np.asarray(self.table, dtype=float))
        least = TABLE_VALUES.get(kind, 1)
        if table.ndim != 3 or table.shape[:2] != grid or not least <= table.shape[2] <= 7:
            values = "7" if least == 7 else f"{least} to 7"
            raise _refuse("table", f"shape (pitch {grid[0]}, roll {grid[1]}, {values} values) on the grids, "
                                   f"got {table.shape}")
        return np.concatenate([table, np.zeros(grid + (7 - table.shape[2],))], axis=-1)

    def _hold(self, kind: int, grid: tuple[int, int], flags: np.ndarray) -> np.ndarray:
        hold = _finite("hold", np.asarray(self.hold, dtype=float))
        if kind == STATE_FEEDBACK and flags[1] and hold.shape != grid + (2,):
            raise _refuse("hold", f"shape (pitch {grid[0]}, roll {grid[1]}, 2) on the grids, got {hold.shape}")
        return hold

    def _friction(self, kind: int, flags: np.ndarray) -> np.ndarray:
        friction = _finite("friction", np.asarray(self.friction, dtype=float).ravel())
        if friction.size != 3:
            raise _refuse("friction", f"3 values (roll, pitch amplitudes, ramp), got {friction.size}")
        if kind == STATE_FEEDBACK and flags[3] and not friction[2] > 0:
            raise _refuse("friction", f"the ramp friction[2] must be > 0 deg/s, got {friction[2]}")
        return friction


def stacked(roll, pitch, *tables) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(roll grid, pitch grid, values)`` of tables on one roll x pitch grid (degrees), stacked
    along the last axis: ``values[j, i]`` at pitch ``pitch[j]``, roll ``roll[i]``."""
    return (np.asarray(roll, dtype=float), np.asarray(pitch, dtype=float),
            np.concatenate([np.asarray(t, dtype=float) for t in tables], axis=-1))

"""A :class:`LoopLaw` the kernel could not index is refused when it is made (the C kernel does no bounds
checks: a short memory or a table smaller than its grids would be read and written out of
bounds), the field at fault named."""

from __future__ import annotations

import numpy as np
import pytest

from rcm_kin.errors import RcmKinError
from rcm_kin.simulation import LoopLaw

GRID = np.array([-20.0, 0.0, 20.0])


def _scheduled(**fields):
    base = dict(memory=np.zeros(1), roll_deg=GRID, pitch_deg=GRID, table=np.zeros((3, 3, 7)))
    return LoopLaw(LoopLaw.STATE_FEEDBACK, **{**base, **fields})


@pytest.mark.parametrize("make, field", [
    (lambda: LoopLaw(7, np.zeros(0)), "kind"),
    (lambda: LoopLaw(True, np.zeros(0)), "kind"),
    (lambda: LoopLaw(LoopLaw.PID, np.zeros(1), gains=np.ones(6)), "memory"),
    (lambda: LoopLaw(LoopLaw.P, np.zeros(1), gains=np.ones(2)), "memory"),
    (lambda: LoopLaw(LoopLaw.THESIS, np.zeros(0)), "memory"),
    (lambda: LoopLaw(LoopLaw.PID, [np.nan, 0.0, np.nan, np.nan], gains=np.ones(6)), "memory"),
    (lambda: LoopLaw(LoopLaw.PID, [0.0, 0.0, np.inf, 0.0], gains=np.ones(6)), "memory"),
    (lambda: LoopLaw(LoopLaw.PID, np.zeros(4), gains=np.ones(2)), "gains"),
    (lambda: LoopLaw(LoopLaw.P, np.zeros(0), gains=np.ones(3)), "gains"),
    (lambda: LoopLaw(LoopLaw.P, np.zeros(0), gains=[1.0, np.nan]), "gains"),
    (lambda: LoopLaw(LoopLaw.THESIS, np.zeros(1), gains=np.ones(7)), "gains"),
    (lambda: _scheduled(table=np.zeros((2, 2, 7))), "table"),           # a 3 x 3 grid, a 2 x 2 table
    (lambda: _scheduled(table=np.zeros((3, 3, 5))), "table"),           # the state feedback reads 7 values
    (lambda: _scheduled(table=np.zeros((3, 3, 8))), "table"),
    (lambda: _scheduled(table=np.zeros((3, 3))), "table"),
    (lambda: _scheduled(table=np.full((3, 3, 7), np.inf)), "table"),
    (lambda: LoopLaw(LoopLaw.THESIS, np.zeros(1), roll_deg=GRID, pitch_deg=GRID, table=np.zeros((3, 3, 4))),
     "table"),
    (lambda: _scheduled(roll_deg=np.array([0.0]), table=np.zeros((3, 1, 7))), "roll_deg"),
    (lambda: _scheduled(roll_deg=np.array([0.0, 0.0, 1.0])), "roll_deg"),
    (lambda: _scheduled(pitch_deg=np.array([1.0, 0.0, -1.0])), "pitch_deg"),
    (lambda: _scheduled(pitch_deg=np.array([0.0, np.nan, 1.0])), "pitch_deg"),
    (lambda: _scheduled(flags=np.zeros(3, dtype=bool)), "flags"),
    (lambda: _scheduled(flags=[False, True, True, False], hold=np.zeros((2, 2, 2))), "hold"),
    (lambda: _scheduled(flags=[False, True, True, False], hold=np.zeros((3, 3, 1))), "hold"),
    (lambda: _scheduled(friction=np.zeros(2)), "friction"),
    (lambda: _scheduled(flags=[True, False, True, True], friction=np.array([10.0, 10.0, 0.0])), "friction"),
    (lambda: _scheduled(friction=np.array([np.nan, 10.0, 1.0])), "friction"),
])
def test_a_law_the_kernel_cannot_index_is_refused(make, field):
    with pytest.raises(RcmKinError, match=f"LoopLaw `{field}`") as caught:
        make()
    assert caught.value.parameter == field


def test_laws_that_fit_are_taken_as_the_kernel_types():
    p = LoopLaw(LoopLaw.P, np.zeros(0), gains=[35, 60])
    assert p.gains.tolist() == [35.0, 60.0, 0, 0, 0, 0] and p.memory.dtype == float and p.flags.dtype == bool
    pid = LoopLaw(LoopLaw.PID, [0.0, 0.0, np.nan, np.nan], gains=np.arange(6.0))
    assert np.isnan(pid.memory[2:]).all()
    thesis = LoopLaw(LoopLaw.THESIS, np.zeros(1), roll_deg=GRID, pitch_deg=GRID[:2], table=np.ones((2, 3, 5)))
    assert thesis.table.shape == (2, 3, 7) and np.all(thesis.table[..., 5:] == 0)
    scheduled = _scheduled(flags=[True, True, True, True], hold=np.zeros((3, 3, 2)), friction=[5.0, 5.0, 2.0])
    assert scheduled.kind == LoopLaw.STATE_FEEDBACK and scheduled.flags.all()

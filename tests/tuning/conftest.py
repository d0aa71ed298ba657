"""Shared fixtures of the tuning tests: building a draw costs about half a second, so the sets are
tiny (2-3 draws, the sinusoid only, coarse grids) and built once per session."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture(scope="session")
def thesis_poses() -> np.ndarray:
    """The thesis grid's nine poses (roll -20/0/20 x pitch -15/0/15 deg, written out here rather
    than read from the code under test) at the holds' insertion, 80 mm: (9, 3) rad, rad, m."""
    return np.array([[np.radians(r), np.radians(p), 0.080] for p in (-15.0, 0.0, 15.0) for r in (-20.0, 0.0, 20.0)])


@pytest.fixture(scope="session")
def smooth_model(psm, params):
    """The shipped set's driven-joint model without Coulomb friction (the loops' and holds' model)."""
    from rcm_kin.dynamics.state_space import driven_dynamics
    return driven_dynamics(psm, params, coulomb=False)


@pytest.fixture(scope="session")
def nominal_draws(params):
    """Two draws of the shipped set, the first the set itself, the sinusoid only, a 2 x 2 loop grid."""
    from rcm_kin.tuning.draws import build_draws
    return build_draws(params, 2, seed=0, points=2, experiments=("sine",), nominal_first=True)

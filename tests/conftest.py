"""Shared fixtures. Tests read ``../shared/`` only through ``shared_data``, which skips when absent."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture(scope="session", autouse=True)
def compiled_cache(tmp_path_factory) -> Path:
    """Compiled CasADi functions go to a fresh folder: every run starts from an empty cache,
    as CI does, and never touches the user's ``~/.cache``."""
    folder = tmp_path_factory.mktemp("xdg_cache")
    os.environ["XDG_CACHE_HOME"] = str(folder)
    return folder


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """The measured PSM logs beside the project (reference material, never committed)."""
    if not (SHARED_DATA / "psm-sysid").is_dir():
        pytest.skip(f"measured PSM logs not found at {SHARED_DATA} (reference data lives beside the project)")
    return SHARED_DATA


@pytest.fixture(scope="session")
def psm():
    from rcm_kin import load_robot
    return load_robot("psm")


@pytest.fixture(scope="session")
def mtm():
    from rcm_kin import load_robot
    return load_robot("mtm")


@pytest.fixture(scope="session")
def params():
    """The shipped drive parameters."""
    from rcm_kin.dynamics.drive import load_drive_parameters
    return load_drive_parameters()


@pytest.fixture(scope="session")
def model(psm, params):
    """The PSM's driven-joint dynamics with the shipped parameters (Coulomb friction included)."""
    from rcm_kin.dynamics.state_space import driven_dynamics
    return driven_dynamics(psm, params)

"""Gain schedules kept on disk, as the compiled functions are: a design is done once per parameter
set, model and code, not once per process.

:func:`cached_schedule` returns the schedule stored under a key (:func:`schedule_key`: the caller's
description of what the design depends on, e.g. the parameter set's exact values and the robot's
files, together with the source of the modules a design runs through and the versions of NumPy,
SciPy, CasADi and Pinocchio), else designs it and stores it. The files live in
``$XDG_CACHE_HOME/rcm-kin/schedules`` (beside :func:`rcm_kin.symbolic.compiled.cache_folder`), one
``.npz`` (no pickles) per key, each with a checksum file as the compiled libraries have
(:func:`rcm_kin.symbolic.compiled.library_mismatch`); a file that does not match, or does not read,
is deleted and designed anew with one warning; the :data:`CACHE_SCHEDULES` most recently used are
kept. A schedule read back is the designed one bit for bit (the tables are stored as float64).
"""

from __future__ import annotations

import functools
import hashlib
import io
import os
import zipfile
from collections.abc import Callable
from dataclasses import astuple, fields
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import casadi as ca
import numpy as np
import pinocchio as pin

from rcm_kin.atomic import write_bytes, write_text
from rcm_kin.control.friction import FrictionCompensation
from rcm_kin.control.gain_schedule import GainSchedule
from rcm_kin.control.weights import Weights
from rcm_kin.errors import warn
from rcm_kin.symbolic.compiled import cache_folder, cache_key, checksum_file, library_mismatch, prune_cache

CACHE_SCHEDULES = 64      # schedule files kept (each a few kB for the thesis grid)
TABLES = ("roll_deg", "pitch_deg", "k_roll", "k_pitch", "u_hold", "ff_pitch", "A", "B", "A_cl")
# the code a design runs through (relative to the package): a change in any of them designs anew
SOURCES = ("control", "dynamics", "model", "symbolic", "kinematics", "errors.py", "hardware.py",
           "firmware_rules.py", "thesis.py")


def schedule_folder() -> Path:
    """Where designed schedules are kept: ``$XDG_CACHE_HOME/rcm-kin/schedules`` (default ``~/.cache``)."""
    return cache_folder().parent / "schedules"


@functools.cache
def source_digest() -> str:
    """SHA-256 (hex) of the source of the modules a design runs through (:data:`SOURCES`)."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for entry in SOURCES:
        path = root / entry
        for file in sorted(path.rglob("*.py")) if path.is_dir() else [path]:
            digest.update(file.relative_to(root).as_posix().encode() + b"\0" + file.read_bytes() + b"\0")
    return digest.hexdigest()


def _scipy_version() -> str:
    try:
        return version("scipy")
    except PackageNotFoundError:          # pragma: no cover - SciPy is a dependency
        return "unknown"


def schedule_key(*parts: str) -> str:
    """The cache key of a design described by ``parts``, the code (:func:`source_digest`) and the
    numerical libraries' versions."""
    versions = f"numpy {np.__version__} scipy {_scipy_version()} casadi {ca.__version__} pinocchio {pin.__version__}"
    return cache_key(*parts, source_digest(), versions)


def cached_schedule(key: str, design: Callable[[], GainSchedule]) -> GainSchedule:
    """The schedule stored under ``key`` (a :func:`schedule_key`), else ``design()``, stored. A cache
    folder that cannot be written leaves the design unstored (one warning)."""
    path = schedule_folder() / f"schedule_{key[:32]}.npz"
    if path.exists():
        reason = library_mismatch(path, key)
        if reason is None:
            try:
                schedule = _read(path)
                os.utime(path)
                return schedule
            except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
                reason = f"does not read ({exc})"
        warn(f"the cached gain schedule {path} {reason}: deleted and designed anew")
        path.unlink(missing_ok=True)
    schedule = design()
    try:
        _write(path, key, schedule)
    except OSError as exc:
        warn(f"cannot write the gain-schedule cache {path.parent} ({exc.strerror}): the design is not kept")
    return schedule


def _write(path: Path, key: str, schedule: GainSchedule) -> None:
    buffer = io.BytesIO()
    friction = schedule.friction
    np.savez(buffer, insertion=np.float64(schedule.insertion), weights=np.array(astuple(schedule.weights), float),
             friction=np.array([*friction.pwm, friction.ramp_deg_s] if friction else [], float),
             **{name: np.asarray(getattr(schedule, name), dtype=float) for name in TABLES})
    data = buffer.getvalue()
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(checksum_file(path), f"{hashlib.sha256(data).hexdigest()} {key}\n")
    write_bytes(path, data)
    prune_cache(path.parent, keep=path, limit=CACHE_SCHEDULES, pattern="*.npz")


def _read(path: Path) -> GainSchedule:
    with np.load(io.BytesIO(path.read_bytes()), allow_pickle=False) as data:
        tables = {name: np.array(data[name]) for name in TABLES}
        weights = Weights(**{f.name: float(v) for f, v in zip(fields(Weights), data["weights"], strict=True)})
        friction = data["friction"]
        compensation = FrictionCompensation((float(friction[0]), float(friction[1])), float(friction[2])) \
            if friction.size else None
        return GainSchedule(insertion=float(data["insertion"]), weights=weights, friction=compensation, **tables)

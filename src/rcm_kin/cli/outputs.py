"""The command's outputs: a new output file or an output folder, claimed for the run
(:func:`rcm_kin.atomic.claim`: a folder locked, only rcm-kin's own files replaced without
``--force``; a file another run writes meanwhile not replaced), and the ``--force`` options."""

from __future__ import annotations

import argparse
import contextlib
from pathlib import Path

from rcm_kin.atomic import claim
from rcm_kin.errors import RcmKinError


def new_output(path: str, force: bool, suffixes: tuple[str, ...] = ()) -> Path:
    """``path`` as a file the command may write: a clear error if it is empty, a folder, has none of
    ``suffixes`` (when given), exists and ``force`` is off, or its folder does not exist."""
    if not str(path).strip():
        raise RcmKinError("an empty output path")
    out = Path(path)
    if suffixes and out.suffix.lower() not in suffixes:
        raise RcmKinError(f"{out}: the output file must end in {' or '.join(suffixes)}")
    if out.is_dir():
        raise RcmKinError(f"{out} is a folder: give a file name")
    if out.exists() and not force:
        raise RcmKinError(f"{out} exists: choose another output file or add --force")
    if not out.parent.is_dir():
        raise RcmKinError(f"no folder {out.parent} for {out.name}")
    _own(out, folder=False, force=force)
    return out


def new_folder(path, force: bool = False) -> Path:
    """``path`` as the run's output folder (created): locked for the run, and its files replaced only
    when rcm-kin wrote them or with ``force`` (:func:`rcm_kin.atomic.claim`)."""
    if not str(path).strip():
        raise RcmKinError("an empty output folder")
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise RcmKinError(f"{out} is a file: give a folder")
    _own(out, folder=True, force=force)
    return out


_RUN: list[contextlib.ExitStack] = []


@contextlib.contextmanager
def owned_outputs():
    """The command's run: the outputs claimed by :func:`new_output` and :func:`new_folder` are
    held until it ends (locks released, manifests written)."""
    with contextlib.ExitStack() as stack:
        _RUN.append(stack)
        try:
            yield
        finally:
            _RUN.remove(stack)


def _own(path: Path, *, folder: bool, force: bool) -> None:
    if _RUN:
        _RUN[-1].enter_context(claim(path, folder=folder, force=force))


def add_force(parser: argparse.ArgumentParser, help_text: str = "overwrite the output file if it exists") -> None:
    parser.add_argument("--force", action="store_true", help=help_text)


FOLDER_FORCE = "replace files in the output folder that rcm-kin did not write (or that changed since)"

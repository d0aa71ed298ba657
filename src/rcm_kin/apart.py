"""Two pieces of work at once on two cores, without a pool: one in a forked child process, the
other here (:func:`run_apart`). For work done in Python, which one process runs on one core (its
GIL), such as drawing figures; the child inherits what this process built, nothing is pickled
to it, and only its result comes back (pickled, through a pipe)."""

from __future__ import annotations

import contextlib
import gc
import os
import pickle
import signal
import sys
import threading
from typing import Callable

from rcm_kin.errors import RcmKinError, recording_warnings, reissue


def cores() -> int:
    """The cores this process may use. A declared twin of :func:`rcm_kin.parallel.machine_workers`
    (that module imports asyncio and multiprocessing, a twentieth of a second of a short command;
    tests/plotting/test_draw_apart.py holds the two equal)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def in_a_worker() -> bool:
    """Whether this process is a multiprocessing worker (a process pool's, e.g. the report's)."""
    started = sys.modules.get("multiprocessing")      # not imported: not one
    return started is not None and started.parent_process() is not None


def run_apart(forked: Callable[[], object], here: Callable[[], object], fork: bool = True,
              what: str = "the forked process") -> tuple[object, object]:
    """``forked()`` in a forked child process while this process runs ``here()``; their results
    (``forked()``'s warnings raised here). One after the other in this process without ``fork``,
    a second core (:func:`cores`), in a pool's worker process (:func:`in_a_worker`: the pool has
    the cores, and a worker it stops would leave the child behind), or while another thread runs
    (a lock it holds at the fork, e.g. in a notebook's kernel, would stay held in the child: start
    threads after the fork, in ``here``).

    The child's error is raised here once both have ended: an RcmKinError or OSError as it was,
    anything else as an RcmKinError naming it (one line, ``what`` naming the child). The child
    takes the default action on SIGINT and SIGTERM unless this process ignores them (Ctrl-C
    reaches the whole process group: the child ends at once); when this process stops (an
    error, Ctrl-C, SIGTERM) it ends the child and waits for it, so no process is left. A file the
    child was writing is left as an unfinished temporary, which the output folder's claim clears
    (:func:`rcm_kin.atomic.claim`); one it finished is whole. Known limit: a file the child
    finishes between this process's SIGTERM and the child's own (microseconds) is committed,
    whole.

    Call it under :func:`paused_collector` to spare both parts the garbage collector's scans."""
    if not fork or cores() < 2 or in_a_worker() or threading.active_count() > 1:
        return forked(), here()
    return _apart(forked, here, what)


@contextlib.contextmanager
def paused_collector():
    """The cyclic garbage collector off while the block runs (in a child forked meanwhile too), as it
    was after. For a bounded burst of object-making work such as importing matplotlib and drawing
    figures: its collections scanned every object made since the start again and again (about
    50 ms of a ``torque-map``'s imports and 60-70 ms of its figures, one full collection among
    them), and would write to the pages of the objects a forked child shares, copying them. What
    the block leaves as cyclic garbage is collected after it."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _apart(forked: Callable[[], object], here: Callable[[], object], what: str) -> tuple[object, object]:
    """:func:`run_apart` on two processes: the fork, the child's result read from the pipe when
    ``here()`` is done, the child waited for (and ended first when this process stops)."""
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        _child(forked, read, write, what)          # never returns
    os.close(write)
    with os.fdopen(read, "rb") as pipe:
        try:
            mine = here()
            sent = pipe.read()
        except BaseException:
            _end(pid, signal.SIGTERM)
            raise
    status = _end(pid, None)
    if not sent:
        raise RcmKinError(f"{what} ended without its result ({_ended(status)})")
    kind, value, raised = pickle.loads(sent)
    if kind == "error":
        raise value
    reissue(raised)
    return value, mine


def _child(forked: Callable[[], object], read: int, write: int, what: str) -> None:
    """The forked process of :func:`run_apart`: ``forked()``'s outcome pickled into ``write``, then
    the process ends (``os._exit``: nothing of the parent's, its buffers or clean-up, runs twice)."""
    status = 1
    try:
        os.close(read)
        for sig in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(sig) is not signal.SIG_IGN:    # ignored stays ignored, as in this process
                signal.signal(sig, signal.SIG_DFL)
        try:
            outcome = ("value", *recording_warnings(forked))
        except Exception as exc:  # noqa: BLE001 - sent to the parent, which raises it
            outcome = ("error", portable(exc, what), [])
        with os.fdopen(write, "wb") as pipe:
            pickle.dump(outcome, pipe)
        status = 0
    finally:
        os._exit(status)


def portable(exc: Exception, what: str = "the forked process") -> Exception:
    """``exc`` as the parent raises it: an RcmKinError or OSError that survives pickling as it is,
    anything else an RcmKinError naming it, ``what`` failed (the command line prints one line)."""
    if isinstance(exc, (RcmKinError, OSError)):
        with contextlib.suppress(Exception):
            pickle.loads(pickle.dumps(exc))
            return exc
    return RcmKinError(f"{what} failed: {type(exc).__name__}: {exc}")


def _end(pid: int, sig: int | None) -> int:
    """Send ``sig`` (if any) to the child ``pid``, wait for it to end; its wait status."""
    if sig is not None:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, sig)
    return os.waitpid(pid, 0)[1]


def _ended(status: int) -> str:
    """A child's wait status in words."""
    if os.WIFSIGNALED(status):
        return f"stopped by {signal.Signals(os.WTERMSIG(status)).name}"
    return f"exit status {os.waitstatus_to_exitcode(status)}"

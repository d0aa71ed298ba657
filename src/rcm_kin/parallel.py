"""Batches of independent work on a ``dask.distributed`` cluster, or for small runs on a pool of
forked processes (:func:`map_local`: no cluster to start), generic plumbing.

Without a scheduler address a run starts an embedded :class:`~distributed.LocalCluster` sized
to the machine (one worker process per core, one thread each: the simulations are pure Python
and NumPy, which threads would serialise); with ``tcp://HOST:PORT`` it runs on an existing
cluster (``dask scheduler`` and ``dask worker ADDRESS`` processes). Every worker needs rcm-kin
importable. Batches are gathered in order, so results do not depend on the cluster. Dask is
imported when a cluster is used, not when this module is.
"""

from __future__ import annotations

import asyncio
import logging
import math
import multiprocessing
import os
import signal
import sys
from concurrent.futures import ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Callable, Iterator, Sequence

from tqdm import tqdm

from rcm_kin.errors import RcmKinError, WorkLimitError, recording_warnings, reissue

CONNECT_SECONDS = 10.0      # to reach an existing scheduler and hear it answer
# at most this many samples run on a local pool of forked processes rather than an embedded Dask
# cluster, whose start costs about 4.5 s (docs/performance.md): 64 robustness samples are about
# 40 s of CPU with their compiles, so the cluster's start is a tenth of a larger run at most
LOCAL_ITEMS = 64
BATCHES_PER_WORKER = 4      # default batch size: about this many batches per worker, for balance


def machine_workers() -> int:
    """Worker processes of the embedded cluster: the cores this process may use."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None) -> Iterator:
    """A ``distributed.Client``: on the scheduler at ``scheduler`` (``tcp://HOST:PORT``), or on an
    embedded local cluster of ``workers`` processes (default :func:`machine_workers`), one thread
    each, closed on exit."""
    from distributed import Client, LocalCluster

    if scheduler is None:
        n = workers or machine_workers()
        check_workers(n)
        _quiet_resource_tracker()
        # silence_logs: the workers' "Compute Failed" reports would precede the one-line error
        # preload: this module's dask_setup, in each worker process (Ctrl-C is the parent's to handle)
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                          silence_logs=logging.CRITICAL, preload=[__name__]) as cluster, Client(cluster) as client:
            yield client
        return
    check_scheduler(scheduler)
    try:
        client = Client(scheduler, timeout=f"{CONNECT_SECONDS}s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise RcmKinError(f"cannot reach a Dask scheduler at {scheduler}: {exc}") from None
    with client:
        yield client


def _quiet_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (if not running) with its leak report off: it
    unlinks the semaphores a cluster stopped by a signal leaves behind, then says so on stderr after
    the run's one error line."""
    from multiprocessing import resource_tracker

    flags = sys.warnoptions
    sys.warnoptions = [*flags, "ignore:resource_tracker:UserWarning"]
    try:
        resource_tracker.ensure_running()
    finally:
        sys.warnoptions = flags


def check_scheduler(address: str, seconds: float = CONNECT_SECONDS) -> None:
    """Refuse ``address`` unless a Dask scheduler answers there within ``seconds``: connected, the
    comm handshake done and its ``identity`` a scheduler's. (``distributed.Client`` waits for the
    handshake without a timeout, and takes any bytes for a frame length.)"""
    from distributed.comm import connect
    from distributed.security import Security

    async def identity():
        comm = await connect(address, timeout=seconds, **Security().get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    try:
        answer = asyncio.run(asyncio.wait_for(identity(), seconds))
    except (TimeoutError, asyncio.TimeoutError):
        what = f"no Dask handshake within {seconds:g} s"
    except (OSError, ValueError) as exc:
        what = str(exc) or type(exc).__name__
    except Exception as exc:        # whatever bytes a service that is not Dask's sent back
        what = f"the service there does not speak Dask's protocol ({type(exc).__name__} reading its answer)"
    else:
        kind = answer.get("type") if isinstance(answer, dict) else None
        if kind == "Scheduler":
            return
        what = f"the service there is {'a Dask ' + kind if kind else 'not a Dask scheduler'}"
    raise RcmKinError(f"cannot reach a Dask scheduler at {address}: {what}")


def dask_setup(worker) -> None:
    """Dask's preload hook, run in each worker process of the embedded cluster: the worker ignores
    SIGINT (Ctrl-C reaches the whole process group; the parent closes the cluster, which stops the
    workers, and prints the one line)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


WORKERS_PER_CORE = 4
"""Local worker processes allowed per core: more only share the cores and take memory (each worker
holds its own Python, NumPy and model, 150-300 MB)."""


def check_workers(n: int, parameter: str = "workers") -> int:
    """``n`` local worker processes, or an error: at least 1 and at most :data:`WORKERS_PER_CORE`
    per core of this machine (a run's memory is bounded by the machine's cores)."""
    limit = WORKERS_PER_CORE * machine_workers()
    if n < 1:
        raise RcmKinError(f"the local cluster needs at least 1 worker, got {n}", parameter=parameter)
    if n > limit:
        raise WorkLimitError(f"{n} local worker processes on {machine_workers()} cores: at most {limit} "
                             f"({WORKERS_PER_CORE} per core; each holds 150-300 MB)", requested=n, limit=limit,
                             parameter=parameter)
    return n


def quiet_worker() -> None:
    """Initializer of every worker process rcm_kin starts: SIGINT (Ctrl-C reaches the whole process
    group) and SIGTERM end it at once, without a traceback; the parent prints the one line."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


@contextmanager
def process_pool(workers: int, fork: bool = True) -> Iterator[ProcessPoolExecutor]:
    """A ``ProcessPoolExecutor`` of ``workers`` :func:`quiet_worker` processes (forked, so that
    they inherit what the parent built, when ``fork``). When the block raises (an error, Ctrl-C,
    SIGTERM) the jobs not started are cancelled and the running ones stopped, not waited for."""
    context = multiprocessing.get_context("fork" if fork else None)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=quiet_worker)
    try:
        yield pool
    except BaseException:
        processes = list((getattr(pool, "_processes", None) or {}).values())   # the stdlib's: no public handle
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(5)
        raise
    pool.shutdown()


def batches_of(items: Sequence, batch_size: int) -> list[list]:
    """``items`` cut in consecutive batches of ``batch_size`` (the last may be shorter)."""
    if batch_size < 1:
        raise RcmKinError(f"the batch size must be at least 1, got {batch_size}")
    return [list(items[k:k + batch_size]) for k in range(0, len(items), batch_size)]


def default_batch_size(items: int, workers: int) -> int:
    """About :data:`BATCHES_PER_WORKER` batches per worker."""
    return max(1, math.ceil(items / (BATCHES_PER_WORKER * max(workers, 1))))


def map_batches(client, function: Callable, batches: list, progress: bool = True, desc: str = "batches",
                on_batch: Callable[[int], None] | None = None, **shared) -> list:
    """``function(batch, **shared)`` for every batch on ``client``'s cluster; the results in batch
    order. A progress bar on stderr when ``progress``; ``on_batch(done)`` after each batch that
    finishes (done = how many have)."""
    from distributed import as_completed

    futures = client.map(recording_warnings, [function] * len(batches), batches, pure=False, **shared)
    with tqdm(total=len(futures), desc=desc, unit="batch", file=sys.stderr, disable=not progress) as bar:
        for done, _ in enumerate(as_completed(futures), start=1):
            bar.update()
            if on_batch:
                on_batch(done)
    return _reissued(client.gather(futures))      # the workers' warnings, raised here


def map_local(function: Callable, batches: list, workers: int, progress: bool = True, desc: str = "batches",
              on_batch: Callable[[int], None] | None = None, **shared) -> list:
    """:func:`map_batches` without a cluster: ``function(batch, **shared)`` for every batch on a pool
    of ``workers`` forked processes (in this process for one worker or one batch); the results in
    batch order, the workers' warnings raised here, the first error raised here."""
    with tqdm(total=len(batches), desc=desc, unit="batch", file=sys.stderr, disable=not progress) as bar:
        def tick(done: int) -> None:
            bar.update()
            if on_batch:
                on_batch(done)

        if check_workers(workers) == 1 or len(batches) <= 1:
            outcomes = []
            for done, batch in enumerate(batches, start=1):
                outcomes.append(recording_warnings(function, batch, **shared))
                tick(done)
        else:
            with process_pool(min(workers, len(batches))) as pool:      # an error or a signal stops it
                futures = [pool.submit(recording_warnings, function, batch, **shared) for batch in batches]
                for done, future in enumerate(as_completed(futures), start=1):
                    future.result()
                    tick(done)
                outcomes = [future.result() for future in futures]
    return _reissued(outcomes)


def _reissued(outcomes) -> list:
    """The values of ``(value, warnings)`` outcomes (:func:`recording_warnings`'), their warnings raised here."""
    results = []
    for value, raised in outcomes:
        reissue(raised)
        results.append(value)
    return results

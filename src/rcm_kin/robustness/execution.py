"""The robustness study's batches on a ``dask.distributed`` cluster (:mod:`rcm_kin.parallel`), or,
for a small run without a scheduler, on a pool of forked processes.

Without a scheduler address the run starts an embedded :class:`~distributed.LocalCluster` sized
to the machine (one worker process per core, one thread each: the simulations are pure Python
and NumPy, which threads would serialise); with ``tcp://HOST:PORT`` it runs on an existing
cluster (``dask scheduler`` and ``dask worker ADDRESS`` processes; see the README). Every worker
needs rcm-kin importable; what it builds (models, the gain schedule, the reference) it builds once
and keeps in its process (:mod:`rcm_kin.robustness.task`).

Results do not depend on the cluster: each sample draws from its own seed
(:func:`rcm_kin.robustness.sampling.sample_seeds`), batches are gathered in order, and a batch
is a pure function of its arguments. A worker lost mid-run costs only time: the scheduler
re-runs its batches elsewhere (up to ``distributed.scheduler.allowed-failures`` losses per
batch). A batch that raised is not retried: a batch is deterministic, so its error (an
:class:`~rcm_kin.errors.RcmKinError` for a user error) reaches the client at once. What can be
checked before a cluster starts is checked by the callers (:mod:`rcm_kin.robustness.work`).
"""

from __future__ import annotations

from contextlib import nullcontext
from typing import Callable

from rcm_kin.parallel import (
    LOCAL_ITEMS,
    batches_of,
    dask_client,
    default_batch_size,
    machine_workers,
    map_batches,
    map_local,
)
from rcm_kin.robustness.sampling import sample_seeds
from rcm_kin.robustness.statistics import Robustness, summarise
from rcm_kin.robustness.task import Study, run_batch
from rcm_kin.robustness.work import check_robustness


def _batch(batch, study: Study):
    return run_batch(study, batch)


def run_in_process(study: Study, samples: int, seed: int = 0) -> Robustness:
    """The same samples one after another in this process, no cluster (for a caller that is a
    worker of a pool already, such as the report): equal to :func:`run_robustness` for the same
    seed (a seed per sample)."""
    check_robustness(study, samples)
    return summarise(study, seed, run_batch(study, list(enumerate(sample_seeds(seed, samples)))))


def run_robustness(study: Study, samples: int, seed: int = 0, client=None, batch_size: int | None = None,
                   progress: bool = True, on_batch: Callable[[int], None] | None = None,
                   workers: int | None = None) -> Robustness:
    """``samples`` samples of ``study`` on ``client``'s cluster, seeded by ``seed``; the same result
    whatever the cluster and the batch size. Without a client: at most
    :data:`~rcm_kin.parallel.LOCAL_ITEMS` samples on a pool of ``workers`` forked processes
    (:func:`~rcm_kin.parallel.map_local`: no cluster's start to pay), more on an embedded local
    cluster of ``workers`` (default: the cores this process may use). The work is checked first
    (:func:`rcm_kin.robustness.work.check_robustness`)."""
    check_robustness(study, samples)
    seeds = list(enumerate(sample_seeds(seed, samples)))
    if client is None and samples <= LOCAL_ITEMS:
        workers = workers or machine_workers()
        batches = batches_of(seeds, batch_size or default_batch_size(samples, workers))
        results = map_local(_batch, batches, workers, progress, "robustness", on_batch, study=study)
        return summarise(study, seed, [outcome for batch in results for outcome in batch])
    with dask_client(workers=workers) if client is None else nullcontext(client) as client:
        if batch_size is None:
            batch_size = default_batch_size(samples, len(client.nthreads()))
        results = map_batches(client, _batch, batches_of(seeds, batch_size), progress, "robustness", on_batch,
                              study=study)
    return summarise(study, seed, [outcome for batch in results for outcome in batch])

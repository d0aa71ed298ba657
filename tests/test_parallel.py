"""The local pool of forked processes (rcm_kin.parallel.map_local): results in batch order, the
workers' warnings raised in the caller, an error raised in the caller; and a small robustness run
without a cluster equal to the serial computation."""

from __future__ import annotations

import os
import warnings

import pytest

from rcm_kin.errors import CompilerFallbackWarning, RcmKinError
from rcm_kin.parallel import map_local


def pid_and_sum(batch, offset=0):
    warnings.warn(f"batch of {len(batch)}", CompilerFallbackWarning)
    return os.getpid(), sum(batch) + offset


def refuse(batch):
    if 3 in batch:
        raise RcmKinError("refused on the worker")
    return batch


@pytest.mark.parametrize("workers", [1, 2])
def test_results_in_batch_order_with_the_warnings(workers):
    batches = [[1, 2], [3], [4, 5, 6], [7]]
    done = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = map_local(pid_and_sum, batches, workers, progress=False, on_batch=done.append, offset=10)
    assert [r[1] for r in results] == [13, 13, 25, 17]
    assert done == [1, 2, 3, 4]
    assert sorted(str(w.message) for w in caught if w.category is CompilerFallbackWarning) == [
        "batch of 1", "batch of 1", "batch of 2", "batch of 3"]
    pids = {r[0] for r in results}
    assert (pids == {os.getpid()}) if workers == 1 else (os.getpid() not in pids)


@pytest.mark.parametrize("workers", [1, 2])
def test_an_error_reaches_the_caller(workers):
    with pytest.raises(RcmKinError, match="refused on the worker"):
        map_local(refuse, [[1], [2], [3], [4]], workers, progress=False)


def test_a_small_robustness_run_without_a_cluster_is_the_serial_one(monkeypatch):
    from dataclasses import replace

    from rcm_kin.dynamics.drive import load_drive_parameters
    from rcm_kin.robustness import execution
    from rcm_kin.robustness.execution import run_in_process, run_robustness
    from rcm_kin.robustness.sampling import uncertain_parameters
    from rcm_kin.robustness.task import Study

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started")

    shipped = load_drive_parameters()
    shipped = replace(shipped, uncertainty=replace(shipped.uncertainty, folds={}))
    study = Study(shipped, uncertain_parameters(shipped), ("p",), "sine", 0.25)
    monkeypatch.setattr(execution, "dask_client", no_cluster)
    pooled = run_robustness(study, 3, 5, progress=False, workers=2, batch_size=1)
    assert pooled.as_dict() == run_in_process(study, 3, 5).as_dict()

"""Where the trainings of a reproduction run: local worker processes (the default, no dependency)
or Ray tasks (`ctrkin reproduce --executor ray`, the optional extra `ctrkin[ray]`).

A training is a call `fn(*job)` of a module-level function that loads its data from a path and
writes its model folder to a path, so a job is a few strings: every executor gives the same
results for the same seeds (each training is seeded and single-threaded). On a Ray cluster the
dataset and output folders must be on a file system every node sees under the same path.
"""

from __future__ import annotations

import logging
import multiprocessing as mp
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from ctrkin.errors import CtrkinError

EXECUTORS = ("local", "ray")
RAY_OBJECT_STORE_BYTES = 200 * 2**20     # jobs and results are paths: the store stays nearly empty


def run_jobs(fn: Callable[..., Any], jobs: Sequence[tuple[Any, ...]], executor: str = "local",
             workers: int = 2, threads: int = 1) -> Iterator[int]:
    """Run fn(*job) for every job; yields the index of each job as it finishes (in job order for
    "local", in finishing order for "ray"); an exception in a job is raised here.

    workers: local processes (or, for Ray without RAY_ADDRESS, the CPUs of the local Ray instance);
    threads: CPUs reserved per Ray task (the job's torch threads)."""
    if executor == "local":
        yield from _local(fn, jobs, workers)
    elif executor == "ray":
        yield from _ray(fn, jobs, workers, threads)
    else:
        raise CtrkinError(f"unknown executor {executor!r}; choose one of {EXECUTORS}")


def _local(fn: Callable[..., Any], jobs: Sequence[tuple[Any, ...]], workers: int) -> Iterator[int]:
    if workers <= 1:
        for k, job in enumerate(jobs):
            fn(*job)
            yield k
        return
    # spawned, not forked: a forked torch/OpenMP runtime can hang
    with mp.get_context("spawn").Pool(workers) as pool:
        pending = [pool.apply_async(fn, job) for job in jobs]
        for k, res in enumerate(pending):
            res.get()
            yield k


def _ray(fn: Callable[..., Any], jobs: Sequence[tuple[Any, ...]], workers: int, threads: int
         ) -> Iterator[int]:
    try:
        import ray
    except ImportError:
        raise CtrkinError("--executor ray needs Ray: pip install 'ctrkin[ray]'") from None
    started = not ray.is_initialized()
    if started:
        address = os.environ.get("RAY_ADDRESS")
        if address:            # an existing cluster (`ray start --head` / a cluster launcher)
            ray.init(address=address, logging_level=logging.WARNING)
        else:                  # a local instance with `workers` CPUs
            ray.init(num_cpus=workers, include_dashboard=False, logging_level=logging.WARNING,
                     object_store_memory=RAY_OBJECT_STORE_BYTES)
    try:
        task = ray.remote(num_cpus=threads, max_retries=0)(fn)
        refs = {task.remote(*job): k for k, job in enumerate(jobs)}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            ray.get(done[0])
            yield refs[done[0]]
    finally:
        if started:
            ray.shutdown()

"""Where chunks run: this machine's cores, a Dask ``LocalCluster``, or a Dask cluster.

Every scheduler calls the same pure `vsj.sweep.runner.run_chunk` with the same
values, so the results do not depend on it. ``None`` (the default) uses every core
of this machine: one chunk at a time on all cores when there is a single chunk,
else one process per core, each running whole chunks on one core (the model
building and sampling around the kernel is Python, which a process runs on one
core; processes keep every core busy with it). ``"local"`` starts a Dask
``LocalCluster`` with one single-threaded worker process per core; any other
text is the address of a running Dask scheduler (``tcp://host:8786``).

`execute` starts the workers and hands them their first chunks at once (so they
start up while the caller makes the store), then yields ``(index, ChunkResult)`` as
chunks finish, keeping at most two chunks per worker in flight, so memory stays
bounded and an interruption loses only those. Close what it returns to stop.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from ..engine.core import available_cores
from ..errors import InputError
from .runner import ChunkResult, Job, run_chunk

#: Imported once by the fork server the workers are forked from (see the module).
PRELOAD = ["vsj.sweep._worker"]


def execute(job: Job, chunks: list[tuple[int, int, object]], scheduler: str | None,
            workers: int | None = None) -> Iterator[tuple[int, ChunkResult]]:
    """Start running ``chunks`` (index, start, values) of ``job``; the generator returned
    yields the results as they finish (its ``close`` stops the workers)."""
    if not chunks:  # every chunk done: a generator still, for the caller to close
        running = _nothing()
    else:
        running = (_local(job, chunks, workers) if scheduler is None
                   else _dask(job, chunks, scheduler, workers))
    next(running)  # up to the first chunks handed out
    return running


def _nothing():
    yield None


def _local(job, chunks, workers):
    cores = workers or available_cores()
    if cores == 1 or len(chunks) == 1:
        yield None
        for index, start, values in chunks:
            yield index, run_chunk(job, start, values, threads=cores)
        return

    # a fork server imports the runner once and forks each worker from it: no fork of
    # this (threaded) process, and no worker importing everything anew
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    pending = list(reversed(chunks))
    running = {}
    with ProcessPoolExecutor(max_workers=min(cores, len(chunks)), mp_context=context) as pool:
        try:
            started = False
            while pending or running:
                while pending and len(running) < 2 * cores:
                    index, start, values = pending.pop()
                    running[pool.submit(run_chunk, job, start, values, 1)] = index
                if not started:
                    started = True
                    yield None
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    yield running.pop(future), future.result()
        except BaseException:
            for future in running:
                future.cancel()
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def client_for(scheduler: str, workers: int | None):
    """A Dask client: of a new ``LocalCluster`` (``"local"``) or of a running scheduler."""
    try:
        # lazy: dask is heavy; only its scheduler
        from dask.distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - a dependency
        raise InputError("--scheduler needs dask.distributed (pip install 'dask[distributed]')")
    if scheduler == "local":
        cluster = LocalCluster(n_workers=workers or available_cores(), threads_per_worker=1,
                               processes=True, dashboard_address=None)
        return Client(cluster), cluster
    try:
        return Client(scheduler, timeout="10s"), None
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there "
                         f"({exc})") from None


def _dask(job, chunks, scheduler, workers):
    from dask.distributed import as_completed  # lazy: dask is heavy; only its scheduler

    client, cluster = client_for(scheduler, workers)
    try:
        slots = 2 * max(1, len(client.scheduler_info()["workers"]))
        shared = client.scatter(job, broadcast=True)
        pending = list(reversed(chunks))
        running = {}

        def submit():
            index, start, values = pending.pop()
            future = client.submit(run_chunk, shared, start, values, 1, pure=False)
            running[future] = index
            return future

        queue = as_completed([submit() for _ in range(min(slots, len(pending)))])
        yield None
        for future in queue:
            index = running.pop(future)
            result = future.result()
            if pending:
                queue.add(submit())
            yield index, result
    finally:
        client.close()
        if cluster is not None:
            cluster.close()

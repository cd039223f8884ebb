"""Where chunks run: this machine's cores, a Dask ``LocalCluster``, or a Dask cluster.

Every scheduler calls the same pure `vsj.sweep.runner.run_chunk` with the same
values, so the results do not depend on it. ``None`` (the default) uses every core
of this machine: one chunk at a time on all cores when there is a single chunk,
else one process per core, each running whole chunks on one core (the model
building and sampling around the kernel is Python, which a process runs on one
core; processes keep every core busy with it). ``"local"`` starts a Dask
``LocalCluster`` with one single-threaded worker process per core; any other
text is the address of a running Dask scheduler (``tcp://host:8786``).

`execute` starts the workers and hands them their first tasks at once (so they
start up while the caller makes the store), then yields ``(index, ChunkResult)`` as
chunks finish, keeping at most two tasks per worker in flight, so memory stays
bounded and an interruption loses only those. Between the chunks it yields None
where the caller is to write those it holds: a few seconds after the first of them
finished (writing a few costs the caller about what writing one does), and before
this process runs a chunk itself. Close what it returns to stop.

A task is a chunk, or towards the end of a sweep a part of one (`tasks`): handed
out whole chunks to the last, the workers would not finish together, and all but
one would wait while it runs its last chunk (half a chunk's time on average, each).
The parts of a chunk are joined before it is yielded, so the caller sees chunks
only, and their numbers are those of the chunk run whole (a run depends on its own
values only, `vsj.sweep.runner`).
"""

from __future__ import annotations

import math
import multiprocessing
import time
from collections.abc import Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

from ..engine.core import available_cores
from ..errors import InputError
from ._worker import follow_fork_server
from .runner import ChunkResult, Job, run_chunk

#: Imported once by the fork server the workers are forked from (see the module).
PRELOAD = ["vsj.sweep._worker"]
#: Towards the end of a sweep a task holds about the runs left / (GUIDE x workers)
#: (guided self-scheduling: Polychronopoulos and Kuck, IEEE Trans. Computers 36(12),
#: 1987, with tasks GUIDE times smaller than theirs): the later the task, the shorter,
#: so the workers finish within about one short task of each other.
GUIDE = 4
#: A chunk is cut into this many parts at most (bounds the tasks' count and so the
#: scheduler's and the transfers' cost per run).
MAX_PARTS = 8


def tasks(chunks: Sequence[tuple[int, int, object]], workers: int
          ) -> list[tuple[int, int, object]]:
    """The tasks ``(chunk index, start, values)`` that run ``chunks`` (index, start,
    values) on ``workers`` workers, in order: whole chunks while many runs are left,
    then each chunk cut into equal parts of about the runs left after its start /
    (`GUIDE` x ``workers``), at most `MAX_PARTS`. A single worker gets the chunks
    whole (it has nobody to wait for)."""
    if workers <= 1:
        return list(chunks)
    left = sum(len(values) for _, _, values in chunks)
    out = []
    for index, start, values in chunks:
        runs = len(values)
        target = max(math.ceil(runs / MAX_PARTS), math.ceil(left / (GUIDE * workers)), 1)
        parts = max(1, min(runs, round(runs / target)))
        a = 0
        for k in range(parts):  # the longer parts first
            b = a + runs // parts + (k < runs % parts)
            out.append((index, start + a, values[a:b]))
            a = b
        left -= runs
    return out


class _Joiner:
    """Collects the parts of each chunk; `add` returns the chunk once it is whole."""

    def __init__(self, plan: Sequence[tuple[int, int, object]]):
        self._missing: dict[int, int] = {}
        for index, _, _ in plan:
            self._missing[index] = self._missing.get(index, 0) + 1
        self._parts: dict[int, list[ChunkResult]] = {}

    def add(self, index: int, result: ChunkResult) -> ChunkResult | None:
        """The whole chunk ``index`` if ``result`` was its last missing part, else None."""
        self._parts.setdefault(index, []).append(result)
        self._missing[index] -= 1
        if self._missing[index]:
            return None
        return ChunkResult.joined(self._parts.pop(index))


def execute(job: Job, chunks: list[tuple[int, int, object]], scheduler: str | None,
            workers: int | None = None, write_every: float = 0.0
            ) -> Iterator[tuple[int, ChunkResult] | None]:
    """Start running ``chunks`` (index, start, values) of ``job``; the generator returned
    yields the results as they finish, and None where the caller is to write the
    results it holds: ``write_every`` seconds after the first of them was yielded (at
    once with 0), and before this process runs a chunk itself (it cannot wake the
    caller during one). Its ``close`` stops the workers."""
    if not chunks:  # every chunk done: a generator still, for the caller to close
        running = _nothing()
    else:
        due = _Due(write_every)
        running = (_local(job, chunks, workers, due) if scheduler is None
                   else _dask(job, chunks, scheduler, workers, due))
    next(running)  # up to the first chunks handed out
    return running


class _Due:
    """When the chunks yielded since the caller last wrote are to be written."""

    def __init__(self, every: float):
        self.every = every
        self.at: float | None = None

    def held(self) -> None:
        """A chunk was yielded: a write is due ``every`` seconds after the first."""
        if self.at is None:
            self.at = time.perf_counter() + self.every

    def timeout(self) -> float | None:
        """Seconds to wait for a chunk before a write is due (None: no write pending)."""
        return None if self.at is None else max(0.0, self.at - time.perf_counter())

    def now(self) -> bool:
        """Whether a write is due now (then the next one waits for another chunk)."""
        if self.at is not None and time.perf_counter() >= self.at:
            self.at = None
            return True
        return False


def fork_server_pool(count: int) -> ProcessPoolExecutor:
    """``count`` worker processes forked from a fork server that imported `PRELOAD` once
    (no fork of this threaded process, and no worker importing everything anew); the
    server and its workers end with this process, however it ends."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    return ProcessPoolExecutor(max_workers=count, mp_context=context,
                               initializer=follow_fork_server)


def _nothing():
    yield None


def _local(job, chunks, workers, due):
    cores = workers or available_cores()
    if cores == 1 or len(chunks) == 1:
        yield None
        for index, start, values in chunks:
            yield index, run_chunk(job, start, values, threads=cores)
            yield None  # the next chunk runs here: the caller writes this one first
        return

    processes = min(cores, len(chunks))
    plan = tasks(chunks, processes)
    joiner = _Joiner(plan)
    pending = list(reversed(plan))
    running = {}
    with fork_server_pool(processes) as pool:
        try:
            started = False
            while pending or running:
                while pending and len(running) < 2 * processes:
                    index, start, values = pending.pop()
                    running[pool.submit(run_chunk, job, start, values, 1)] = index
                if not started:
                    started = True
                    yield None
                done, _ = wait(running, timeout=due.timeout(), return_when=FIRST_COMPLETED)
                for future in done:
                    index = running.pop(future)
                    whole = joiner.add(index, future.result())
                    if whole is not None:
                        due.held()
                        yield index, whole
                if due.now():
                    yield None
        except BaseException:
            for future in running:
                future.cancel()
            pool.shutdown(wait=False, cancel_futures=True)
            raise


def client_for(scheduler: str, workers: int | None):
    """A Dask client: of a new ``LocalCluster`` (``"local"``) or of a running scheduler."""
    try:
        # lazy: dask is heavy; only its scheduler
        from dask.distributed import Client
    except ImportError:  # pragma: no cover - a dependency
        raise InputError("--scheduler needs dask.distributed (pip install 'dask[distributed]')")
    if scheduler == "local":
        cluster = local_cluster(workers or available_cores())
        return Client(cluster), cluster
    try:
        return Client(scheduler, timeout="10s"), None
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"--scheduler {scheduler}: cannot reach a Dask scheduler there "
                         f"({exc})") from None


#: Dask settings of the ``LocalCluster`` a sweep starts (`local_cluster`). A task is one
#: call of the compiled kernel for most of its time, and the cluster shares its
#: machine's cores with the runs: so no statistical profiler (a look at the task's
#: stack every 10 ms, which learns nothing of a compiled kernel), and the cluster's
#: checks of its event loops, processes and memory, and its work stealing (the sweep
#: hands each worker two tasks at a time) off or at a slower pace, leaving the cores to
#: the runs.
QUIET = {"distributed.worker.profile.enabled": False,
         "distributed.admin.system-monitor.interval": "5s",
         "distributed.admin.tick.interval": "500ms",
         "distributed.worker.memory.monitor-interval": "1s",
         "distributed.scheduler.work-stealing": False,
         "distributed.deploy.cluster-repr-interval": "5s"}


def local_cluster(workers: int):
    """A Dask ``LocalCluster`` of ``workers`` one-thread worker processes, without a
    dashboard, with the settings `QUIET`."""
    # lazy: dask is heavy; only its scheduler
    import dask
    from dask.distributed import LocalCluster

    with dask.config.set(QUIET):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                            dashboard_address=None)


def _dask(job, chunks, scheduler, workers, due):
    from dask.distributed import wait as wait_any  # lazy: dask is heavy; only its scheduler

    client, cluster = client_for(scheduler, workers)
    try:
        count = max(1, len(client.scheduler_info()["workers"]))
        slots = 2 * count
        shared = client.scatter(job, broadcast=True)
        plan = tasks(chunks, count)
        joiner = _Joiner(plan)
        pending = list(reversed(plan))
        running = {}

        def submit():
            index, start, values = pending.pop()
            running[client.submit(run_chunk, shared, start, values, 1, pure=False)] = index

        for _ in range(min(slots, len(pending))):
            submit()
        yield None
        while running:
            try:
                done = wait_any(list(running), timeout=due.timeout(),
                                return_when="FIRST_COMPLETED").done
            except TimeoutError:  # no chunk finished: a write is due
                done = ()
            for future in done:
                index = running.pop(future)
                whole = joiner.add(index, future.result())
                if pending:
                    submit()
                if whole is not None:
                    due.held()
                    yield index, whole
            if due.now():
                yield None
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


class Pool:
    """Workers kept for many batches of chunks, started once: an optimisation's
    generations (`vsj.design`), each a batch that depends on the one before.

    ``scheduler`` and ``workers`` are those of `execute`: None runs on this machine's
    cores (in this process with one core, else in worker processes forked from a fork
    server), ``"local"`` or an address on Dask. `run` calls ``work(job, start, values,
    1)`` (a module-level function, as `vsj.sweep.runner.run_chunk`) for each task of a
    batch and returns the chunks' results in the batch's order; a result depends on its
    own values only, so it does not depend on the scheduler or the worker count."""

    def __init__(self, scheduler: str | None, workers: int | None = None):
        self.scheduler = scheduler
        self._processes = None
        self._client = self._cluster = None
        self._scattered = None  # (job, its future on the cluster), kept across batches
        if scheduler is None:
            self.count = workers or available_cores()
        else:
            self._client, self._cluster = client_for(scheduler, workers)
            self.count = max(1, len(self._client.scheduler_info()["workers"]))

    def run(self, work, job, chunks: Sequence[tuple[int, int, object]]) -> list[ChunkResult]:
        """The results of ``chunks`` (index, start, values) of ``job``, in their order."""
        if self.scheduler is None and self.count == 1:
            return [work(job, start, values, 1) for _, start, values in chunks]
        plan = tasks(chunks, self.count)
        if self.scheduler is None:
            if self._processes is None:
                self._processes = fork_server_pool(self.count)
            futures = [(index, self._processes.submit(work, job, start, values, 1))
                       for index, start, values in plan]
        else:
            # scattered once and held: a job scattered again has the same key, which the
            # scheduler would drop with the earlier batch's reference to it
            if self._scattered is None or self._scattered[0] is not job:
                self._scattered = (job, self._client.scatter(job, broadcast=True))
            shared = self._scattered[1]
            futures = [(index, self._client.submit(work, shared, start, values, 1,
                                                   pure=False))
                       for index, start, values in plan]
        joiner = _Joiner(plan)
        whole = {}
        try:
            for index, future in futures:
                result = joiner.add(index, future.result())
                if result is not None:
                    whole[index] = result
        except BaseException:
            for _, future in futures:
                future.cancel()
            raise
        return [whole[index] for index, _, _ in chunks]

    def close(self) -> None:
        """Stop the workers (and a ``LocalCluster`` this pool started)."""
        if self._processes is not None:
            self._processes.shutdown(wait=True, cancel_futures=True)
            self._processes = None
        if self._client is not None:
            self._scattered = None
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def __enter__(self) -> "Pool":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

"""Throughput of `vsj sweep` against the bare batch kernel, timed in the same run.

The study (issue 22): a Monte Carlo of fig-4.15-type runs (velocity-driven suns,
exponential elastic elements, arctan friction, 10 s simulated), the pivot position q
uniform on [-1.5, 0.5] cm and the transmission's and the differential's stiction
normal (10 +- 2 mN m, 2 +- 0.4 mN m), three metrics (peak deflection, lag, tracking
RMS) on samples every 20 ms, no signal kept. The issue's size is 100 000 runs (the
default here); ``make bench`` runs fewer (``VSJ_SWEEP_RUNS``, see the Makefile) and
this prints the count used.

Three ways, in interleaved blocks of runs (this machine is a shared VM whose speed
drifts; each way sees every moment alike, and the order rotates from block to block):

* kernel: `vsj.engine.plan.run_batch` on every core, the block's plans made
  beforehand and not timed: the integration alone;
* sweep: `vsj.sweep.run` with the default scheduler (every core), from the sweep
  file to sweep.zarr, metrics.csv and the manifest (models, chunking, the metrics,
  storage and each sweep's start-up of its worker processes included; no figures);
* dask: the same through a two-worker `LocalCluster`, started before the timed sweeps
  of each block and closed after them (its start is not timed; its idle heartbeats
  do not run beside the other ways).

The sweeps are chunked as the full study is (256 runs a chunk, fewer where the blocks
are small). Each block also runs both sweeps on one chunk: a straight line through the
two sizes splits a sweep's time into a fixed part (start-up of its processes,
preparation, files) and a part per run, and gives the time of the issue's full study,
which is compared with the kernel's. Before the blocks, each way runs one one-chunk
sweep: a process's first sweep imports what sweeps need, once, and that cost is added
to the full study's fixed part instead of weighing on the first block's runs. With fewer runs than the full
study, that is the figure the issue's target is checked on; the ratios measured at
the block's size are printed above it. Beside them, without the drift between the
ways: the share of each sweep's own cores x wall time that its workers spent in the
kernel's calls (`vsj.sweep.Outcome.kernel`), start-up and all, at the blocks' size.
That share is wall time inside the calls: time the system gives other processes
meanwhile (this process storing chunks, Dask's scheduler) counts as the kernel's, so
it is an upper bound of the kernel's share, not the comparison with the bare kernel.

Then, for the README's estimate of where a cluster's scheduler becomes the
bottleneck: the work in one chunk of the full study, the bytes a chunk sends back,
the client's time to store a chunk, and the Dask scheduler's overhead per task (from
2000 empty tasks).

    python benchmarks/sweep.py [RUNS] [--blocks K]     (RUNS: default $VSJ_SWEEP_RUNS,
                                                        else 100000)
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import pickle
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SPEC = """
[sweep]
scenario = "fig-4.15"
seed = {seed}
samples = {samples}
design = "random"

[vary]
q = {{ distribution = "uniform", low = "-1.5 cm", high = "0.5 cm" }}
"transmission.stiction" = {{ distribution = "normal", mean = "10 mN m", sd = "2 mN m" }}
"differential.stiction" = {{ distribution = "normal", mean = "2 mN m", sd = "0.4 mN m" }}

[signals]
reference_x = "planetary.sun_teeth / (planetary.sun_teeth + planetary.ring_teeth) / transmission.ratio * (motor_1 + motor_2) / 2"

[metrics]
deflection = {{ kind = "peak", signal = "phi_1", start = "4 s" }}
lag = {{ kind = "lag", signal = "theta_x", reference = "reference_x", frequency = "0.5 Hz", start = "4 s" }}
tracking = {{ kind = "tracking_rms", signal = "theta_x", reference = "reference_x", start = "4 s" }}

[output]
every = "20 ms"
"""
#: the issue's Monte Carlo
FULL_RUNS = 100_000
#: issue 32's target: the full study at this fraction of the bare kernel's speed or more
TARGET = 0.95
#: runs per call of the kernel (bounds the memory of the sampled states)
KERNEL_SLICE = 512
#: the LocalCluster's worker processes, one thread each
DASK_WORKERS = 2


def bare_kernel(spec) -> float:
    """Seconds the batch kernel takes for the spec's runs (models built beforehand)."""
    from vsj.engine.plan import run_batch
    from vsj.sweep import runner, sampling

    p = runner.prepared(runner.job_for(spec))
    values, _ = sampling.design(spec)
    elapsed = 0.0
    for a in range(0, len(values), KERNEL_SLICE):
        plans = [runner._build(p, v).plan for v in values[a:a + KERNEL_SLICE]]
        for plan in plans:
            plan.native  # checked beforehand: the kernel alone is timed
        started = time.perf_counter()
        batch = run_batch(plans, p.t_out)
        elapsed += time.perf_counter() - started
        assert np.all(batch.status == 0)
    return elapsed


def swept(spec, out: Path, scheduler=None, chunk=None) -> tuple[float, int, float, int, float]:
    """Seconds of a whole sweep, its bytes on disk, the client's seconds storing
    chunks, the chunk count (``chunk``: runs per chunk, default the sweep's own) and the
    core-seconds its workers spent in the batch kernel."""
    from vsj import sweep

    shutil.rmtree(out, ignore_errors=True)
    started = time.perf_counter()
    outcome = sweep.run(spec, out, scheduler=scheduler, chunk=chunk, plots=False,
                        show_progress=False)
    elapsed = time.perf_counter() - started
    assert outcome.failed == 0 and outcome.ran == outcome.runs
    size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    return elapsed, size, outcome.storing, outcome.chunks, outcome.kernel


@contextlib.contextmanager
def cluster(warm: bool = True):
    """The address of a `LocalCluster` of `DASK_WORKERS` one-thread worker processes
    as ``vsj sweep --scheduler local`` starts one (`vsj.sweep.schedulers.local_cluster`),
    running for the ``with`` block only: an idle cluster's heartbeats would take the
    cores from the other ways' measurements. With ``warm`` its workers have imported
    the sweep's runner, as the workers of a long study have after its first task."""
    from dask.distributed import Client

    from vsj.sweep.schedulers import local_cluster

    with local_cluster(DASK_WORKERS) as running:
        if warm:
            with Client(running.scheduler_address) as client:
                client.run(importlib.import_module, "vsj.sweep.runner")
        yield running.scheduler_address


def task_overhead(address: str, tasks: int = 2000) -> float:
    """Seconds per task the Dask scheduler adds (empty tasks, two workers)."""
    from dask.distributed import Client, wait

    with Client(address) as client:
        wait(client.map(int, range(100), pure=False))  # warm up
        started = time.perf_counter()
        wait(client.map(int, range(tasks), pure=False))
        return (time.perf_counter() - started) / tasks


def chunk_bytes(spec, runs: int) -> int:
    """Bytes a chunk of ``runs`` sends back (its pickled `ChunkResult`)."""
    from vsj.sweep import runner

    info = runner.describe(runner.job_for(spec))
    result = runner.ChunkResult(0, np.zeros((runs, len(info["time"]), len(info["keep"]))),
                                np.zeros((runs, len(info["metrics"]))),
                                np.zeros(runs, dtype=np.int64), ["ok"] * runs,
                                np.zeros(runs, dtype=np.int64))
    return len(pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="?", type=int,
                        default=int(os.environ.get("VSJ_SWEEP_RUNS", FULL_RUNS)))
    parser.add_argument("--blocks", type=int, default=None,
                        help="interleaved blocks (default: 10, fewer for small counts)")
    args = parser.parse_args()
    from vsj import sweep
    from vsj.engine.core import available_cores

    blocks = args.blocks or max(2, min(10, args.runs // 1000))
    per_block = max(1, args.runs // blocks)
    runs = per_block * blocks
    cores = available_cores()
    note = "" if runs >= FULL_RUNS else f" (the issue's study is {FULL_RUNS} runs)"
    # the full study's chunks (fewer runs each where the blocks are small): the costs of a
    # chunk (its transfer, storing, each task's start) then weigh on a run as there
    chunk = min(sweep.default_chunk(FULL_RUNS), max(1, per_block // 4))
    print(f"sweep benchmark: {runs} runs{note} in {blocks} interleaved blocks of "
          f"{per_block}, chunks of {chunk} runs, {cores} cores", flush=True)
    root = Path(tempfile.mkdtemp(prefix="vsj-sweep-bench-"))
    totals = {"kernel": 0.0, "sweep": 0.0, "dask": 0.0}
    small = chunk  # one chunk, which the workers share in parts
    small_totals = {"sweep": 0.0, "dask": 0.0}
    blockwise = {k: [] for k in totals}  # each block's seconds
    inside = {"sweep": 0.0, "dask": 0.0}  # the sweeps' core-seconds in the kernel
    size = storing = chunks = 0

    def both(spec, small_spec, way, address=None):
        """A sweep of the block's size and one of one chunk, one way (timed: the sweeps)."""
        nonlocal size, storing, chunks
        seconds, size, stored, n, kernel = swept(spec, root / way, address, chunk=chunk)
        inside[way] += kernel
        if way == "sweep":
            storing, chunks = storing + stored, chunks + n
        # the same sweep of one chunk: what a sweep costs whatever its size (start-up,
        # preparation, files) against what each run adds
        small_totals[way] += swept(small_spec, root / f"{way}-small", address, chunk=chunk)[0]
        return seconds

    # A process's first sweep of each way also imports what it needs (xarray, zarr and
    # Dask's client; about a second): a cost it pays once, whatever the sweep's size.
    # Left in the first block it would count as a cost per run of that block's sweep,
    # so each way's first sweep is a one-chunk sweep here, and the time it took beyond
    # the blocks' one-chunk sweeps is added to the full study's fixed cost below.
    first = {}
    try:
        first_path = root / "first.toml"
        first_path.write_text(SPEC.format(seed=blocks, samples=chunk))
        first["sweep"] = swept(sweep.load(first_path), root / "sweep-first", chunk=chunk)[0]
        with cluster(warm=False) as address:
            first["dask"] = swept(sweep.load(first_path), root / "dask-first", address,
                                  chunk=chunk)[0]
        for block in range(blocks):
            path = root / f"spec{block}.toml"
            path.write_text(SPEC.format(seed=block, samples=per_block))
            spec = sweep.load(path)
            small_path = root / f"small{block}.toml"
            small_path.write_text(SPEC.format(seed=block, samples=small))
            small_spec = sweep.load(small_path)
            ways = list(totals)
            for way in ways[block % 3:] + ways[:block % 3]:
                if way == "kernel":
                    seconds = bare_kernel(spec)
                elif way == "sweep":
                    seconds = both(spec, small_spec, way)
                else:
                    with cluster() as address:
                        seconds = both(spec, small_spec, way, address)
                totals[way] += seconds
                blockwise[way].append(seconds)
            print(f"block {block + 1}/{blocks}: " + ", ".join(
                f"{k} {(block + 1) * per_block / v:.1f} runs/s" for k, v in totals.items()),
                flush=True)
        with cluster() as address:
            overhead = task_overhead(address)
    finally:
        shutil.rmtree(root, ignore_errors=True)
    rates = {k: runs / v for k, v in totals.items()}
    names = {"kernel": "bare batch kernel", "sweep": "vsj sweep, default scheduler",
             "dask": "vsj sweep, 2-worker LocalCluster"}
    print(f"\n{'way':<34}{'runs/s':>9}{'of kernel':>11}{'median of blocks':>18}")
    for k, rate in rates.items():
        ratios = [b / a for a, b in zip(blockwise[k], blockwise["kernel"])]
        print(f"{names[k]:<34}{rate:>9.1f}{rate / rates['kernel']:>10.0%}"
              f"{statistics.median(ratios):>17.0%}")
    print(f"size on disk: {size / per_block:.0f} bytes per run (sweep.zarr, metrics.csv, "
          "sweep.json; no signal kept)")
    # the kernel's share of each sweep's own time, both measured in the same moments (no
    # drift between them): what the sweep adds to the kernel, start-up and all, at this size
    for way, workers in (("sweep", cores), ("dask", DASK_WORKERS)):
        print(f"{names[way]}: its {workers} one-thread workers spent "
              f"{inside[way] / (workers * totals[way]):.1%} of the sweeps' wall time in the "
              "batch kernel's calls")
    full_chunk = sweep.default_chunk(FULL_RUNS)
    work = full_chunk * cores / rates["kernel"]  # core-seconds of kernel in one chunk
    per_run_extra = cores / rates["sweep"] - cores / rates["kernel"]
    chunk_work = work + full_chunk * max(per_run_extra, 0.0)
    store_cost = storing / max(chunks, 1)
    back = chunk_bytes(spec, full_chunk)
    print(f"chunk of the full study ({full_chunk} runs): {chunk_work:.2f} core-seconds of "
          f"work ({work:.2f} of them kernel), {back} bytes sent back")
    print(f"client: {store_cost * 1e3:.1f} ms to store a chunk; Dask scheduler: "
          f"{overhead * 1e3:.2f} ms per task")
    print(f"workers at which each saturates, {full_chunk}-run chunks: scheduler "
          f"{chunk_work / overhead:.0f}, client {chunk_work / store_cost:.0f}, both "
          f"{chunk_work / (overhead + store_cost):.0f}")
    # A sweep's time is a fixed part (its processes' start-up, the preparation, the
    # files) and a part per run; from the sweeps of both sizes, a straight line through
    # the two gives both, and with them the time of the full study
    kernel_run = totals["kernel"] / runs  # seconds per run (the kernel has no fixed part)
    if per_block < 4 * small:
        print(f"blocks of {per_block} runs are too few to tell a sweep's fixed cost from its "
              f"cost per run; run at least {4 * blocks} runs")
        return 0
    projected = {}
    print(f"\n{'way':<34}{'fixed per sweep':>16}{'first in a process':>20}"
          f"{'per run vs kernel':>19}{f'of kernel at {FULL_RUNS}':>22}")
    for way in ("sweep", "dask"):
        big, little = totals[way] / blocks, small_totals[way] / blocks
        per_run = (big - little) / (per_block - small)
        fixed = little - small * per_run
        once = max(first[way] - little, 0.0)
        projected[way] = kernel_run * FULL_RUNS / (fixed + once + per_run * FULL_RUNS)
        print(f"{names[way]:<34}{fixed:>15.2f}s{once:>+19.2f}s"
              f"{per_run / kernel_run - 1:>+18.1%}{projected[way]:>22.1%}")
    # issue 32's acceptance: the 1e5-run Monte Carlo at >= 95 % of the bare kernel's
    # speed, locally and on a Dask LocalCluster
    measured = ("" if runs >= FULL_RUNS else
                f" ({runs}-run sweeps measured, {FULL_RUNS} from the line)")
    verdict = {way: "met" if projected[way] >= TARGET else "NOT met" for way in projected}
    print(f"targets (issue 32, at {FULL_RUNS} runs{measured}): sweep >= {TARGET:.0%} of kernel: "
          f"{projected['sweep']:.1%} ({verdict['sweep']}); dask >= {TARGET:.0%}: "
          f"{projected['dask']:.1%} ({verdict['dask']})")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(main())

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
* dask: the same through a two-worker `LocalCluster` started once beforehand.

Then, for the README's estimate of where a cluster's scheduler becomes the
bottleneck: the work in one chunk of the full study, the bytes a chunk sends back,
the client's time to store a chunk, and the Dask scheduler's overhead per task (from
2000 empty tasks).

    python benchmarks/sweep.py [RUNS] [--blocks K]     (RUNS: default $VSJ_SWEEP_RUNS,
                                                        else 100000)
"""

from __future__ import annotations

import argparse
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
#: runs per call of the kernel (bounds the memory of the sampled states)
KERNEL_SLICE = 512


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


def swept(spec, out: Path, scheduler=None) -> tuple[float, int, float, int]:
    """Seconds of a whole sweep, its bytes on disk, the client's seconds storing
    chunks, and the chunk count."""
    from vsj import sweep

    shutil.rmtree(out, ignore_errors=True)
    started = time.perf_counter()
    outcome = sweep.run(spec, out, scheduler=scheduler, plots=False, show_progress=False)
    elapsed = time.perf_counter() - started
    assert outcome.failed == 0 and outcome.ran == outcome.runs
    size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    return elapsed, size, outcome.storing, outcome.chunks


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
    from dask.distributed import LocalCluster

    from vsj import sweep
    from vsj.engine.core import available_cores

    blocks = args.blocks or max(2, min(10, args.runs // 1000))
    per_block = max(1, args.runs // blocks)
    runs = per_block * blocks
    cores = available_cores()
    note = "" if runs >= FULL_RUNS else f" (the issue's study is {FULL_RUNS} runs)"
    print(f"sweep benchmark: {runs} runs{note} in {blocks} interleaved blocks of "
          f"{per_block}, chunks of {sweep.default_chunk(per_block)} runs, {cores} cores",
          flush=True)
    root = Path(tempfile.mkdtemp(prefix="vsj-sweep-bench-"))
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    totals = {"kernel": 0.0, "sweep": 0.0, "dask": 0.0}
    blockwise = {k: [] for k in totals}  # each block's seconds
    size = storing = chunks = 0
    try:
        for block in range(blocks):
            path = root / f"spec{block}.toml"
            path.write_text(SPEC.format(seed=block, samples=per_block))
            spec = sweep.load(path)
            ways = list(totals)
            for way in ways[block % 3:] + ways[:block % 3]:
                if way == "kernel":
                    seconds = bare_kernel(spec)
                else:
                    seconds, size, stored, n = swept(
                        spec, root / way, None if way == "sweep" else cluster.scheduler_address)
                    if way == "sweep":
                        storing, chunks = storing + stored, chunks + n
                totals[way] += seconds
                blockwise[way].append(seconds)
            print(f"block {block + 1}/{blocks}: " + ", ".join(
                f"{k} {(block + 1) * per_block / v:.1f} runs/s" for k, v in totals.items()),
                flush=True)
        overhead = task_overhead(cluster.scheduler_address)
    finally:
        cluster.close()
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
    # issue 32's acceptance: the 1e5-run Monte Carlo at >= 95 % of the bare kernel's
    # speed, locally and on a Dask LocalCluster
    print(f"targets (issue 32, at {FULL_RUNS} runs): sweep >= 95 % of kernel: "
          f"{rates['sweep'] / rates['kernel']:.0%}; dask >= 95 %: "
          f"{rates['dask'] / rates['kernel']:.0%}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(main())

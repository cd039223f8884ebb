"""Throughput of `vsj sweep` against the bare batch kernel, timed in the same run.

The study: a Monte Carlo of fig-4.15-type runs (velocity-driven suns, exponential
elastic elements, arctan friction, 10 s simulated), the pivot position q uniform on
[-1.5, 0.5] cm and the transmission's and the differential's stiction normal
(10 +- 2 mN m, 2 +- 0.4 mN m), three metrics (peak deflection, lag, tracking RMS)
on samples every 20 ms, no signal kept.

Three ways, in interleaved blocks of runs (this machine is a shared VM whose speed
drifts; each way sees every moment alike):

* kernel: `vsj.engine.core.run_batch` on every core, the block's models compiled
  beforehand and not timed: the integration alone;
* sweep: `vsj.sweep.run` with the default scheduler (every core), from the sweep
  file to sweep.zarr, metrics.csv and the manifest (model building, chunking,
  sampling the metrics and storage included; no figures);
* dask: the same through a two-worker `LocalCluster` started once beforehand.

Then the Dask scheduler's overhead per task, from 2000 empty tasks, and the work and
data per chunk, for the README's estimate of where the scheduler becomes the
bottleneck.

    python benchmarks/sweep.py [RUNS] [--blocks K]     (default 100000 runs, 10 blocks)
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from vsj import sweep
from vsj.engine import Engine, core
from vsj.engine.core import available_cores
from vsj.sweep import runner, sampling

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


def bare_kernel(spec) -> float:
    """Seconds the batch kernel takes for the spec's runs (models built beforehand)."""
    job = runner.job_for(spec)
    p = runner.prepared(job)
    values, _ = sampling.design(spec)
    built = [runner._build(p, v) for v in values]
    first = built[0]
    engine = Engine(first.model._replace(src_pos0=first.sigma0))
    arrays = [np.array([getattr(b.model, k) for b in built]) for k in ("mass", "Minv", "par")]
    o = p.options
    started = time.perf_counter()
    _, _, status, *_ = core.run_batch(
        p.solver, engine, *arrays, np.array([b.sigma0 for b in built]),
        np.array([b.y0 for b in built]), p.duration, p.t_out, rtol=o.rtol, atol=o.atol,
        h_max=o.max_step, max_steps=o.max_steps, h=o.step)
    elapsed = time.perf_counter() - started
    assert np.all(status == 0)
    return elapsed


def swept(spec, out: Path, scheduler=None) -> tuple[float, int]:
    """Seconds of a whole sweep, and its bytes on disk."""
    shutil.rmtree(out, ignore_errors=True)
    started = time.perf_counter()
    outcome = sweep.run(spec, out, scheduler=scheduler, plots=False, show_progress=False)
    elapsed = time.perf_counter() - started
    assert outcome.failed == 0
    size = sum(f.stat().st_size for f in out.rglob("*") if f.is_file())
    return elapsed, size


def task_overhead(address: str, tasks: int = 2000) -> float:
    """Seconds per task the Dask scheduler adds (empty tasks, two workers)."""
    from dask.distributed import Client, wait

    with Client(address) as client:
        wait(client.map(int, range(100), pure=False))  # warm up
        started = time.perf_counter()
        wait(client.map(int, range(tasks), pure=False))
        return (time.perf_counter() - started) / tasks


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="?", type=int, default=100_000)
    parser.add_argument("--blocks", type=int, default=10)
    args = parser.parse_args()
    from dask.distributed import LocalCluster

    per_block = max(1, args.runs // args.blocks)
    cores = available_cores()
    print(f"{args.blocks} blocks of {per_block} runs, {cores} cores", flush=True)
    root = Path(tempfile.mkdtemp(prefix="vsj-sweep-bench-"))
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    totals = {"kernel": 0.0, "sweep": 0.0, "dask": 0.0}
    size = 0
    try:
        for block in range(args.blocks):
            path = root / f"spec{block}.toml"
            path.write_text(SPEC.format(seed=block, samples=per_block))
            spec = sweep.load(path)
            totals["kernel"] += bare_kernel(spec)
            seconds, size = swept(spec, root / "local")
            totals["sweep"] += seconds
            seconds, _ = swept(spec, root / "dask", cluster.scheduler_address)
            totals["dask"] += seconds
            print(f"block {block + 1}: " + ", ".join(
                f"{k} {(block + 1) * per_block / v:.1f} runs/s" for k, v in totals.items()),
                flush=True)
        overhead = task_overhead(cluster.scheduler_address)
    finally:
        cluster.close()
        shutil.rmtree(root, ignore_errors=True)
    runs = per_block * args.blocks
    rates = {k: runs / v for k, v in totals.items()}
    chunk = sweep.default_chunk(per_block)
    work = chunk / rates["kernel"] * cores  # core-seconds of one chunk
    print(f"\n{'way':<8}{'runs/s':>10}{'of kernel':>11}")
    for k, rate in rates.items():
        print(f"{k:<8}{rate:>10.1f}{rate / rates['kernel']:>10.0%}")
    print(f"size on disk: {size / per_block:.0f} bytes per run (sweep.zarr, metrics.csv, "
          "manifest; no signal kept)")
    print(f"chunk of {chunk} runs: {work:.2f} core-seconds of work, "
          f"{chunk * 3 * 8 + chunk * 16} bytes of metrics and status back")
    print(f"Dask scheduler overhead: {overhead * 1e3:.2f} ms per task; it saturates at "
          f"{work / overhead:.0f} workers for chunks of {chunk} runs")
    print(f"targets: sweep >= 90 % of kernel: {rates['sweep'] / rates['kernel']:.0%}; "
          f"dask >= 80 %: {rates['dask'] / rates['kernel']:.0%}")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(main())

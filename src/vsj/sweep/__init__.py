"""Many runs of one scenario: sweeps, Monte Carlo and sensitivity analysis.

`load` reads a sweep file (`vsj.sweep.spec` documents the format) and checks it;
`run` simulates its runs in chunks through the batch kernel, on this machine's
cores or a Dask cluster (`vsj.sweep.schedulers`), writes every finished chunk
into ``DIR/sweep.zarr`` and its manifest (`vsj.sweep.store`), and, once all are
done, ``metrics.csv``, the figures, the sensitivity indices and ``summary.html``
(`vsj.sweep.analysis`). The runs equal those ``vsj simulate`` makes one by one,
bit for bit, whatever the scheduler, worker count or chunk size.
"""

from __future__ import annotations

import csv
import io
import math
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..output import OutputError, atomic_write, file_record
from ..progress import progress
from . import analysis, schedulers, store
from .runner import describe, job_for, probed
from .sampling import design, sensitivity_problem
from .spec import SweepSpec, load, loads, run_count, spec_of, with_method, within_pivot_range

#: Default runs per chunk at most: enough to keep the per-chunk cost (a task, a zarr
#: region, a manifest update) small beside the runs, few enough to lose little when
#: killed and to keep a cluster's workers busy.
MAX_CHUNK = 256
#: Finished chunks are held and written to the store (and entered in its manifest)
#: together, this many seconds after the first of them finished
#: (`vsj.sweep.schedulers.execute`): a write of a few store chunks costs the
#: coordinating process, which shares the cores with the workers, about what a write
#: of one does. A stopped sweep writes what finished; a killed one runs the chunks that
#: finished in its last seconds again when resumed.
WRITE_EVERY = 2.0
#: Bytes of finished chunks held for a write at most: past them they are written at
#: once (many workers, or many kept signals, fill them before `WRITE_EVERY` passes).
HOLD_BYTES = 64 * 2 ** 20
#: Default chunks per sweep at least (while chunks stay below `MAX_CHUNK`): enough to
#: share the work among this machine's cores and show progress.
MIN_CHUNKS = 16


def default_chunk(runs: int) -> int:
    """Runs per chunk when ``--chunk`` is not given (a function of the run count only,
    so a resumed sweep on another machine chunks alike)."""
    return max(1, min(MAX_CHUNK, math.ceil(runs / MIN_CHUNKS)))


@dataclass
class Outcome:
    """What `run` did."""

    out: Path
    runs: int
    ran: int
    failed: int
    chunks: int
    complete: bool
    seconds: float
    files: list[str] = field(default_factory=list)
    sensitivity: list[list] = field(default_factory=list)
    method: str | None = None
    #: seconds this process spent storing returned chunks (zarr regions, manifest)
    storing: float = 0.0
    #: seconds the kernel calls of the chunks run now took, summed (each call's wall time:
    #: core-seconds where a worker runs its kernel on one thread, as the worker processes
    #: of the default scheduler and of a LocalCluster of one-thread workers do; a sweep
    #: run in this process alone runs it on every core). The rest of a worker's time is
    #: building the runs and measuring them.
    kernel: float = 0.0
    #: what a resumed sweep found damaged and redid (one sentence each)
    notes: list[str] = field(default_factory=list)
    #: what the sweep varies in vain (a parameter its scenario's model does not read)
    warnings: list[str] = field(default_factory=list)


class Unfinished(RuntimeError):
    """A sweep stopped by a failure to write or read its directory (a full or read-only
    file system, an I/O error). The chunks finished before it are kept when the sweep
    was recorded, and the message says how to go on (``--resume``)."""


def run(spec: SweepSpec, out: str | Path, *, resume: bool = False,
        scheduler: str | None = None, chunk: int | None = None, workers: int | None = None,
        plots: bool = True, show_progress: bool = True, announce=None) -> Outcome:
    """Run the sweep ``spec`` into ``out`` (see the module docstring). Everything the
    sweep file, scenario and parameter set allow to be checked is checked before any
    run (`vsj.errors.InputError`), the free space against a bound on the bytes the
    sweep writes included. ``announce(text)``, if given, is told that bound before the
    runs start, the sweep's warnings (`Outcome.warnings`), and what a resumed sweep found
    damaged and runs again. A failure to write the directory raises `Unfinished`.

    The default scheduler's worker processes import the calling script as Python's
    ``multiprocessing`` does: call this from a script under ``if __name__ ==
    "__main__":``, or each worker runs the script's top level again."""
    started = time.perf_counter()
    job = job_for(spec)
    info = describe(job)
    base = info["base_params"]
    if not {"pivot.q_min", "pivot.q_max"} & set(spec.varied):
        spec = within_pivot_range(spec, base.pivot.q_min, base.pivot.q_max)
    runs = run_count(spec)
    if chunk is not None and not 1 <= chunk <= runs:
        raise InputError(f"--chunk {chunk}: must be between 1 and the {runs} runs")
    out = Path(out)
    say = announce or (lambda text: None)
    for text in info["warnings"]:
        say(f"warning: {text}")
    with store.Directory(out, resume=resume) as directory:
        try:
            record = store.read_manifest(out) if resume else None
            size = chunk or (record or {}).get("chunk") or default_chunk(runs)
            expected = {**store.inputs(job, spec), "runs": runs, "chunk": size}
            if record is not None:
                store.check_resume(out, record, expected, job=job, spec=spec)
            outcome = _run(spec, job, info, directory, record, expected, size,
                           scheduler=scheduler, workers=workers, plots=plots,
                           show_progress=show_progress, say=say)
        except OSError as exc:
            recorded = (out / store.MANIFEST).exists()
            what = exc.filename or out
            remedy = ("the finished chunks are kept: make room (or make it writable) and "
                      "run the same command with --resume" if recorded else
                      "nothing was kept: make room (or make it writable) and run the "
                      "command again")
            raise Unfinished(f"{what}: writing the sweep failed ({exc.strerror or exc}); "
                             f"{remedy}") from None
    outcome.seconds = time.perf_counter() - started
    return outcome


def _check_space(out: Path, info, spec, runs: int, size: int, record, plots: bool,
                 say) -> None:
    """`OutputError` if the runs not done yet may not fit the free space of ``out``;
    else ``say`` how many bytes they write at most."""
    done = sum(b - a for a, b in (e["runs"] for e in (record or {"done": {}})["done"].values()))
    todo = runs - done
    need = store.estimate(todo, math.ceil(todo / size), len(info["time"]), len(info["keep"]),
                          len(info["metrics"]), len(spec.varied), figures=plots)
    free = store.free_bytes(out)
    if say is None and need <= free:
        return
    plan = (f"{runs} runs in {math.ceil(runs / size)} chunks, {todo} to run: up to "
            f"{store.size_text(need)} on disk ({len(info['time'])} samples x "
            f"{len(info['keep'])} kept signals and {len(info['metrics'])} metrics per run, "
            f"uncompressed); {store.size_text(free)} free")
    if need > free:
        raise OutputError(f"--out {out}: {plan}: not enough room; nothing was run (keep fewer "
                          "signals, a coarser output.every, or choose another disk)")
    if say is not None:
        say(plan)


def _run(spec, job, info, directory, record, expected, size, *, scheduler, workers, plots,
         show_progress, say) -> Outcome:
    out = directory.path
    runs = run_count(spec)
    # before the draws (which take a while for millions of runs): the runs not recorded
    # done; once the finished chunks are checked, again with those to run again
    _check_space(out, info, spec, runs, size, record, plots, None)
    values, unit = design(spec)
    units = [spec_of(name).unit for name in spec.varied]

    def make(path: Path) -> None:
        base = info["base_params"]
        store.create(path, varied=spec.varied, values=values, units=units,
                     time=info["time"], keep=info["keep"], keep_units=info["keep_units"],
                     metrics=info["metrics"], metric_units=info["metric_units"], chunk=size,
                     attrs={"vsj_version": __version__, "scenario": job.scenario_origin,
                            "parameters": base.origin, "parameters_hash": base.hash(),
                            "solver": info["solver"], "seed": spec.seed,
                            "sweep_file": spec.origin, "sweep": spec.text,
                            "method": spec.method or ""})

    notes: list[str] = []
    if record is not None:
        notes = _recover(spec, directory, record, values, make, show_progress)
        for note in notes:
            say(note)
    _check_space(out, info, spec, runs, size, record, plots, say)
    bounds = [(i, i * size, min(runs, (i + 1) * size)) for i in range(math.ceil(runs / size))]
    done = set(record["done"]) if record is not None else set()
    todo = [(i, a, values[a:b]) for i, a, b in bounds if str(i) not in done]
    ran = 0
    storing = kernel = 0.0
    bar = None
    # the workers start on their first chunks while this process makes the store
    running = schedulers.execute(probed(job), todo, scheduler, workers, WRITE_EVERY)
    try:
        if record is None:
            make(directory.zarr)
            record = {"about": "chunks of this sweep whose runs are in sweep.zarr; "
                               "'vsj sweep SPEC --out DIR --resume' runs the others",
                      **expected, "libraries": store.libraries(),
                      "chunks": math.ceil(runs / size), "done": {}, "failed_runs": {},
                      "complete": False, "frame": store.frame_record(directory.zarr)}
            store.write_manifest(out, record)
        if show_progress:
            bar = progress(None, desc="sweep", unit="run", total=runs)
            bar.update(runs - sum(len(v) for _, _, v in todo))
        writer = store.Writer(directory.zarr)
        held: list = []  # finished chunks not written yet
        held_bytes = 0
        writing = False

        def write_held() -> None:
            """Write the chunks held, then enter them in the manifest."""
            nonlocal storing, writing, held_bytes
            if not held:
                return
            writing, began = True, time.perf_counter()
            writer.write([result for _, result in held])
            for index, result in held:
                record["done"][str(index)] = {"runs": [result.start, bounds[index][2]],
                                              "failed": result.failed,
                                              "sha256": store.digest(result)}
                for k, message in enumerate(result.messages):
                    if result.status[k] != 0:
                        record["failed_runs"][str(result.start + k)] = message
            record["done"] = dict(sorted(record["done"].items(), key=lambda kv: int(kv[0])))
            record["failed_runs"] = dict(sorted(record["failed_runs"].items(),
                                                key=lambda kv: int(kv[0])))
            store.write_manifest(out, record)
            held.clear()
            held_bytes = 0
            writing = False
            storing += time.perf_counter() - began

        try:
            for item in running:
                if item is None:  # the scheduler's moment to write (`schedulers.execute`)
                    write_held()
                    continue
                index, result = item
                held.append((index, result))
                held_bytes += result.kept.nbytes + result.metrics.nbytes
                kernel += result.kernel_time
                ran += len(result.status)
                if bar is not None:
                    bar.update(len(result.status))
                if held_bytes >= HOLD_BYTES:
                    write_held()
            write_held()
        except BaseException as stopped:
            # stopped (Ctrl-C, a worker's failure): what finished is kept, unless
            # writing it is what failed; a failure to write it then is said beside
            # what stopped the sweep, which is what ends it
            if held and not writing:
                try:
                    write_held()
                except OSError as exc:
                    stopped.add_note(f"the chunks that had finished were not written: {exc}")
            raise
    finally:
        running.close()
        if bar is not None:
            bar.close()
    outcome = Outcome(out, runs, ran, len(record["failed_runs"]), len(bounds), True,
                      0.0, method=spec.method, storing=storing, kernel=kernel, notes=notes,
                      warnings=list(info["warnings"]))
    _finish(spec, out, directory.zarr, record, unit, outcome, plots)
    for text in outcome.warnings[len(info["warnings"]):]:  # what the runs' metrics gave
        say(f"warning: {text}")
    written = {name: file_record(out / name) for name in outcome.files
               if name not in (store.ZARR, store.MANIFEST)}
    for name in record.get("files", {}):
        if name not in written:  # a figure of an earlier finish (with plots)
            (out / name).unlink(missing_ok=True)
    record["files"] = written
    record["complete"] = True
    store.write_manifest(out, record)
    return outcome


def _recover(spec, directory, record: dict, values: np.ndarray, make,
             show_progress: bool) -> list[str]:
    """Make the store of a resumed sweep whole: refuse files vsj did not write in it,
    rebuild its frame from the inputs where that is damaged or missing, check that the
    values drawn now are those stored, and forget every finished chunk whose numbers no
    longer match its SHA-256 (to run it again). Returns what was found, one sentence
    each."""
    out = directory.path
    notes = []
    frame = record["frame"]
    if os.path.lexists(directory.zarr) and not directory.zarr.is_dir():
        raise OutputError(f"--out {out}: {store.ZARR} is not a directory; vsj did not make it "
                          "so: move it away, or start a new directory")
    if directory.zarr.is_dir():
        foreign = store.foreign_in_store(directory.zarr, frame)
        if foreign:
            raise OutputError(f"--out {out}: {store.ZARR} holds files that vsj did not write "
                              f"({', '.join(foreign[:5])}); move them away, or start a new "
                              "directory")
    damage = store.check_frame(directory.zarr, frame)
    if damage:
        temp = store.build_frame(out, make)
        fresh = store.frame_record(temp)
        drawn = [n for n in spec.varied
                 if fresh["coordinates"].get(n) != frame["coordinates"].get(n)]
        if drawn:
            shutil.rmtree(temp)
            raise InputError(_drawn_differ(out, drawn, record))
        store.install_frame(temp, directory.zarr)
        record["frame"] = fresh
        notes.append(f"{'; '.join(damage)}: rebuilt from the sweep's inputs")
    else:
        ds = store.open_dataset(directory.zarr)
        drawn = [n for j, n in enumerate(spec.varied)
                 if not np.array_equal(ds[n].values, values[:, j])]
        if drawn:
            raise InputError(_drawn_differ(out, drawn, record))
    bar = None
    if show_progress and record["done"]:
        bar = progress(None, desc="checking finished chunks", unit="run",
                       total=sum(b - a for a, b in (e["runs"] for e in record["done"].values())))
    try:
        bad = store.check_chunks(directory.zarr, record,
                                 progress=bar.update if bar is not None else None)
    finally:
        if bar is not None:
            bar.close()
    for index, why in sorted(bad.items()):
        a, b = record["done"][str(index)]["runs"]
        notes.append(f"chunk {index} ({store.runs_text(a, b)}): {why}: run again")
    if bad or damage:
        store.drop_chunks(record, bad)
        store.write_manifest(out, record)
    return notes


def _drawn_differ(out: Path, names: list[str], record: dict) -> str:
    then, now = record.get("libraries", {}), store.libraries()
    changed = [f"{k} {then.get(k)} there, {now.get(k)} now" for k in sorted(set(then) | set(now))
               if then.get(k) != now.get(k)]
    why = (f"the libraries that draw them differ ({'; '.join(changed)})" if changed else
           "with the inputs and the versions of NumPy, SciPy and SALib it recorded (another "
           "platform or Python?)")
    return (f"--resume {out}: the values of {', '.join(names)} drawn now differ from those "
            f"the sweep there stored, {why}; start a new directory")


def _not_finite(metrics: np.ndarray, names: list[str], status: np.ndarray) -> list[str]:
    """A warning for each metric that came out NaN or infinite in runs that succeeded
    (a division by zero, a log of 0 in its expression): metrics.csv leaves a NaN cell
    empty, so a run with status ok would show nothing."""
    ok = status == 0
    out = []
    for j, name in enumerate(names):
        bad = np.flatnonzero(ok & ~np.isfinite(metrics[:, j]))
        if bad.size:
            out.append(f"metric {name!r} is not a finite number in {bad.size} of "
                       f"{int(np.count_nonzero(ok))} runs that succeeded (run {int(bad[0])}: "
                       f"{metrics[bad[0], j]!r}); check its expression")
    return out


def _finish(spec: SweepSpec, out: Path, zarr_path: Path, record: dict, unit,
            outcome: Outcome, plots: bool) -> None:
    """The tables, figures and page of a sweep whose chunks are all done."""
    ds = store.open_dataset(zarr_path)
    varied = spec.varied
    store.write_metrics_csv(out / store.METRICS, ds, record["failed_runs"], varied)
    files = [store.ZARR, store.METRICS, store.MANIFEST]
    metrics = ds["metrics"].values
    names = ds["metric"].values.tolist()
    units = ds["metric_unit"].values.tolist()
    outcome.warnings += _not_finite(metrics, names, ds["status"].values)
    inputs = np.column_stack([ds[n].values for n in varied])
    input_units = [ds[n].attrs.get("units", "") for n in varied]
    figures = {}
    rows: list[list] = []
    if names and plots:
        figures["sweep-histograms.png"] = ("Histogram of each metric",
                                           analysis.histograms(metrics, names, units))
        figures["sweep-scatter.png"] = ("Each metric against each varied quantity",
                                        analysis.scatter(metrics, names, units, inputs, varied,
                                                         input_units))
        if varied == ["q"]:
            figures["sweep-vs-q.png"] = ("Each metric against the pivot position q",
                                         analysis.versus_q(inputs[:, 0], metrics, names, units))
    if names and spec.method is not None:
        problem = sensitivity_problem(spec.sampled)
        indices = {name: analysis.sensitivity(spec.method, problem, unit, metrics[:, j],
                                              spec.seed)
                   for j, name in enumerate(names)}
        rows = analysis.sensitivity_rows(spec.method, indices)
        if plots:
            figures["sweep-sensitivity.png"] = (
                f"Sensitivity indices ({spec.method}) with 95 % confidence intervals",
                analysis.sensitivity_chart(spec.method, indices))
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(analysis.header(spec.method))
        writer.writerows([[r[0], r[1], *(repr(float(v)) for v in r[2:])] for r in rows])
        with atomic_write(out / "sensitivity.csv") as handle:
            handle.write(buffer.getvalue())
        files.append("sensitivity.csv")
    for name, (_, png) in figures.items():
        with atomic_write(out / name, "wb") as handle:
            handle.write(png)
        files.append(name)
    failures = [(int(r), m) for r, m in record["failed_runs"].items()]
    facts = [("sweep file", spec.origin), ("scenario", str(ds.attrs.get("scenario"))),
             ("parameter set", (f"{ds.attrs.get('parameters')} (hash "
                                f"{str(ds.attrs.get('parameters_hash'))[:12]})")),
             ("runs", f"{outcome.runs} ({len(failures)} failed)"),
             ("varied", ", ".join(f"{n} [{u}]" for n, u in zip(varied, input_units))),
             ("design", spec.method or spec.design), ("seed", str(spec.seed)),
             ("vsj", __version__)]
    page = analysis.page(f"vsj sweep: {Path(spec.origin).name}", facts,
                         analysis.statistics(metrics, names, units), figures, spec.method,
                         rows, failures)
    with atomic_write(out / "summary.html") as handle:
        handle.write(page)
    files.append("summary.html")
    outcome.files = files
    outcome.sensitivity = rows


__all__ = [
    "Outcome",
    "SweepSpec",
    "Unfinished",
    "default_chunk",
    "load",
    "loads",
    "run",
    "run_count",
    "with_method",
]

"""A sweep's directory: ``sweep.zarr``, its manifest of finished chunks, the tables.

A sweep is written chunk by chunk, not as one `vsj.output.ResultSet` (which
replaces a set of files whole at the end, and whose staging a killed process
loses): the zarr store is made up front with every array's shape, each finished
chunk is written into its own region of it (zarr chunks along ``run`` are the
sweep's chunks, so no two chunks share a file), and only then is it entered in
``sweep.json``, replaced atomically (`vsj.output.atomic_write`). A process killed
at any moment leaves the manifest naming only chunks whose data is complete;
``--resume`` runs the others. The directory is locked (``flock``) while a sweep
writes it, and vsj refuses a directory that holds files it did not write.

``sweep.json`` also records what the sweep's runs depend on (`inputs`: the sweep
file, the scenario, the parameter set as resolved, the covariance, the vsj
version), the SHA-256 of each finished chunk's numbers (`digest`), of the store's
metadata and coordinates (`frame_record`), and, once the sweep is complete, of the
tables and figures. ``--resume`` refuses other inputs, rebuilds a damaged or missing
store frame from the inputs, and runs again every chunk whose numbers no longer
match (`check_chunks`); `verify` checks a sweep directory without its inputs.

``sweep.zarr`` holds, over ``run``, ``time`` and ``signal``: ``signals`` (the kept
signals, SI, their units in the coordinate ``unit``), ``metrics`` (over ``run`` and
``metric``), ``status`` (0: ok; an engine status; -1: not built; -2: not run yet)
and ``steps``; each varied quantity is a coordinate over ``run`` with its unit.
Its attributes carry the vsj version, the parameter set's hash, the scenario,
and the sweep file's text.
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import hashlib
import io
import json
import math
import os
import re
import secrets
import shutil
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError, read_bytes
from ..output import (OUTPUTS, PLOT_BYTES, PROBE, OutputError, atomic_write,
                      file_record, recorded_file_problems, regular_file)
from ..params import SCHEMA

ZARR = "sweep.zarr"
MANIFEST = "sweep.json"
METRICS = "metrics.csv"
#: Status of a run not simulated yet (in the store's fill value).
NOT_RUN = -2
#: The arrays over ``run`` that chunks write (the rest of the store is its frame).
DATA = ("signals", "metrics", "status", "steps")
_OURS = re.compile(OUTPUTS["sweep"])
#: `atomic_write`'s temporary files of the sweep's files (where the file system has no
#: unnamed ones) and its probes of the directory, and a store frame being rebuilt
#: (`build_frame`).
_TEMPORARY = re.compile(rf"\.(?:{OUTPUTS['sweep']}|{re.escape(ZARR)}|{PROBE})\.vsj-tmp-\w+")
#: zarr's temporary file of a chunk or metadata file being written (``KEY.HEX.partial``).
_PARTIAL = re.compile(r".*\.[0-9a-f]{32}\.partial")
#: Largest sweep.json read [bytes]: it holds about 250 bytes per chunk and 300 per failed
#: run, so a sweep of `vsj.sweep.spec.MAX_RUNS` runs in chunks of one, every run failed,
#: stays below it (5.5 GB); a device or a file far beyond it is refused unread.
MANIFEST_BYTES = 8 << 30


class Directory:
    """The locked output directory of one sweep (a context manager).

    Entering takes the lock, removes what a killed sweep left (temporary files, a
    store frame being rebuilt, zarr's partial files, a store without a manifest) and
    refuses a directory that is not writable or holds files vsj did not write. Leaving
    with an exception removes a directory it created if no sweep was recorded there."""

    def __init__(self, path: str | Path, *, resume: bool):
        self.path = Path(path)
        self.resume = resume
        self._fd = None
        self._created = False

    def __enter__(self):
        shown = f"--out {self.path}"
        if self.path.exists() and not self.path.is_dir():
            raise OutputError(f"{shown}: exists and is not a directory")
        if not self.path.exists():
            if self.resume:
                raise OutputError(f"{shown}: no such directory: nothing to resume")
            try:
                self.path.mkdir(parents=True)
            except OSError as exc:
                raise OutputError(f"{shown}: cannot create the directory "
                                  f"({exc.strerror or exc})") from None
            self._created = True
        self._fd = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(self._fd)
            self._fd = None
            raise OutputError(f"{shown}: another vsj command is writing to this directory")
        try:
            self._check(shown)
        except BaseException as exc:
            self.__exit__(type(exc), exc, None)
            raise
        return self

    def _check(self, shown: str) -> None:
        if not os.access(self.path, os.W_OK | os.X_OK):
            raise OutputError(f"{shown}: cannot write in the directory (permission denied or "
                              "a read-only file system)")
        entries = sorted(os.listdir(self.path))
        foreign = [e for e in entries if not (e == ZARR or _OURS.fullmatch(e) or
                                              _TEMPORARY.fullmatch(e))]
        if foreign:
            raise OutputError(f"{shown}: holds files that vsj did not write "
                              f"({', '.join(foreign[:5])}); choose another directory")
        has_sweep = MANIFEST in entries
        if not has_sweep:  # then the sweep's files are not a sweep's of vsj, or one's left
            left = [e for e in entries if _OURS.fullmatch(e)
                    or (e == ZARR and not _started_frame(self.path / ZARR))]
            if left:
                raise OutputError(f"{shown}: holds files that no sweep records ({MANIFEST} is "
                                  f"missing: {', '.join(left[:5])}); vsj did not write them, or "
                                  "it deleted what recorded them: choose another directory")
        if has_sweep and not self.resume:
            raise OutputError(f"{shown}: holds a sweep already; add --resume to finish it, or "
                              "choose another directory")
        if self.resume and not has_sweep:
            raise OutputError(f"{shown}: holds no sweep ({MANIFEST} is missing): nothing to "
                              "resume; run the command without --resume")
        for name in entries:  # what a killed sweep left; we hold the lock
            if _TEMPORARY.fullmatch(name):
                _remove(self.path / name)
        if not has_sweep and ZARR in entries:  # a store whose manifest was never written
            _remove(self.path / ZARR)
        elif ZARR in entries and (self.path / ZARR).is_dir():
            for root, _, files in os.walk(self.path / ZARR):
                for name in files:
                    if _PARTIAL.fullmatch(name):
                        with contextlib.suppress(FileNotFoundError):
                            os.unlink(os.path.join(root, name))

    def close(self):
        """Release the directory's lock."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __exit__(self, kind, *exc):
        if kind is not None and self._created and not (self.path / MANIFEST).exists():
            with contextlib.suppress(OSError):
                _remove(self.path / ZARR)
                self.path.rmdir()
        self.close()
        return False

    @property
    def zarr(self) -> Path:
        """Path of the sweep's zarr store in the directory."""
        return self.path / ZARR


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path)
    elif path.exists() or path.is_symlink():
        path.unlink()


#: Keys every sweep.json holds (a file without them is not one vsj wrote).
_REQUIRED = {"runs": int, "chunk": int, "chunks": int, "done": dict, "failed_runs": dict,
             "complete": bool}


def read_manifest(directory: Path, option: str = "--out") -> dict:
    """The sweep's manifest; `OutputError` naming the file when it cannot be read or is
    not a sweep manifest of vsj (a FIFO or a device is refused, not read)."""
    path = Path(directory) / MANIFEST
    try:
        record = json.loads(read_bytes(path, "sweep manifest", MANIFEST_BYTES))
    except InputError as exc:
        raise OutputError(f"{option} {directory}: {exc}") from None
    except ValueError as exc:
        raise OutputError(f"{option} {directory}: {MANIFEST} is not valid JSON ({exc}); it "
                          "was damaged: the sweep cannot be resumed, start it in a new "
                          "directory") from None
    bad = [k for k, kind in _REQUIRED.items()
           if not isinstance(record, dict) or not isinstance(record.get(k), kind)]
    if bad:
        raise OutputError(f"{option} {directory}: {MANIFEST} is not the manifest of a vsj sweep "
                          f"(no valid {', '.join(bad)}); start the sweep in a new directory")
    for index, entry in record["done"].items():
        if not (index.isdigit() and isinstance(entry, dict) and
                isinstance(entry.get("sha256"), str) and isinstance(entry.get("runs"), list)
                and len(entry["runs"]) == 2 and all(type(r) is int for r in entry["runs"])
                and 0 <= entry["runs"][0] < entry["runs"][1] <= record["runs"]):
            raise OutputError(f"{option} {directory}: {MANIFEST}: done.{index} is not a "
                              "finished chunk's record; start the sweep in a new directory")
    return record


def write_manifest(directory: Path, record: dict) -> None:
    """Write the sweep's manifest ``record`` into ``directory`` atomically."""
    with atomic_write(directory / MANIFEST) as handle:
        handle.write(json.dumps(record, indent=1) + "\n")


#: xarray's encoding of a NaN fill value in zarr v3 attributes (what ``to_zarr`` writes).
_NAN_FILL = "AAAAAAAA+H8="


def create(path: Path, *, varied: list[str], values: np.ndarray, units: list[str],
           time: np.ndarray, keep: list[str], keep_units: list[str], metrics: list[str],
           metric_units: list[str], chunk: int, attrs: dict) -> None:
    """Make the store: the coordinates written, the per-run arrays allocated with
    their fill values (NaN; status `NOT_RUN`) and chunked along ``run`` by ``chunk``.

    The coordinates go through xarray; the per-run arrays are made with zarr
    directly, in xarray's layout (dimension names, the ``coordinates`` attribute),
    because xarray can allocate an array without writing it only through Dask."""
    import xarray as xr  # lazy: xarray is heavy; only reading the results
    import zarr  # lazy: zarr is heavy; vsj verify of result sets needs none

    runs, n_t = len(values), len(time)
    coords = {"run": ("run", np.arange(runs)),
              "time": ("time", time, {"units": "s"}),
              "signal": ("signal", np.array(keep, dtype=object)),
              "unit": ("signal", np.array(keep_units, dtype=object)),
              "metric": ("metric", np.array(metrics, dtype=object)),
              "metric_unit": ("metric", np.array(metric_units, dtype=object))}
    for j, (name, unit) in enumerate(zip(varied, units)):
        coords[name] = ("run", values[:, j], {"units": unit})
    encoding = {name: {"chunks": (chunk,)} for name in [*varied, "run"]}
    xr.Dataset(coords=coords, attrs=attrs).to_zarr(path, mode="w", consolidated=False,
                                                  encoding=encoding)
    group = zarr.open_group(path, mode="r+")
    arrays = [
        ("signals", ("run", "time", "signal"), (runs, n_t, len(keep)),
         (chunk, max(1, n_t), max(1, len(keep))), np.float64, np.nan,
         "kept signals, SI units (see the coordinate unit)"),
        ("metrics", ("run", "metric"), (runs, len(metrics)), (chunk, max(1, len(metrics))),
         np.float64, np.nan, "metrics per run (see the coordinate metric_unit)"),
        ("status", ("run",), (runs,), (chunk,), np.int64, NOT_RUN,
         "0 ok; >0 the engine's failure status; -1 not built; -2 not run"),
        ("steps", ("run",), (runs,), (chunk,), np.int64, 0, "solver steps"),
    ]
    for name, dims, shape, chunks, dtype, fill, description in arrays:
        # the non-dimension coordinates along this array's dimensions, as xarray names them
        along = sorted(c for c, spec in coords.items() if c not in dims and spec[0] in dims)
        attributes = {"description": description, "coordinates": " ".join(along)}
        if dtype is np.float64:
            attributes["_FillValue"] = _NAN_FILL
        group.create_array(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill,
                           dimension_names=dims, attributes=attributes)


class Writer:
    """The store opened once for writing finished chunks into their regions."""

    def __init__(self, path: Path):
        import zarr  # lazy: zarr is heavy; vsj verify of result sets needs none

        group = zarr.open_group(path, mode="r+")
        self.arrays = {name: group[name] for name in ("signals", "metrics", "status", "steps")}

    def write(self, results) -> None:
        """Write finished chunks (`vsj.sweep.runner.ChunkResult`); those that follow one
        another as one region (`ChunkResult.joined`: a write costs the same for one store
        chunk as for a few)."""
        regions: list[list] = []
        for result in sorted(results, key=lambda result: result.start):
            if regions and regions[-1][-1].start + len(regions[-1][-1].status) == result.start:
                regions[-1].append(result)
            else:
                regions.append([result])
        for region in regions:
            whole = type(region[0]).joined(region)
            where = slice(whole.start, whole.start + len(whole.status))
            for name, data in (("signals", whole.kept), ("metrics", whole.metrics),
                               ("status", whole.status), ("steps", whole.steps)):
                if data.size:
                    self.arrays[name][where] = data


def digest(result) -> str:
    """SHA-256 of a chunk's numbers (recorded, so a resumed sweep can be compared).

    A NaN counts as NaN whatever its bits: a chunk that is all fill value is not
    written by zarr and reads back as the fill value's NaN."""
    return _digest((result.kept, result.metrics, result.status, result.steps))


def _digest(arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        if a.dtype.kind == "f":
            a = np.where(np.isnan(a), np.nan, a)
        h.update(a.tobytes())
    return h.hexdigest()


def open_dataset(path: Path):
    """The store as an xarray Dataset (NumPy-backed: read on access, no Dask)."""
    import xarray as xr  # lazy: xarray is heavy; only reading the results

    return xr.open_dataset(path, engine="zarr", consolidated=False, chunks=None)


def write_metrics_csv(path: Path, ds, messages: dict[str, str], varied: list[str]) -> None:
    """``metrics.csv``: one row per run: run, status, message, the varied values, the
    metrics (SI; units in the header)."""
    status = ds["status"].values
    metrics = ds["metrics"].values
    header = ["run", "status", "message"]
    header += [f"{name} [{ds[name].attrs.get('units', '')}]" for name in varied]
    header += [f"{m} [{u}]" if u else m for m, u in
               zip(ds["metric"].values.tolist(), ds["metric_unit"].values.tolist())]
    columns = [ds[name].values for name in varied]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for r in range(len(status)):
        row = [r, int(status[r]), messages.get(str(r), "ok" if status[r] == 0 else "")]
        row += [_number(c[r]) for c in columns]
        row += [_number(v) for v in metrics[r]]
        writer.writerow(row)
    with atomic_write(path) as handle:
        handle.write(buffer.getvalue())


def _number(value) -> str:
    value = float(value)
    return "" if math.isnan(value) else repr(value)


# --- what a resumed sweep must match --------------------------------------------------

def _sha256_json(value) -> str:
    return hashlib.sha256(json.dumps(value, sort_keys=True).encode()).hexdigest()


def inputs(job, spec) -> dict:
    """What the numbers of a sweep depend on, as recorded in sweep.json and compared by
    `check_resume`: hashes of the sweep file's text (with the ``--method``), the
    scenario's text, the parameter set as resolved (every value after ``extends``, SI)
    and the covariance as read (names, means, matrix), the resolved values themselves
    (to name the ones that changed), and the vsj version."""
    params = job.params
    cov = spec.covariance
    return {
        "spec_sha256": spec.sha256(),
        "scenario_sha256": hashlib.sha256(job.scenario_text.encode()).hexdigest(),
        "parameters_hash": params.hash(),
        "covariance_sha256": None if cov is None else _sha256_json(
            [list(cov.names), [repr(v) for v in cov.mean],
             [[repr(v) for v in row] for row in cov.matrix]]),
        "vsj_version": __version__,
        "parameters": {k: repr(v) for k, v in sorted(params.values.items())},
    }


def libraries() -> dict:
    """Versions of the libraries the draws come from (for messages, not compared)."""
    from importlib import metadata  # lazy: scans installed packages; only for a manifest

    out = {}
    for name in ("numpy", "scipy", "SALib"):
        with contextlib.suppress(metadata.PackageNotFoundError):
            out[name] = metadata.version(name)
    return out


def check_resume(directory: Path, record: dict, expected: dict, *, job=None,
                 spec=None) -> None:
    """`InputError` unless the sweep in ``directory`` is the one being resumed: the same
    inputs (`inputs`), run count and chunk size. The message names what changed."""
    def refuse(what: str, detail: str = "") -> None:
        raise InputError(f"--resume {directory}: {what}{detail}; a resumed sweep must run "
                         "with what started it: restore that, or start a new directory")

    older = [k for k in [*expected, "frame"] if k not in record]
    if older:
        refuse(f"the sweep there was started by a vsj that did not record "
               f"{', '.join(older)}", "")
    if record["vsj_version"] != expected["vsj_version"]:
        refuse(f"it was started by vsj {record['vsj_version']}, this is vsj "
               f"{expected['vsj_version']}")
    if record["spec_sha256"] != expected["spec_sha256"]:
        shown = spec.origin if spec is not None else "the sweep file"
        refuse(f"the sweep file {shown} (or --method) has changed since the sweep there "
               "started")
    if record["scenario_sha256"] != expected["scenario_sha256"]:
        shown = job.scenario_origin if job is not None else "the scenario"
        refuse(f"the scenario {shown} has changed since the sweep there started")
    if record["parameters_hash"] != expected["parameters_hash"]:
        shown = (job.params.origin if job is not None else "the parameter set")
        then, now = record.get("parameters") or {}, expected["parameters"]
        changed = sorted(k for k in set(then) | set(now) if then.get(k) != now.get(k))
        detail = "; ".join(f"{k}: {_si(then.get(k), k)} there, {_si(now.get(k), k)} now"
                           for k in changed[:5])
        more = f" and {len(changed) - 5} more" if len(changed) > 5 else ""
        refuse(f"the parameter set {shown} (with every file it extends) has changed since "
               "the sweep there started", f" ({detail}{more})" if detail else "")
    if record["covariance_sha256"] != expected["covariance_sha256"]:
        shown = spec.covariance.origin if spec is not None and spec.covariance else \
            "the covariance file"
        refuse(f"the covariance file {shown} has changed since the sweep there started "
               "(its names, values or covariance differ)")
    for key, what in (("runs", "the number of runs"), ("chunk", "the chunk size (--chunk)")):
        if record[key] != expected[key]:
            refuse(f"{what} differs from the sweep there ({record[key]} there, "
                   f"{expected[key]} now)")


def _si(text, key: str) -> str:
    if text is None:
        return "absent"
    section, _, name = key.partition(".")
    unit = SCHEMA.get(section, {}).get(name)
    return f"{text} {unit.unit}" if unit is not None and unit.unit != "1" else str(text)


# --- the store's frame: metadata and coordinates -----------------------------------

def _metadata_files(path: Path) -> list[str]:
    """The zarr.json files under the store ``path`` (relative, sorted)."""
    out = []
    for root, _, files in os.walk(path):
        if "zarr.json" in files:
            out.append(os.path.relpath(os.path.join(root, "zarr.json"), path))
    return sorted(p.replace(os.sep, "/") for p in out)


def _values_sha256(values: np.ndarray) -> str:
    values = np.asarray(values)
    if values.dtype.kind in "OUST":
        return _sha256_json([str(v) for v in values.ravel().tolist()])
    return _digest([values.astype(values.dtype.newbyteorder("<"))])


def frame_record(path: Path) -> dict:
    """SHA-256 of each metadata file of the store ``path`` and of each coordinate's
    values (everything but the chunks' arrays `DATA`)."""
    import zarr  # lazy: zarr is heavy; vsj verify of result sets needs none

    group = zarr.open_group(path, mode="r")
    coordinates = {name: _values_sha256(group[name][...]) for name in sorted(group.array_keys())
                   if name not in DATA}
    return {"metadata": {f: file_record(path / f)["sha256"] for f in _metadata_files(path)},
            "coordinates": coordinates}


def check_frame(path: Path, recorded: dict) -> list[str]:
    """What differs between the store's frame and ``recorded`` (`frame_record`): each
    metadata file missing, changed or unreadable, each coordinate changed."""
    import zarr  # lazy: zarr is heavy; vsj verify of result sets needs none

    shown = f"{ZARR}"
    if not path.is_dir():
        return [f"{shown} is missing"]
    problems = []
    for name, sha in sorted(recorded.get("metadata", {}).items()):
        file = path / name
        if not regular_file(file):
            problems.append(f"{shown}/{name} is missing" if not os.path.lexists(file) else
                            f"{shown}/{name} is not a regular file")
        elif file_record(file)["sha256"] != sha:
            problems.append(f"{shown}/{name} has changed (its SHA-256 differs)")
    if problems:
        return problems
    try:
        group = zarr.open_group(path, mode="r")
        for name, sha in sorted(recorded.get("coordinates", {}).items()):
            if _values_sha256(group[name][...]) != sha:
                problems.append(f"{shown}: the coordinate {name} has changed (a file under "
                                f"{shown}/{name} changed or was deleted)")
    except Exception as exc:  # noqa: BLE001 - any failure to decode the store is damage
        problems.append(f"{shown}: cannot be read ({type(exc).__name__}: {exc})")
    return problems


def _started_frame(path: Path) -> bool:
    """Whether ``path`` is a store frame a new sweep was making when it was stopped, before
    it recorded the sweep: a directory, empty, or whose group carries the attributes
    `create` gives it."""
    if path.is_symlink() or not path.is_dir():
        return False
    if not any(path.iterdir()):
        return True
    try:
        meta = json.loads(read_bytes(path / "zarr.json", "store metadata", 1 << 20))
    except (OSError, InputError, ValueError):
        return False
    attributes = meta.get("attributes") if isinstance(meta, dict) else None
    return isinstance(attributes, dict) and {"vsj_version", "sweep_file", "sweep"} <= set(
        attributes)


def build_frame(directory: Path, make) -> Path:
    """A new frame made by ``make(path)`` (`create`) in a temporary directory beside the
    store (`install_frame` moves it in; a killed process leaves it for `Directory` to
    remove)."""
    temp = directory / f".{ZARR}.vsj-tmp-{secrets.token_hex(8)}"
    make(temp)
    return temp


def install_frame(temp: Path, path: Path) -> None:
    """Replace the frame of the store ``path`` (its metadata and coordinates) by the one
    built in ``temp``, keeping the chunks' arrays (checked by `check_chunks` after)."""
    path.mkdir(exist_ok=True)
    for root, _, files in os.walk(path):
        top = os.path.relpath(root, path).split(os.sep)[0]
        for name in files:
            if top not in DATA or (root == str(path / top) and name == "zarr.json"):
                os.unlink(os.path.join(root, name))
    for root, _, files in os.walk(temp):
        for name in files:
            source = Path(root) / name
            target = path / source.relative_to(temp)
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(source, target)
    shutil.rmtree(temp)


# --- the chunks -------------------------------------------------------------------

def check_chunks(path: Path, record: dict, progress=None) -> dict[int, str]:
    """The finished chunks of ``record`` whose numbers in the store ``path`` no longer
    match their recorded SHA-256, each with what is wrong (a chunk file changed,
    truncated or deleted). ``progress(runs)`` is called as chunks are read."""
    import zarr  # lazy: zarr is heavy; vsj verify of result sets needs none

    done = record["done"]
    try:
        group = zarr.open_group(path, mode="r")
        arrays = [group[name] for name in DATA]
    except Exception as exc:  # noqa: BLE001 - an unreadable store: every chunk is lost
        return {int(i): f"the store cannot be read ({type(exc).__name__})" for i in done}
    bad = {}
    for index, entry in done.items():
        a, b = entry["runs"]
        try:
            numbers = [array[a:b] for array in arrays]
        except Exception as exc:  # noqa: BLE001 - a chunk file zarr cannot decode
            bad[int(index)] = f"a file of it cannot be decoded ({type(exc).__name__}: {exc})"
        else:
            if _digest(numbers) != entry["sha256"]:
                bad[int(index)] = ("its numbers differ from the SHA-256 recorded in "
                                   f"{MANIFEST} (a chunk file changed or was deleted)")
        if progress is not None:
            progress(b - a)
    return bad


def _failures_disagree(path: Path, record: dict, damaged: set[int]) -> list[str]:
    """Where the failed runs ``record`` names (its ``failed_runs`` and each chunk's
    ``failed`` count) are not the runs whose status in the store ``path`` says they
    failed, chunk by chunk (those in ``damaged`` left out: their numbers are wrong
    already). The chunks' hashes cover the store, not these lines of the record."""
    import zarr  # lazy: zarr is heavy; vsj verify of result sets needs none

    try:
        status = np.asarray(zarr.open_group(path, mode="r")["status"][:])
    except Exception:  # noqa: BLE001 - an unreadable store: check_chunks says so
        return []
    named = {int(r) for r in record.get("failed_runs", {})}
    problems = []
    for index, entry in sorted(record["done"].items(), key=lambda kv: int(kv[0])):
        if int(index) in damaged:
            continue
        a, b = entry["runs"]
        failed = {a + int(k) for k in np.flatnonzero(status[a:b] != 0)}
        listed = {r for r in named if a <= r < b}
        if failed != listed or entry.get("failed") != len(failed):
            problems.append(f"{MANIFEST}: chunk {index} ({runs_text(a, b)}): the failed runs it "
                            f"records ({', '.join(map(str, sorted(listed))) or 'none'}) are not "
                            f"those whose status in {ZARR} failed "
                            f"({', '.join(map(str, sorted(failed))) or 'none'})")
    return problems


def runs_text(start: int, stop: int) -> str:
    """``"run 4"`` or ``"runs 4 to 7"`` for the runs ``start`` to ``stop - 1``."""
    return f"run {start}" if stop - start == 1 else f"runs {start} to {stop - 1}"


def drop_chunks(record: dict, bad) -> None:
    """Forget the chunks ``bad`` (indices) and their failed runs, to run them again."""
    for index in bad:
        a, b = record["done"].pop(str(index))["runs"]
        for r in range(a, b):
            record["failed_runs"].pop(str(r), None)
    record["complete"] = False


def _chunk_grid(path: Path, name: str) -> list[int] | None:
    """The chunk grid of the store's array ``name`` (chunks along each dimension), from
    its metadata; None where that cannot be read."""
    try:
        meta = json.loads(read_bytes(path / name / "zarr.json", "zarr metadata", 1 << 20))
        shape = meta["shape"]
        chunks = meta["chunk_grid"]["configuration"]["chunk_shape"]
        return [math.ceil(n / c) for n, c in zip(shape, chunks, strict=True)]
    except (InputError, ValueError, KeyError, TypeError, ZeroDivisionError):
        return None


def _is_chunk_key(rel: str, name: str, grid: list[int]) -> bool:
    """Whether ``rel`` is the file of a chunk of the array ``name`` (``NAME/c/i/j``)."""
    parts = rel.split("/")
    if parts[:2] != [name, "c"] or len(parts) != 2 + len(grid):
        return False
    return all(p.isdigit() and int(p) < g for p, g in zip(parts[2:], grid))


def foreign_in_store(path: Path, recorded: dict) -> list[str]:
    """Files under the store ``path`` that are neither its recorded metadata nor chunk
    files of its arrays (relative paths; zarr's partial files of a killed write count)."""
    expected = set(recorded.get("metadata", {}))
    arrays = {f.split("/")[0] for f in expected if "/" in f}
    grids = {name: _chunk_grid(path, name) for name in arrays}
    unknown = []
    for root, _, files in os.walk(path):
        for name in files:
            rel = os.path.relpath(os.path.join(root, name), path).replace(os.sep, "/")
            top = rel.split("/")[0]
            if rel in expected:
                continue
            if top in arrays and grids[top] is None and rel.startswith(f"{top}/c/"):
                continue  # its array's metadata is damaged, which is reported
            if top in arrays and grids[top] is not None and \
                    _is_chunk_key(rel, top, grids[top]) and regular_file(path / rel):
                continue
            unknown.append(rel)
    return sorted(unknown)


# --- the sweep's size ----------------------------------------------------------------

#: Bytes of one metrics.csv value (``repr`` of a float64 and a comma) and of a run's
#: status message (the longest are setup failures naming a parameter and its range).
CSV_VALUE_BYTES = 25
MESSAGE_BYTES = 300
#: zarr's bytes per stored chunk file beyond its numbers (zstd frame and block headers
#: of data that does not compress), and per chunk in sweep.json.
CHUNK_OVERHEAD = 1024
#: Figures of a sweep at most (histograms, scatter, versus q, sensitivity), each at most
#: `vsj.output.PLOT_BYTES`, and summary.html holds them again in base64 (4/3 larger).
FIGURES = 4


def estimate(runs: int, chunks: int, samples: int, kept: int, metrics: int,
             varied: int, *, figures: bool = True) -> int:
    """A conservative bound on the bytes ``runs`` runs in ``chunks`` chunks write: the
    store's numbers uncompressed (zstd never grows them beyond its headers), the
    manifest written twice over (atomic replacement), metrics.csv, the page and (with
    ``figures``) the figures."""
    numbers = runs * (8 * samples * kept + 8 * metrics + 16)
    manifest = 2 * (chunks * 256 + runs * MESSAGE_BYTES)
    table = runs * (CSV_VALUE_BYTES * (3 + varied + metrics) + MESSAGE_BYTES)
    # the PNGs, and again in base64 (4/3 larger) in the page; the page's tables besides
    pictures = FIGURES * PLOT_BYTES * 3 if figures else 0
    page = PLOT_BYTES + runs * MESSAGE_BYTES  # statistics, and a row per failed run
    return numbers + len(DATA) * chunks * CHUNK_OVERHEAD + manifest + table + pictures + page


def size_text(count: float) -> str:
    """Bytes as text in decimal units (``"1.6 TB"``)."""
    for unit, size in (("PB", 1e15), ("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{int(count)} bytes"


def free_bytes(path: Path) -> int:
    """Bytes free for this user on the file system of ``path`` (or its nearest parent)."""
    path = Path(path)
    while not path.exists() and path != path.parent:
        path = path.parent
    info = os.statvfs(path)
    return info.f_bavail * info.f_frsize


# --- verify ------------------------------------------------------------------------

def verify(directory: str | Path) -> list[str]:
    """What is wrong with the sweep in ``directory`` (empty when it is complete and every
    file and chunk is as its ``sweep.json`` records it): each missing, changed or
    foreign file, each chunk whose numbers changed, and an unfinished sweep. Reads only
    regular files (a FIFO or a device is named, never opened for reading)."""
    directory = Path(directory)
    try:
        record = read_manifest(directory, "")
    except OutputError as exc:
        return [str(exc).strip()]
    problems = []
    files = record.get("files", {}) if isinstance(record.get("files"), dict) else {}
    for entry in sorted(os.listdir(directory)):
        path = directory / entry
        if entry in (MANIFEST, ZARR):
            if entry == ZARR and not path.is_dir():
                problems.append(f"{ZARR} is not a directory")
            continue
        if _TEMPORARY.fullmatch(entry):
            problems.append(f"{entry}: left by an interrupted vsj sweep (--resume removes it)")
        elif entry in files:
            continue
        elif _OURS.fullmatch(entry) and not record["complete"]:
            problems.append(f"{entry}: not recorded in {MANIFEST} (written by the unfinished "
                            "sweep, or not by vsj)")
        else:
            problems.append(f"{entry}: a foreign file (not recorded in {MANIFEST})")
    problems += recorded_file_problems(directory, files)
    frame = record.get("frame")
    if not isinstance(frame, dict):
        problems.append(f"{MANIFEST} records no store frame (written by an older vsj)")
        return problems
    damaged = check_frame(directory / ZARR, frame)
    problems += damaged
    if (directory / ZARR).is_dir():
        for rel in foreign_in_store(directory / ZARR, frame):
            kind = ("left by an interrupted write (--resume removes it)"
                    if _PARTIAL.fullmatch(rel.rsplit("/", 1)[-1]) else
                    f"a foreign file (not a file of the store that {MANIFEST} records)")
            problems.append(f"{ZARR}/{rel}: {kind}")
    if (directory / ZARR).is_dir():
        damaged = check_chunks(directory / ZARR, record)
        for index, why in sorted(damaged.items()):
            a, b = record["done"][str(index)]["runs"]
            problems.append(f"{ZARR}: chunk {index} ({runs_text(a, b)}): {why}")
        problems += _failures_disagree(directory / ZARR, record, set(damaged))
    missing = [i for i in range(record["chunks"]) if str(i) not in record["done"]]
    if record["complete"] and missing:
        shown = ", ".join(map(str, missing[:5])) + (", ..." if len(missing) > 5 else "")
        problems.append(f"{MANIFEST} calls the sweep complete but records {len(missing)} of its "
                        f"{record['chunks']} chunks as not done (chunk {shown}): their runs "
                        "are not checked")
    if not record["complete"]:
        problems.append(f"the sweep is unfinished ({len(record['done'])} of "
                        f"{record['chunks']} chunks done, tables not written): run the "
                        "sweep's command again with --resume")
    return problems


__all__ = [
    "DATA",
    "MANIFEST",
    "METRICS",
    "NOT_RUN",
    "ZARR",
    "Directory",
    "build_frame",
    "check_chunks",
    "check_frame",
    "check_resume",
    "create",
    "digest",
    "drop_chunks",
    "estimate",
    "foreign_in_store",
    "frame_record",
    "free_bytes",
    "inputs",
    "install_frame",
    "libraries",
    "open_dataset",
    "read_manifest",
    "runs_text",
    "size_text",
    "verify",
    "Writer",
    "write_manifest",
    "write_metrics_csv",
]

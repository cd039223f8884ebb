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

``sweep.zarr`` holds, over ``run``, ``time`` and ``signal``: ``signals`` (the kept
signals, SI, their units in the coordinate ``unit``), ``metrics`` (over ``run`` and
``metric``), ``status`` (0: ok; an engine status; -1: not built; -2: not run yet)
and ``steps``; each varied quantity is a coordinate over ``run`` with its unit.
Its attributes carry the vsj version, the parameter set's hash, the scenario,
and the sweep file's text.
"""

from __future__ import annotations

import csv
import fcntl
import io
import json
import math
import os
import re
import shutil
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..output import OUTPUTS, OutputError, atomic_write

ZARR = "sweep.zarr"
MANIFEST = "sweep.json"
METRICS = "metrics.csv"
#: Status of a run not simulated yet (in the store's fill value).
NOT_RUN = -2
_OURS = re.compile(OUTPUTS["sweep"])


class Directory:
    """The locked output directory of one sweep (a context manager)."""

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
            raise OutputError(f"{shown}: another vsj command is writing to this directory")
        entries = sorted(os.listdir(self.path))
        foreign = [e for e in entries if not (e == ZARR or _OURS.fullmatch(e) or
                                              e.startswith(f".{MANIFEST}.vsj-tmp-"))]
        if foreign:
            self.close()
            raise OutputError(f"{shown}: holds files that vsj did not write "
                              f"({', '.join(foreign[:5])}); choose another directory")
        has_sweep = MANIFEST in entries
        if has_sweep and not self.resume:
            self.close()
            raise OutputError(f"{shown}: holds a sweep already; add --resume to finish it, or "
                              "choose another directory")
        if self.resume and not has_sweep:
            self.close()
            raise OutputError(f"{shown}: holds no sweep ({MANIFEST} is missing): nothing to "
                              "resume")
        if not has_sweep and ZARR in entries:  # a store whose manifest was never written
            shutil.rmtree(self.path / ZARR)
        return self

    def close(self):
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __exit__(self, *exc):
        self.close()
        return False

    @property
    def zarr(self) -> Path:
        return self.path / ZARR


def read_manifest(directory: Path) -> dict:
    try:
        return json.loads((directory / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise OutputError(f"--out {directory}: cannot read {MANIFEST} ({exc})") from None


def write_manifest(directory: Path, record: dict) -> None:
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
    import xarray as xr
    import zarr

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
        import zarr

        group = zarr.open_group(path, mode="r+")
        self.arrays = {name: group[name] for name in ("signals", "metrics", "status", "steps")}

    def write(self, result, stop: int) -> None:
        """Write one finished chunk (runs ``result.start .. stop``)."""
        region = slice(result.start, stop)
        for name, data in (("signals", result.kept), ("metrics", result.metrics),
                           ("status", result.status), ("steps", result.steps)):
            if data.size:
                self.arrays[name][region] = data


def digest(result) -> str:
    """SHA-256 of a chunk's numbers (recorded, so a resumed sweep can be compared)."""
    import hashlib

    h = hashlib.sha256()
    for a in (result.kept, result.metrics, result.status, result.steps):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def open_dataset(path: Path):
    """The store as an xarray Dataset (NumPy-backed: read on access, no Dask)."""
    import xarray as xr

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


def check_resume(directory: Path, record: dict, expected: dict) -> None:
    """`InputError` unless the sweep in ``directory`` is the one being resumed."""
    for key in ("spec_sha256", "job", "runs", "chunk", "vsj_version"):
        if record.get(key) != expected[key]:
            what = {"spec_sha256": "the sweep file (or --method)", "job": "the scenario or "
                    "parameter file", "runs": "the number of runs", "chunk": "the chunk size",
                    "vsj_version": "the vsj version"}[key]
            raise InputError(f"--resume {directory}: {what} differs from the sweep there "
                             f"({key}: {record.get(key)!r} there, {expected[key]!r} now); "
                             "finish it with what started it, or start a new directory")


__all__ = [
    "MANIFEST",
    "METRICS",
    "NOT_RUN",
    "ZARR",
    "Directory",
    "check_resume",
    "create",
    "digest",
    "open_dataset",
    "read_manifest",
    "Writer",
    "write_manifest",
    "write_metrics_csv",
]

"""Trajectories on disk: the samples of runs as netCDF and CSV, streamed or at once.

A run's signals (`vsj.simulate.signals.catalogue`: name, unit, description) become the
variables of a netCDF file (their attributes) and the columns of a CSV file (their
headers); `TrajectoryFile` receives a long run's samples block by block
(`vsj.simulate.simulate`'s sink), so memory stays flat whatever the duration. Every
file is written through `vsj.output.files.atomic_write`.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from .. import __version__
from ..netcdf import ClassicFile, Variable
from ..params import SCHEMA, Parameters
from ..simulate import Result
from .files import atomic_write, start_writeback

def signals_bound(structure) -> int:
    """At most the number of signals `vsj.simulate.simulate` returns for ``structure``
    (counted as `vsj.simulate.collect` makes them: angle and speed per named or free
    flange, q and its rate, three per source, two per load, four per motor, three per
    friction element, five per spring, two per constraint for the port flows)."""
    return (2 * (len(structure.signals) + len(structure.free)) + 2
            + 3 * len(structure.sources) + 2 * len(structure.loads) + 4 * len(structure.motors)
            + 3 * len(structure.frictions) + 5 * len(structure.springs)
            + 2 * len(structure.constraint_names))


#: Bytes of a float64 as the trajectory CSV writes it (``repr``: at most 24 characters)
#: with its separator.
CSV_BYTES_PER_VALUE = 25
#: Upper bounds of the small files of a simulation: the plot, meta.json per case, manifest.
PLOT_BYTES = 4 * 2 ** 20
META_BYTES_PER_CASE = 2 ** 20


def trajectory_bytes(samples: int, signals: int, cases: int, *, csv: bool, plot: bool) -> int:
    """A conservative bound on the bytes `vsj simulate` writes: the netCDF file (8 bytes
    per value, a header per variable), the CSV file, the plot, meta.json."""
    values = samples * signals * cases
    size = 8 * values + 8 * samples + 256 * (signals + 8) + META_BYTES_PER_CASE * cases
    if csv:
        size += CSV_BYTES_PER_VALUE * (values + samples) + 64 * signals * cases
    if plot:
        size += PLOT_BYTES
    return size


# --- trajectories and metadata -----------------------------------------------------

def column_name(signal: str, unit: str, label: str | None) -> str:
    """A CSV column's header: ``signal@label [unit]`` (without ``@label`` for one case)."""
    name = signal if label is None else f"{signal}@{label}"
    return f"{name} [{unit}]"


def trajectory_table(runs: Sequence[tuple[str, Result]]) -> tuple[list[str], np.ndarray]:
    """Header and data of the trajectory CSV (one column block per case)."""
    if not runs:
        raise ValueError("no runs to write")
    longest = max(runs, key=lambda r: len(r[1].time))[1].time
    header = ["time [s]"]
    columns = [longest]
    single = len(runs) == 1
    for label, result in runs:
        for name in result.columns():
            header.append(column_name(name, result.units[name], None if single else label))
            values = np.full(len(longest), np.nan)
            values[:len(result.time)] = result.signals[name]
            columns.append(values)
    return header, np.column_stack(columns)


def write_trajectory(path: Path, runs: Sequence[tuple[str, Result]]) -> None:
    """Write the trajectory CSV of ``runs`` (label, result) to ``path``, every value
    with all its digits, an empty field where a run has no sample."""
    header, data = trajectory_table(runs)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for row in data:
        writer.writerow(["" if math.isnan(v) else repr(float(v)) for v in row])
    with atomic_write(path) as handle:
        handle.write(buffer.getvalue())


def cases_dataset(runs: Sequence[tuple[str, Result]]):
    """Several runs on one time grid as one `xarray.Dataset` with a ``case``
    dimension (a failed run's missing samples are NaN), each signal with its
    unit; each case's success is the variable ``success``."""
    import xarray as xr  # lazy: heavy, and only the dataset functions need it

    if not runs:
        raise ValueError("no runs to write")
    time = max(runs, key=lambda r: len(r[1].time))[1].time
    names = list(dict.fromkeys(name for _, result in runs for name in result.columns()))
    units, texts = {}, {}
    data = {}
    for name in names:
        values = np.full((len(runs), len(time)), np.nan)
        for k, (_, result) in enumerate(runs):
            if name in result.signals:
                values[k, :len(result.time)] = result.signals[name]
                units[name] = result.units[name]
                texts.setdefault(name, result.descriptions.get(name))
        data[name] = (("case", "time"), values,
                      {"units": units[name], **({"long_name": texts[name]} if texts[name] else {})})
    data["success"] = ("case", np.array([int(r.success) for _, r in runs], dtype=np.int32))
    ds = xr.Dataset(data, coords={"case": ("case", [label for label, _ in runs]),
                                  "time": ("time", time, {"units": "s"})})
    ds.attrs.update(vsj_version=__version__,
                    description="vsj simulate: signals [SI units] of each case over time")
    return ds


def write_cases(path: Path, runs: Sequence[tuple[str, Result]]) -> None:
    """Write `cases_dataset` (``runs``) as the netCDF file `write_dataset` makes of it,
    without building the dataset: the same dimensions, variables, attributes and
    encoding (xarray's for netCDF-3: float NaN as fill value, labels as UTF-8
    characters), written by SciPy's netCDF-3 writer, which is what xarray uses for
    this format. Importing xarray (and through it Dask) costs a ``vsj simulate``
    more than simulating and writing; reading the file back with xarray gives
    `cases_dataset`'s dataset (tested)."""
    from scipy.io import netcdf_file  # lazy: heavy, and only reading back needs it

    if not runs:
        raise ValueError("no runs to write")
    time = max(runs, key=lambda r: len(r[1].time))[1].time
    names = list(dict.fromkeys(name for _, result in runs for name in result.columns()))
    labels = [label.encode("utf-8") for label, _ in runs]
    width = max(1, max(len(label) for label in labels))
    chars = np.zeros((len(labels), width), dtype="S1")
    for k, label in enumerate(labels):
        chars[k, :len(label)] = np.frombuffer(label, dtype="S1")
    with atomic_write(Path(path), "wb") as handle:
        f = netcdf_file(handle, "w", version=2)
        f.vsj_version = __version__
        f.description = "vsj simulate: signals [SI units] of each case over time"
        f.createDimension("case", len(runs))
        f.createDimension("time", len(time))
        f.createDimension(f"string{width}", width)
        v = f.createVariable("time", "d", ("time",))
        v[:] = time
        v.units, v._FillValue = "s", math.nan
        v = f.createVariable("case", "c", ("case", f"string{width}"))
        v[:] = chars
        v._Encoding = "utf-8"
        for name in names:
            v = f.createVariable(name, "d", ("case", "time"))
            values = v.data
            text = None
            for k, (_, result) in enumerate(runs):
                n = len(result.time) if name in result.signals else 0
                if n:
                    values[k, :n] = result.signals[name]
                    units = result.units[name]
                    text = text or result.descriptions.get(name)
                values[k, n:] = math.nan  # a failed run's missing samples, a missing signal
            v.units, v._FillValue = units, math.nan
            if text:
                v.long_name = text
        v = f.createVariable("success", "i", ("case",))
        v[:] = np.array([int(r.success) for _, r in runs], dtype=np.int32)
        f.flush()  # not close(): that would close the handle, which atomic_write syncs


class TrajectoryFile:
    """``trajectory.nc`` of `vsj simulate` written while its cases run: the layout of
    `write_cases` (a variable per signal over ``case`` and ``time`` with its unit and
    description, ``case`` labels, ``success``), its header first and each block of
    samples put where it belongs as the engine produces it (`vsj.netcdf`), so that
    memory stays flat whatever the duration. `case` gives the sink of one case for
    `vsj.simulate.simulate`; samples a run did not reach, and signals a case does not
    have, read as NaN. Used as a context manager on an open binary handle."""

    def __init__(self, handle, labels: Sequence[str], time: np.ndarray, tables):

        self.labels = list(labels)
        self.time = np.asarray(time, dtype=float)
        self.specs: dict[str, tuple[str, str]] = {}
        for table in tables:  # the union of the cases' signals, in first-seen order
            for spec in table:
                self.specs.setdefault(spec.name, (spec.unit, spec.description))
        raw = [label.encode("utf-8") for label in self.labels]
        width = max(1, max(len(r) for r in raw))
        variables = [Variable("time", ("time",), "d", {"units": "s", "_FillValue": math.nan}),
                     Variable("case", ("case", f"string{width}"), "c", {"_Encoding": "utf-8"})]
        variables += [Variable(name, ("case", "time"), "d",
                               {"units": unit, "long_name": text, "_FillValue": math.nan})
                      for name, (unit, text) in self.specs.items()]
        variables.append(Variable("success", ("case",), "i", {}))
        self.file = ClassicFile(handle, {"case": len(raw), "time": len(self.time),
                                         f"string{width}": width},
                                {"vsj_version": __version__, "description": "vsj simulate: "
                                 "signals [SI units] of each case over time"}, variables)
        self.file.write("time", self.time)
        chars = np.zeros((len(raw), width), dtype="S1")
        for k, label in enumerate(raw):
            chars[k, :len(label)] = np.frombuffer(label, dtype="S1")
        self.file.write("case", chars)
        self.tables = [[spec.name for spec in table] for table in tables]
        self.reached = [0] * len(raw)
        self.success = [0] * len(raw)

    def case(self, k: int) -> "_CaseSink":
        """The sink of case ``k`` (`vsj.simulate.MemorySink`'s protocol)."""
        return _CaseSink(self, k)

    def read(self, name: str, k: int, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Samples ``start:stop`` of signal ``name`` in case ``k`` (from the file)."""
        stop = len(self.time) if stop is None else stop
        count = max(0, stop - start)
        offset = self.file.begin[name] + 8 * (k * len(self.time) + start)
        data = os.pread(self.file.fd, 8 * count, offset)
        return np.frombuffer(data, dtype=">f8").astype(float)

    def names(self, k: int) -> list[str]:
        """The signals of case ``k``, in its own order."""
        return self.tables[k]

    def close(self) -> None:
        """Record each case's success; the file is complete after this."""
        self.file.write("success", np.array(self.success, dtype=np.int32))


def write_trajectory_csv(path: Path, trajectory: TrajectoryFile, *,
                         rows_per_block: int = 4096) -> None:
    """The CSV of `write_trajectory` made from a `TrajectoryFile`, a block of rows at a
    time (the file's samples are never all in memory)."""
    labels = trajectory.labels
    single = len(labels) == 1
    header = ["time [s]"]
    columns = []
    for k, label in enumerate(labels):
        for name in trajectory.names(k):
            unit = trajectory.specs[name][0]
            header.append(column_name(name, unit, None if single else label))
            columns.append((name, k))
    total = len(trajectory.time)
    with atomic_write(path) as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(header)
        for start in range(0, total, rows_per_block):
            stop = min(total, start + rows_per_block)
            block = np.column_stack([trajectory.time[start:stop]]
                                    + [trajectory.read(name, k, start, stop)
                                       for name, k in columns])
            writer.writerows(["" if math.isnan(v) else repr(float(v)) for v in row]
                             for row in block)


class _CaseSink:
    """One case of a `TrajectoryFile`: writes each block into the case's rows."""

    keeps_samples = False

    def __init__(self, trajectory: TrajectoryFile, k: int):
        self.trajectory, self.k = trajectory, k

    def begin(self, table, time: np.ndarray) -> None:
        if len(time) != len(self.trajectory.time):
            raise ValueError("every case of a trajectory file has the file's sample times")
        self.names = [spec.name for spec in table]
        self.units = {spec.name: spec.unit for spec in table}

    def write(self, start: int, signals: Mapping[str, np.ndarray]) -> None:
        for name, values in signals.items():
            self.trajectory.file.write(name, values, (self.k, start))

    def end(self, samples: int) -> tuple[np.ndarray, dict, dict]:
        t = self.trajectory
        total = len(t.time)
        own = set(self.names)
        for name in t.specs:  # NaN where the run did not reach, or has no such signal
            first = samples if name in own else 0
            for start in range(first, total, 2 ** 20):
                stop = min(total, start + 2 ** 20)
                t.file.write(name, np.full(stop - start, np.nan), (self.k, start))
        t.reached[self.k] = samples
        start_writeback(t.file.fd)  # the case's samples are final: to disk while others run
        return t.time[:samples], {}, self.units


def write_dataset(path: Path, ds) -> None:
    """Write a dataset as netCDF (classic format, which MATLAB's ncread, xarray,
    netCDF4 and most tools read), through a temporary file that replaces
    ``path`` on success."""
    with atomic_write(Path(path), "wb") as handle:
        ds.to_netcdf(handle, engine="scipy", format="NETCDF3_64BIT")


def read_trajectory(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and data of a trajectory CSV written by `write_trajectory`."""
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        rows = [[float(v) if v else math.nan for v in row] for row in reader]
    return header, np.array(rows)


def parameters_record(params: Parameters) -> dict:
    """The parameter set as a result's metadata records it: origin, hash, and each
    entry's SI value, unit, text as written and source."""
    values = {}
    for section, specs in SCHEMA.items():
        for name, spec in specs.items():
            key = f"{section}.{name}"
            values[key] = {"si": params[key], "unit": spec.unit, "text": params.texts[key],
                           "source": params.sources[key]}
    return {"origin": params.origin, "hash": params.hash(), "values": values}

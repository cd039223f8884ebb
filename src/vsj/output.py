"""Writing results: trajectory CSV, run metadata JSON, atomically.

Files are written to a temporary name in the target directory and renamed
into place, so an interrupted or failed write never leaves a half file where a
good one stood.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import tempfile
from pathlib import Path
from typing import Sequence

import numpy as np

from . import __version__
from .errors import InputError
from .params import Parameters
from .simulate import Result


@contextlib.contextmanager
def atomic_write(path: Path, mode: str = "w"):
    """Write ``path`` through a temporary file that replaces it on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it private; results are ordinary files
    try:
        with os.fdopen(fd, mode, encoding=None if "b" in mode else "utf-8",
                       newline="" if "b" not in mode else None) as handle:
            yield handle
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def column_name(signal: str, unit: str, label: str | None) -> str:
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
    import xarray as xr

    if not runs:
        raise ValueError("no runs to write")
    time = max(runs, key=lambda r: len(r[1].time))[1].time
    names = list(dict.fromkeys(name for _, result in runs for name in result.columns()))
    units = {}
    data = {}
    for name in names:
        values = np.full((len(runs), len(time)), np.nan)
        for k, (_, result) in enumerate(runs):
            if name in result.signals:
                values[k, :len(result.time)] = result.signals[name]
                units[name] = result.units[name]
        data[name] = (("case", "time"), values, {"units": units[name]})
    data["success"] = ("case", np.array([int(r.success) for _, r in runs], dtype=np.int32))
    ds = xr.Dataset(data, coords={"case": ("case", [label for label, _ in runs]),
                                  "time": ("time", time, {"units": "s"})})
    ds.attrs.update(vsj_version=__version__,
                    description="vsj simulate: signals [SI units] of each case over time")
    return ds


def write_dataset(path: Path, ds) -> None:
    """Write a dataset as netCDF (classic format, which MATLAB's ncread, xarray,
    netCDF4 and most tools read), through a temporary file that replaces
    ``path`` on success."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(fd)
    try:
        ds.to_netcdf(tmp, engine="scipy", format="NETCDF3_64BIT")
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def read_trajectory(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and data of a trajectory CSV written by `write_trajectory`."""
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        rows = [[float(v) if v else math.nan for v in row] for row in reader]
    return header, np.array(rows)


def parameters_record(params: Parameters) -> dict:
    from .params import SCHEMA

    values = {}
    for section, specs in SCHEMA.items():
        for name, spec in specs.items():
            key = f"{section}.{name}"
            values[key] = {"si": params[key], "unit": spec.unit, "text": params.texts[key],
                           "source": params.sources[key]}
    return {"origin": params.origin, "hash": params.hash(), "values": values}


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else str(v)
    if isinstance(value, (np.integer,)):
        return int(value)
    return value


def write_meta(path: Path, record: dict) -> None:
    record = {"vsj_version": __version__, **record}
    text = json.dumps(_jsonable(record), indent=2, sort_keys=False)
    with atomic_write(path) as handle:
        handle.write(text + "\n")


def ensure_output_dir(path: Path) -> Path:
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"--out {path}: exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"--out {path}: cannot create directory ({exc.strerror})") from None
    return path

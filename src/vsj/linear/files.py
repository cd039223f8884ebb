"""Linear models in files: JSON (everything as text) or NumPy ``.npz``."""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path
from collections.abc import Mapping

import numpy as np

from .. import __version__
from ..errors import TEXT_BYTES, InputError, read_bytes
from ..output import _jsonable, atomic_write
from .data import FRICTION_TREATMENTS, LinearData

#: File format tag of `save`/`load`.
FORMAT = "vsj-linear-model"
FORMAT_VERSION = 1


def to_dict(model: LinearData) -> dict:
    """The model as plain data (the JSON file's content; see `save`)."""
    def named(names, units):
        return [{"name": n, "unit": u} for n, u in zip(names, units)]

    op = model.operating_point
    return {
        "format": FORMAT, "version": FORMAT_VERSION, "name": model.name,
        "time": "continuous",
        "equations": "dx/dt = A x + B u, y = C x + D u, all deviations from the operating "
                     "point, SI units",
        "friction": {"treatment": model.friction,
                     "description": FRICTION_TREATMENTS.get(model.friction, "")},
        "operating_point": {"q": op.get("q"), "states": op.get("states", {}),
                            "inputs": op.get("inputs", {}), "outputs": op.get("outputs", {})},
        "states": named(model.state_labels, model.state_units),
        "inputs": named(model.input_labels, model.input_units),
        "outputs": named(model.output_labels, model.output_units),
        "A": model.A.tolist(), "B": model.B.tolist(), "C": model.C.tolist(),
        "D": model.D.tolist(),
        "info": model.info,
    }


def from_dict(data: Mapping, *, origin: str = "data", statespace: bool = True):
    """A `LinearModel` (or with ``statespace=False`` a `LinearData`) from `to_dict`'s
    output; `InputError` names what is wrong."""
    if data.get("format") != FORMAT:
        raise InputError(f"{origin}: not a vsj linear model (format {data.get('format')!r}, "
                         f"expected {FORMAT!r})")
    if data.get("version") != FORMAT_VERSION:
        raise InputError(f"{origin}: unsupported version {data.get('version')!r} (this vsj "
                         f"reads version {FORMAT_VERSION})")
    try:
        mats = {k: np.array(data[k], dtype=float) for k in "ABCD"}
        states, inputs, outputs = data["states"], data["inputs"], data["outputs"]
        op = data["operating_point"]
        ns, ni, no = len(states), len(inputs), len(outputs)
        mats = {k: v.reshape(shape) for (k, v), shape in
                zip(mats.items(), [(ns, ns), (ns, ni), (no, ns), (no, ni)])}
        model = LinearData(
            mats["A"], mats["B"], mats["C"], mats["D"],
            state_labels=[s["name"] for s in states], input_labels=[s["name"] for s in inputs],
            output_labels=[s["name"] for s in outputs],
            state_units=[s["unit"] for s in states], input_units=[s["unit"] for s in inputs],
            output_units=[s["unit"] for s in outputs], operating_point=op,
            friction=data["friction"]["treatment"], info=data.get("info", {}),
            name=data.get("name", "wrist"))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"{origin}: malformed linear model ({type(exc).__name__}: {exc})") \
            from None
    return model.statespace() if statespace else model


def save(model: LinearData, path: Path) -> None:
    """Write ``.json`` (everything as text) or ``.npz`` (matrices as arrays, names and
    units as string arrays, the rest as JSON text under ``meta``)."""
    path = Path(path)
    data = _jsonable(to_dict(model))
    if path.suffix == ".json":
        with atomic_write(path) as handle:
            handle.write(json.dumps(data, indent=1) + "\n")
    elif path.suffix == ".npz":
        meta = {k: v for k, v in data.items() if k not in "ABCD"}
        with atomic_write(path, "wb") as handle:
            np.savez(handle, A=model.A, B=model.B, C=model.C, D=model.D,
                     states=np.array(model.state_labels), inputs=np.array(model.input_labels),
                     outputs=np.array(model.output_labels),
                     state_units=np.array(model.state_units),
                     input_units=np.array(model.input_units),
                     output_units=np.array(model.output_units), meta=np.array(json.dumps(meta)),
                     vsj_version=np.array(__version__))
    else:
        raise InputError(f"{path}: write a linear model to a .json or .npz file")


def load(path: Path, *, statespace: bool = True):
    """Read a file written by `save` (a `LinearModel`, or with ``statespace=False`` a
    `LinearData`); a regular file of at most `vsj.errors.TEXT_BYTES`."""
    path = Path(path)
    if path.suffix not in (".json", ".npz"):
        raise InputError(f"{path}: a linear model file ends in .json or .npz")
    data = read_bytes(path, "linear model file", TEXT_BYTES)
    try:
        if path.suffix == ".json":
            return from_dict(json.loads(data.decode("utf-8")), origin=str(path),
                             statespace=statespace)
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            meta = json.loads(str(z["meta"]))
            for k in "ABCD":
                meta[k] = z[k]
            return from_dict(meta, origin=str(path), statespace=statespace)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        raise InputError(f"{path}: cannot read a linear model ({exc})") from None



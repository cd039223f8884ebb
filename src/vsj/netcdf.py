"""A netCDF classic file written in slabs, as a long run produces its samples.

The classic format (64-bit offsets, CDF-2) stores each fixed-size variable as one
contiguous big-endian array after a header that gives every size and offset. When
the sizes are known before the data, as a simulation's are (cases, samples,
signals), the header can be written first and each block of samples put straight
where it belongs, so that nothing larger than a block is ever held in memory.
SciPy's writer (`scipy.io.netcdf_file`), which the rest of vsj uses for small files,
keeps every variable in memory until it closes the file; netCDF4-python writes
slabs but brings the netCDF and HDF5 C libraries with it. This module writes only
what vsj's trajectories need: dimensions of fixed size, text, 32-bit integer and
double variables, and attributes of those types. xarray, SciPy, netCDF4 and
MATLAB's ``ncread`` read what it writes (tested with the first two).

The layout follows the netCDF classic format specification (Unidata, "The NetCDF
Classic Format Specification"): ``CDF\\x02``, the record count, the dimension,
global attribute and variable lists (each name padded to four bytes), then the
data of each variable at the offset its entry gives.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from collections.abc import Mapping

import numpy as np

_DIMENSION, _VARIABLE, _ATTRIBUTE = 10, 11, 12
#: netCDF type code and big-endian NumPy type of each variable type vsj writes.
TYPES = {"c": (2, "S1"), "i": (4, ">i4"), "d": (6, ">f8")}


@dataclass
class Variable:
    """A variable: its name, dimension names, type (``"c"`` text, ``"i"`` int32,
    ``"d"`` double) and attributes (text, int or float values)."""

    name: str
    dims: tuple[str, ...]
    kind: str
    attrs: Mapping[str, object] = field(default_factory=dict)


def _int32(value: int) -> bytes:
    return int(value).to_bytes(4, "big", signed=True)


def _vsize(size: int) -> bytes:
    """A variable's size field: unsigned, and 2^32 - 1 for one too large for it (the
    specification's rule; readers take the size from the dimensions)."""
    return (size if size < 2 ** 32 - 4 else 2 ** 32 - 1).to_bytes(4, "big", signed=False)


def _name(text: str) -> bytes:
    raw = text.encode("utf-8")
    return _int32(len(raw)) + raw + b"\0" * (-len(raw) % 4)


def _attribute(name: str, value) -> bytes:
    if isinstance(value, str):
        raw = value.encode("utf-8")
        body = _int32(2) + _int32(len(raw)) + raw + b"\0" * (-len(raw) % 4)
    elif isinstance(value, (bool, np.bool_)):
        raise TypeError(f"attribute {name}: no boolean type in netCDF classic")
    elif isinstance(value, (int, np.integer)):
        body = _int32(4) + _int32(1) + _int32(value)
    else:
        body = _int32(6) + _int32(1) + np.array(float(value), ">f8").tobytes()
    return _name(name) + body


def _attributes(attrs: Mapping[str, object]) -> bytes:
    if not attrs:
        return b"\0" * 8
    return (_int32(_ATTRIBUTE) + _int32(len(attrs))
            + b"".join(_attribute(k, v) for k, v in attrs.items()))


class ClassicFile:
    """A netCDF classic file on an open binary ``handle`` (positioned at 0; it must
    allow ``os.pwrite`` on its descriptor): the header is written at once, the file
    sized, and each variable's data written with `write` as it comes. Parts never
    written read as zeros; the caller writes every value it means (``NaN`` fill
    included)."""

    def __init__(self, handle, dims: Mapping[str, int], attrs: Mapping[str, object],
                 variables: list[Variable]):
        self.fd = handle.fileno()
        self.dims = dict(dims)
        self.variables = {v.name: v for v in variables}
        if len(self.variables) != len(variables):
            raise ValueError("variable names must be unique")
        ids = {name: k for k, name in enumerate(self.dims)}
        self.shape = {v.name: tuple(self.dims[d] for d in v.dims) for v in variables}
        #: elements per step of each index of a variable (its C-order strides), and in all
        self.strides = {name: tuple(math.prod(shape[k + 1:]) for k in range(len(shape)))
                        for name, shape in self.shape.items()}
        self.count = {name: math.prod(shape) for name, shape in self.shape.items()}
        self.size = {}
        for v in variables:
            item = np.dtype(TYPES[v.kind][1]).itemsize
            raw = int(np.prod(self.shape[v.name], dtype=np.int64)) * item
            self.size[v.name] = raw + (-raw % 4)

        parts = [b"CDF\x02", _int32(0)]
        if self.dims:
            parts += [_int32(_DIMENSION), _int32(len(self.dims))]
            parts += [_name(d) + _int32(n) for d, n in self.dims.items()]
        else:
            parts.append(b"\0" * 8)
        parts.append(_attributes(attrs))
        parts += [_int32(_VARIABLE), _int32(len(variables))] if variables else [b"\0" * 8]
        slots = {}  # where each variable's begin (a fixed 8 bytes) goes among the parts
        for v in variables:
            parts += [_name(v.name), _int32(len(v.dims))]
            parts += [_int32(ids[d]) for d in v.dims]
            parts += [_attributes(v.attrs), _int32(TYPES[v.kind][0]),
                      _vsize(self.size[v.name])]
            slots[v.name] = len(parts)
            parts.append(bytes(8))
        offset = sum(map(len, parts))  # the data start after the header
        self.begin = {}
        for v in variables:
            self.begin[v.name] = offset
            parts[slots[v.name]] = offset.to_bytes(8, "big", signed=True)
            offset += self.size[v.name]
        self.total = offset
        os.pwrite(self.fd, b"".join(parts), 0)
        os.ftruncate(self.fd, self.total)

    def write(self, name: str, values, index: tuple[int, ...] = ()) -> None:
        """Write ``values`` into variable ``name`` from the element at ``index`` (leading
        indices; the values fill the trailing dimensions in C order, contiguously)."""
        v = self.variables[name]
        data = np.ascontiguousarray(values, dtype=TYPES[v.kind][1])
        if len(index) > len(self.shape[name]):
            raise ValueError(f"{name}: index {index} has more entries than the variable has "
                             f"dimensions {v.dims}")
        start = sum(int(i) * step for i, step in zip(index, self.strides[name]))
        count = data.size
        if start + count > self.count[name]:
            raise ValueError(f"{name}: writing {count} values at {index} overruns "
                             f"{self.shape[name]}")
        # the array's own buffer: tobytes() would copy every block once more
        os.pwrite(self.fd, data, self.begin[name] + start * data.itemsize)

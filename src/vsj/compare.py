"""Compare a trajectory with a reference result, as Modelica's regression tests do.

The Modelica Association checks every tool's result against published
reference curves with a *tube*: around each reference curve, the set of
points within ``X`` in time and ``Y`` in value of it (the curve swept by a
rectangle of half-width ``X`` and half-height ``Y``). A result passes when
every one of its samples lies inside. Both half-sizes are a fraction
``relative`` (MSL: 2e-3) of the reference's span: ``X`` of its duration,
``Y`` of its range (never below an absolute ``floor``, for signals that
hardly move). The width in time lets a discontinuity, such as the speed kink
when a clutch locks, come a little early or late without failing the test;
the height bounds the error everywhere else.

`tube` checks one signal; `read_csv` reads a reference file (a Modelica CSV:
a header of quoted names, a ``time`` column, rows repeated at event instants);
`changes` lists the instants at which a mode signal switches, for comparing
stick/slip intervals.
"""

from __future__ import annotations

import csv
import gzip
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

#: The MSL regression tests' relative tube size.
RELATIVE = 2e-3


@dataclass(frozen=True)
class TubeReport:
    """Result of `tube`.

    ``usage`` is the largest distance of a sample from the reference's extent
    in its window, in units of the half-height ``Y``: inside means usage <= 1.
    """

    name: str
    usage: float
    worst_time: float
    half_width: float
    half_height: float
    samples: int
    outside: int

    @property
    def inside(self) -> bool:
        """True if no sample leaves the tube (``outside == 0``)."""
        return self.outside == 0

    def __str__(self) -> str:
        verdict = "inside" if self.inside else f"OUTSIDE at {self.outside} of"
        return (f"{self.name}: {verdict} {self.samples} samples; worst at t = "
                f"{self.worst_time:.6g} s, {self.usage:.3g} of the half-height "
                f"{self.half_height:.3g} (half-width {self.half_width:.3g} s)")


def _curve(time, values, what: str) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(time, dtype=float)
    y = np.asarray(values, dtype=float)
    if t.ndim != 1 or t.shape != y.shape or t.size < 2:
        raise InputError(f"{what}: time and values must be 1-D of the same length >= 2, got "
                         f"shapes {t.shape} and {y.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(y))):
        raise InputError(f"{what}: time and values must be finite")
    if np.any(np.diff(t) < 0.0):
        raise InputError(f"{what}: time must not decrease")
    return t, y


def _window_extremes(t_ref, y_ref, t, half_width):
    """Largest and smallest value of the piecewise-linear reference over
    ``[t - X, t + X]`` for each ``t``: the vertices inside the window and the
    curve's values at its two ends."""
    lo = np.searchsorted(t_ref, t - half_width, side="left")
    hi = np.searchsorted(t_ref, t + half_width, side="right")
    ends = np.vstack([np.interp(t - half_width, t_ref, y_ref),
                      np.interp(t + half_width, t_ref, y_ref)])
    top, bottom = ends.max(axis=0), ends.min(axis=0)
    # ufunc.reduceat over the windows [lo, hi): interleave the bounds; a
    # sentinel makes hi == len valid, and empty windows are masked out
    nonempty = hi > lo
    if np.any(nonempty):
        idx = np.empty(2 * int(nonempty.sum()), dtype=np.intp)
        idx[0::2], idx[1::2] = lo[nonempty], hi[nonempty]
        padded_max = np.append(y_ref, -np.inf)
        padded_min = np.append(y_ref, np.inf)
        top[nonempty] = np.maximum(top[nonempty], np.maximum.reduceat(padded_max, idx)[0::2])
        bottom[nonempty] = np.minimum(bottom[nonempty],
                                      np.minimum.reduceat(padded_min, idx)[0::2])
    return top, bottom


def tube(reference_time, reference_values, time, values, *, relative: float = RELATIVE,
         floor: float = 1e-9, time_relative: float | None = None,
         name: str = "signal") -> TubeReport:
    """Check the samples ``(time, values)`` against the tube around the
    reference curve (see the module's description). ``time_relative`` sets
    the half-width apart from the height (0: a purely vertical tube, the
    stricter test). Samples outside the reference's time span are not judged;
    the result must cover that span."""
    time_relative = relative if time_relative is None else time_relative
    if not (math.isfinite(relative) and 0.0 < relative < 1.0):
        raise InputError(f"tube: relative size must be in (0, 1), got {relative!r}")
    if not (math.isfinite(time_relative) and 0.0 <= time_relative < 1.0):
        raise InputError(f"tube: relative half-width must be in [0, 1), got {time_relative!r}")
    if not (math.isfinite(floor) and floor > 0.0):
        raise InputError(f"tube: floor must be > 0, got {floor!r}")
    t_ref, y_ref = _curve(reference_time, reference_values, f"reference of {name}")
    t, y = _curve(time, values, name)
    span = t_ref[-1] - t_ref[0]
    if t[0] > t_ref[0] + 1e-9 * span or t[-1] < t_ref[-1] - 1e-9 * span:
        raise InputError(f"{name}: the result covers [{t[0]:g}, {t[-1]:g}] s, the reference "
                         f"[{t_ref[0]:g}, {t_ref[-1]:g}] s")
    half_width = time_relative * span
    half_height = max(relative * float(np.ptp(y_ref)), floor)
    keep = (t >= t_ref[0]) & (t <= t_ref[-1])
    t, y = t[keep], y[keep]
    top, bottom = _window_extremes(t_ref, y_ref, t, half_width)
    usage = np.maximum(y - top, bottom - y) / half_height
    worst = int(np.argmax(usage))
    return TubeReport(name=name, usage=max(float(usage[worst]), 0.0),
                      worst_time=float(t[worst]), half_width=half_width,
                      half_height=half_height, samples=int(t.size),
                      outside=int(np.count_nonzero(usage > 1.0)))


def read_csv(path) -> dict[str, np.ndarray]:
    """Columns of a reference CSV (header of names, one row per sample, rows
    repeated at events; gzip-compressed if its name ends in ``.gz``) as float
    arrays keyed by name; must have ``time``."""
    path = Path(path)
    try:
        raw = path.read_bytes()
        text = gzip.decompress(raw) if path.suffix == ".gz" else raw
        rows = list(csv.reader(io.StringIO(text.decode("utf-8"), newline="")))
    except OSError as exc:
        raise InputError(f"{path}: cannot read the reference "
                         f"({exc.strerror or exc})") from None
    except (UnicodeDecodeError, EOFError, csv.Error) as exc:
        raise InputError(f"{path}: not a text CSV file ({exc})") from None
    if len(rows) < 3:
        raise InputError(f"{path}: a reference needs a header and at least two rows")
    names = [name.strip() for name in rows[0]]
    if "time" not in names:
        raise InputError(f"{path}: no 'time' column in the header (columns: "
                         f"{', '.join(names[:8])})")
    data = np.empty((len(rows) - 1, len(names)))
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(names):
            raise InputError(f"{path}, line {line}: {len(row)} fields, the header has "
                             f"{len(names)}")
        try:
            data[line - 2] = [float(field) for field in row]
        except ValueError:
            raise InputError(f"{path}, line {line}: every field must be a number") from None
    columns = {name: data[:, k] for k, name in enumerate(names)}
    if not np.all(np.isfinite(data)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(data), axis=1))[0]) + 2
        raise InputError(f"{path}, line {bad}: values must be finite")
    if np.any(np.diff(columns["time"]) < 0.0):
        bad = int(np.flatnonzero(np.diff(columns["time"]) < 0.0)[0]) + 3
        raise InputError(f"{path}, line {bad}: time goes backwards")
    return columns


def changes(time, mode) -> list[tuple[float, float, float]]:
    """The instants at which a piecewise-constant ``mode`` signal switches:
    (time of the first sample with the new value, old value, new value)."""
    time = np.asarray(time, dtype=float)
    mode = np.asarray(mode, dtype=float)
    at = np.flatnonzero(mode[1:] != mode[:-1]) + 1
    return [(float(time[k]), float(mode[k - 1]), float(mode[k])) for k in at]


def on_grid(time, mode, grid) -> np.ndarray:
    """A mode signal (with repeated rows at its switches) sampled on ``grid``:
    at a grid time that is also a switch instant, the value after the switch."""
    time = np.asarray(time, dtype=float)
    k = np.searchsorted(time, np.asarray(grid, dtype=float), side="right") - 1
    return np.asarray(mode)[np.clip(k, 0, len(time) - 1)]

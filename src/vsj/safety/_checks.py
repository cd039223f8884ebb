"""Checks of the arguments of `vsj.safety`: each failure is an `InputError` that names
the function, the argument, the value and what is allowed."""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError


def number(where: str, name: str, value, unit: str, *, positive: bool = True,
           allow_inf: bool = False) -> float:
    """``value`` as a float: finite (or ``inf`` when ``allow_inf``), and > 0 when
    ``positive`` (else >= 0)."""
    if isinstance(value, bool):
        raise InputError(f"{where}: {name} must be a number [{unit}], got {value!r}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {name} must be a number [{unit}], got {value!r}") from None
    bound = "> 0" if positive else ">= 0"
    if math.isnan(out) or (math.isinf(out) and not (allow_inf and out > 0)):
        allowed = f"a finite number {bound}" + (" or inf" if allow_inf else "")
        raise InputError(f"{where}: {name} must be {allowed} [{unit}], got {value!r}")
    if out < 0 or (positive and out == 0):
        raise InputError(f"{where}: {name} must be {bound} [{unit}], got {value!r}")
    return out


def series(where: str, name: str, values, length: int | None, unit: str,
           *, columns: bool = False) -> np.ndarray:
    """``values`` as a float array of finite samples: one value a sample (shape ``(n,)``),
    or, with ``columns``, also one row a sample (``(n, m)``); ``length`` samples when
    given."""
    try:
        out = np.array(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {name} must be an array of numbers [{unit}]") from None
    allowed = (1, 2) if columns else (1,)
    if out.ndim not in allowed:
        shape = "(samples,) or (samples, elements)" if columns else "(samples,)"
        raise InputError(f"{where}: {name} must have shape {shape}, got shape {out.shape}")
    if length is not None and out.shape[0] != length:
        raise InputError(f"{where}: {name} has {out.shape[0]} samples, time has {length}; "
                         f"every signal needs one value per time sample")
    bad = np.argwhere(~np.isfinite(out))
    if bad.size:
        at = tuple(int(i) for i in bad[0])
        index = at[0] if out.ndim == 1 else at
        raise InputError(f"{where}: {name}[{index}] is {float(out[at])!r}; every sample "
                         f"must be a finite number [{unit}]")
    return out


def time_axis(where: str, time, minimum: int = 2) -> np.ndarray:
    """Sample times [s]: finite, strictly increasing, at least ``minimum`` of them."""
    t = series(where, "time", time, None, "s")
    if t.size < minimum:
        raise InputError(f"{where}: time needs at least {minimum} samples, got {t.size}")
    steps = np.diff(t)
    if np.any(steps <= 0):
        i = int(np.flatnonzero(steps <= 0)[0])
        raise InputError(f"{where}: time must increase strictly; time[{i + 1}] = "
                         f"{float(t[i + 1])!r} s follows time[{i}] = {float(t[i])!r} s")
    return t


def non_negative(where: str, name: str, values: np.ndarray, unit: str, what: str) -> None:
    """Refuse a negative sample of ``values``, saying what the signal must be."""
    if np.any(values < 0):
        i = int(np.flatnonzero(values < 0)[0])
        raise InputError(f"{where}: {name}[{i}] = {float(values[i])!r} {unit} is negative; "
                         f"{what}")

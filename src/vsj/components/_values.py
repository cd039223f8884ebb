"""Checks of component parameters shared by the component modules."""

from __future__ import annotations

import math


def _positive(name: str, value: float, *, allow_zero: bool = True) -> float:
    """``value`` as a float, refused unless >= 0 (or > 0 without ``allow_zero``)."""
    value = float(value)
    ok = value >= 0.0 if allow_zero else value > 0.0
    if not ok or math.isnan(value):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be {bound}, got {value!r}")
    return value


def _stiction(name: str, stiction: float, coulomb: float | None) -> float:
    """The report's stiction parameter ``k`` [N m], given as ``k`` itself or as the
    Coulomb level ``coulomb = k pi/2`` (not both)."""
    if coulomb is None:
        return _positive(f"stiction of {name}", stiction)
    if stiction:
        raise ValueError(f"{name}: give the stiction parameter k or the Coulomb level, not both")
    return _positive(f"Coulomb level of {name}", coulomb) * 2.0 / math.pi


def _peak(name: str, peak: float) -> float:
    """A static-to-kinetic friction ratio (MSL's ``peak``): finite and >= 1."""
    peak = float(peak)
    if not (math.isfinite(peak) and peak >= 1.0):
        raise ValueError(f"peak of {name} (static over kinetic friction) must be >= 1, got "
                         f"{peak!r}")
    return peak

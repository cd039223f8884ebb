"""Checks of the basic elements' arguments, by the kinds of quantity `vsj.params`
declares.

A bound is not written here: each argument of a basic element (`Inertia`,
`Bearing`, ...) is checked against its kind (`vsj.params.INERTIA`, `VISCOUS`,
...). The parts of the wrist take their parameters from the schema itself
(`vsj.components._fields`), so a bound is declared once and holds for files and
for code alike.
"""

from __future__ import annotations

import math

from ..params import PEAK, STICTION, Spec


def _check(name: str, kind: Spec, value: float) -> float:
    """``value`` as a float, refused with a `ValueError` naming ``name`` unless ``kind``
    allows it."""
    return kind.require(name, value)


def _stiction(name: str, stiction: float, coulomb: float | None) -> float:
    """The report's stiction parameter ``k`` [N m], given as ``k`` itself or as the
    Coulomb level ``coulomb = k pi/2`` (not both)."""
    if coulomb is None:
        return STICTION.require(f"stiction of {name}", stiction)
    if stiction:
        raise ValueError(f"{name}: give the stiction parameter k or the Coulomb level, not both")
    return STICTION.require(f"Coulomb level of {name}", coulomb) * 2.0 / math.pi


def _peak(name: str, peak: float) -> float:
    """A static-to-kinetic friction ratio (MSL's ``peak``): finite and >= 1."""
    return PEAK.require(f"peak of {name} (static over kinetic friction)", peak)

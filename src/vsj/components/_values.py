"""Checks of component arguments, by the kinds of quantity `vsj.params` declares.

A component's bounds are not written here: each argument is checked against
its kind (`vsj.params.INERTIA`, `VISCOUS`, ...) or, where the component takes
a parameter file's own names, against that parameter's schema entry, so a
bound is declared once and holds for files and for code alike.
"""

from __future__ import annotations

import math

from ..params import PEAK, SCHEMA, STICTION, Spec


def _check(name: str, kind: Spec, value: float) -> float:
    """``value`` as a float, refused with a `ValueError` naming ``name`` unless ``kind``
    allows it."""
    return kind.require(name, value)


def _section(component: str, section: str, **values: float) -> dict[str, float]:
    """Arguments named as in the parameter file's ``[section]``, each checked against
    its schema entry."""
    return {key: SCHEMA[section][key].require(f"{component}: {key}", value)
            for key, value in values.items()}


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

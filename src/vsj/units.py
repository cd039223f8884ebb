"""Unit parsing at the boundary: text with units in, SI floats out.

Every number inside vsj is SI (rad, m, kg, s, N m, V, A, ohm, H). Files and
the command line may use any unit pint understands, for example ``"-1.45 1/cm"``,
``"-0.4 cm"``, ``"100 rpm"`` or ``"5 mN m"``; `to_si` converts them and checks
that the dimension is the expected one. Radians are dimensionless, as in SI, so
``"N m"`` and ``"N m/rad"`` share a dimension.

pint is imported on first use only: it costs about 0.3 s, which a process that
never reads a unit should not pay.
"""

from __future__ import annotations

import functools
import math

from .errors import InputError


@functools.lru_cache(maxsize=1)
def registry():
    """The shared pint registry (created once per process)."""
    import pint

    try:
        return pint.UnitRegistry(cache_folder=":auto:")
    except OSError:  # read-only home: a registry without a disk cache works too
        return pint.UnitRegistry()


@functools.lru_cache(maxsize=256)
def _unit(unit: str):
    return registry().Unit(unit)


def to_si(text: str | float | int, unit: str, *, where: str) -> float:
    """Parse ``text`` (a number with a unit) and return its value in the SI unit.

    ``unit`` is the SI unit the quantity must be convertible to (``"1"`` for a
    dimensionless number, in which case a bare number is accepted). ``where``
    names the origin (file and key) for the error message.
    """
    import pint

    ureg = registry()
    target = _unit(unit)
    dimensionless = target.dimensionless
    if isinstance(text, bool):
        raise InputError(f"{where}: expected a number with unit {unit!r}, got {text!r}")
    if isinstance(text, (int, float)):
        if not dimensionless:
            raise InputError(
                f"{where}: value {text!r} has no unit; write it with a unit "
                f"convertible to {unit!r}, for example \"{text} {unit}\""
            )
        value = float(text)
    elif isinstance(text, str):
        try:
            quantity = ureg.Quantity(text.strip())
        except (pint.errors.PintError, ValueError, TypeError, AttributeError, SyntaxError) as exc:
            raise InputError(f"{where}: cannot read {text!r} as a quantity ({exc})") from None
        if not isinstance(quantity, ureg.Quantity):  # a bare number parsed from text
            quantity = ureg.Quantity(float(quantity))
        if quantity.unitless and not dimensionless:
            raise InputError(
                f"{where}: value {text!r} has no unit; expected a unit convertible to {unit!r}"
            )
        try:
            value = float(quantity.to(target).magnitude)
        except pint.errors.DimensionalityError:
            raise InputError(
                f"{where}: {text!r} has unit {quantity.units:~}, which cannot be converted "
                f"to {unit!r}"
            ) from None
    else:
        raise InputError(f"{where}: expected a number with a unit, got {type(text).__name__}")
    if math.isnan(value):
        raise InputError(f"{where}: value is NaN")
    return value


def from_si(value: float, unit: str) -> float:
    """Convert an SI value to ``unit`` (for display and plots)."""
    ureg = registry()
    return float(ureg.Quantity(value, _si_of(unit)).to(_unit(unit)).magnitude)


@functools.lru_cache(maxsize=256)
def _si_of(unit: str):
    return registry().Quantity(1.0, _unit(unit)).to_base_units().units


def format_quantity(value: float, unit: str, digits: int = 6) -> str:
    """Text such as ``"-0.4 cm"`` for an SI value shown in ``unit``."""
    shown = from_si(value, unit) if unit not in ("1", "") else value
    text = f"{shown:.{digits}g}"
    return text if unit in ("1", "") else f"{text} {unit}"

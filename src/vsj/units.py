"""Unit parsing at the boundary: text with units in, SI floats out.

Every number inside vsj is SI (rad, m, kg, s, N m, V, A, ohm, H). Files and
the command line write a quantity as a number and a unit, for example
``"-1.45 1/cm"``, ``"-0.4 cm"``, ``"100 rpm"``, ``"5 mN m"`` or
``"1 rad/(N m)"``; `to_si` converts it and checks that the dimension is the
expected one. Radians are dimensionless, as in SI, so ``"N m"`` and
``"N m/rad"`` share a dimension.

The text is checked against that form before pint sees it: one decimal number,
then unit names joined by spaces, ``*`` or ``/``, with integer exponents of one
digit (``m^2``, ``s**-1``), a ``1`` only as in ``1/cm``, and at most one level
of parentheses. Nothing is evaluated: pint is handed the number as a float and
the unit text alone, which by then is a product of powers of names.

pint is imported on first use only: it costs about 0.3 s, which a process that
never reads a unit should not pay.
"""

from __future__ import annotations

import functools
import math
import re

from .errors import InputError

#: The form `to_si` accepts, for messages.
FORM = ("a number and a unit, such as \"-0.4 cm\", \"6.47e-5 kg m^2\" or \"1 rad/(N m)\": "
        "unit names joined by spaces, * or /, exponents from -9 to 9 (m^2, s^-1) and at most "
        "one level of parentheses")
#: Longest quantity text read (the longest in vsj's own files is 20 characters).
MAX_LENGTH = 100

_NUMBER = re.compile(r"\s*([+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf(?:inity)?))",
                     re.IGNORECASE)
_TOKEN = re.compile(r"\s*(?:(?P<name>(?:[^\W\d]|[°%])\w*)|(?P<one>1)(?![\w.])"
                    r"|(?P<power>(?:\^|\*\*)[+-]?\d(?!\d))|(?P<op>[*/()]))")


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


def _check_unit(unit: str) -> str | None:
    """Why ``unit`` is not a product of powers of unit names, or None."""
    depth, operand, powered = 0, False, False  # inside (), after a factor, after its exponent
    position = 0
    while position < len(unit):
        m = _TOKEN.match(unit, position)
        if m is None or m.end() == position:
            rest = unit[position:].lstrip()
            return f"unexpected {rest[:10]!r} at character {len(unit) - len(rest) + 1} of the unit"
        position = m.end()
        kind, token = m.lastgroup, m.group(m.lastgroup)
        if token == "(":
            depth, operand = depth + 1, False
            if depth > 1:
                return "parentheses inside parentheses"
        elif kind in ("name", "one"):
            if kind == "name" and not all(c.isalpha() or c.isdecimal() or c in "_°%"
                                          for c in token):
                return f"{token!r} is not a unit name (letters, digits and _ only)"
            operand, powered = True, False
        elif kind == "power":
            if not operand:
                return f"exponent {token!r} without a unit name before it"
            if powered:
                return f"a second exponent {token!r} in a row"
            powered = True
        elif token == ")":
            if depth == 0 or not operand:
                return "a ')' without its '(' or an empty pair of parentheses"
            depth, powered = depth - 1, False
        elif operand:  # * or /
            operand = False
        else:
            return f"{token!r} without a unit name before it"
    if depth:
        return "a '(' that is not closed"
    if unit and not operand:
        return "the unit ends with an operator"
    return None


def to_si(text: str | float | int, unit: str, *, where: str, infinite: bool = False) -> float:
    """Parse ``text`` (a number with a unit) and return its finite value in the SI unit.

    ``unit`` is the SI unit the quantity must be convertible to (``"1"`` for a
    dimensionless number, in which case a bare number is accepted). ``where``
    names the origin (file and key) for the error message. Anything but `FORM`,
    and values that are NaN, infinite, or overflow or underflow on conversion,
    raise `InputError`; with ``infinite``, a written ``inf`` (such as
    ``"inf N m/rad"``, a rigid stop) is returned as +inf.
    """
    import pint

    target = _unit(unit)
    dimensionless = target.dimensionless
    if isinstance(text, bool) or not isinstance(text, (int, float, str)):
        raise InputError(f"{where}: expected {FORM}; got {type(text).__name__} {text!r}")
    if isinstance(text, (int, float)):
        if not dimensionless:
            raise InputError(
                f"{where}: value {text!r} has no unit; write it with a unit "
                f"convertible to {unit!r}, for example \"{text} {unit}\""
            )
        value = float(text)
    else:
        if len(text) > MAX_LENGTH:
            raise InputError(f"{where}: a quantity of {len(text)} characters; expected {FORM} "
                             f"(at most {MAX_LENGTH} characters)")
        number = _NUMBER.match(text)
        if number is None:
            raise InputError(f"{where}: {text!r} does not start with a number; expected {FORM}")
        unit_text = text[number.end():].strip()
        why = _check_unit(unit_text)
        if why:
            raise InputError(f"{where}: cannot read {text!r}: {why}; expected {FORM}")
        value = float(number.group(1))
        if not unit_text and not dimensionless:
            raise InputError(
                f"{where}: value {text!r} has no unit; expected a unit convertible to {unit!r}"
            )
        try:
            parsed = _unit(unit_text)
            converted = float(registry().Quantity(value, parsed).to(target).magnitude)
        except pint.errors.DimensionalityError:
            raise InputError(f"{where}: {text!r} has unit {parsed:~}, which cannot be "
                             f"converted to {unit!r}") from None
        except (pint.errors.PintError, ValueError, TypeError, AttributeError) as exc:
            raise InputError(f"{where}: cannot read the unit of {text!r} ({exc})") from None
        if converted == 0.0 and value != 0.0:
            raise InputError(f"{where}: {text!r} is too small to represent in {unit} (below "
                             "5e-324)")
        value = converted
        if infinite and value == math.inf and number.group(1).lower().lstrip("+") in (
                "inf", "infinity"):
            return value
    if not math.isfinite(value):
        raise InputError(f"{where}: {text!r} is not a finite number in {unit} (NaN, infinite, "
                         "or beyond the largest floating-point number, 1.8e308)")
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

"""Unit parsing at the boundary: text with units in, SI floats out.

Every number inside vsj is SI (rad, m, kg, s, N m, V, A, ohm, H). Files and
the command line write a quantity as a number and a unit, for example
``"-1.45 1/cm"``, ``"-0.4 cm"``, ``"100 rpm"``, ``"5 mN m"`` or
``"1 rad/(N m)"``; `to_si` converts it and checks that the dimension is the
expected one. Radians are dimensionless, as in SI, so ``"N m"`` and
``"N m/rad"`` share a dimension.

The text is checked against that form before anything converts it: one decimal
number, then unit names joined by spaces, ``*`` or ``/``, with integer exponents
of one digit (``m^2``, ``s**-1``), a ``1`` only as in ``1/cm``, and at most one
level of parentheses. As in pint, ``*``, ``/`` and a space bind equally from left
to right (``"N/m s"`` is N s/m). Nothing is evaluated: pint, where it is asked,
is handed the number as a float and the unit text alone.

Conversion factors
------------------
A unit made only of the names in `definitions` (the SI units of mechanics and
electricity with their prefixes, radian, degree, turn, rpm, minute, hour,
percent, and the inch, foot, pound, ounce and pound-force of the 1959
international yard and pound) is converted here, from the exact definition of
each name: a rational number times a power of pi times a product of powers of
m, kg, s and A. A unit text's factor is exact until its single last rounding,
to the nearest float, so the same text gives the same float in every process,
on every machine and with every pint version. Every unit in vsj's own files and
commands is of this kind. Any other unit (a plural such as ``"meters"``, an
offset unit such as ``degC``, ``mdeg``) is converted by pint, in the process
that meets it.

Why the factors are defined in code and not cached: importing pint (which
imports Dask) and building its registry is a large share of a warm
``vsj simulate fig-4.15`` (``benchmarks/units_startup.py`` measures both), which
is why earlier versions kept pint's factors in a file in the user's cache
directory. A factor in a file is only as right as the file: one
edited or damaged entry (``deg`` to ``rad`` = 1) silently turned degrees into
radians, and nothing short of asking pint again could tell; asking pint costs what
the file saved. A checksum would catch a damaged file but not an edited one. A
factor derived from definitions in the code can change only with the code, and
the tests compare every name of `definitions` with pint: its dimension, and its
factor within pint's own rounding (pint multiplies rounded factors along each
name's chain of definitions, so its foot is 0.30479999999999996 m; the factor
here is the nearest float to the exact one). So no file outside vsj and pint
takes part in a conversion: pint's registry is built without its disk cache
too, and files that earlier versions left in ``~/.cache/vsj`` are never read.
"""

from __future__ import annotations

import functools
import math
import re
from fractions import Fraction
from typing import NamedTuple

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
    """The shared pint registry (created once per process, without pint's disk cache)."""
    import pint  # lazy: pint is heavy; only units outside vsj's own table

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
    if isinstance(text, bool) or not isinstance(text, (int, float, str)):
        raise InputError(f"{where}: expected {FORM}; got {type(text).__name__} {text!r}")
    if isinstance(text, (int, float)):
        value, unit_text, written = float(text), "", None
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
        value, written = float(number.group(1)), number.group(1)
    try:
        converted = _convert(value, unit_text, unit)
    except _NotConvertible as exc:
        if unit_text:
            raise InputError(f"{where}: {text!r} has unit {exc.unit}, which cannot be "
                             f"converted to {unit!r}") from None
        if written is None:
            raise InputError(f"{where}: value {text!r} has no unit; write it with a unit "
                             f"convertible to {unit!r}, for example \"{text} {unit}\"") from None
        raise InputError(f"{where}: value {text!r} has no unit; expected a unit convertible "
                         f"to {unit!r}") from None
    except _Unreadable as exc:
        raise InputError(f"{where}: cannot read the unit of {text!r} ({exc})") from None
    if converted == 0.0 and value != 0.0:
        raise InputError(f"{where}: {text!r} is too small to represent in {unit} (below "
                         "5e-324)")
    if (infinite and converted == math.inf and written is not None
            and written.lower().lstrip("+") in ("inf", "infinity")):
        return converted
    if not math.isfinite(converted):
        raise InputError(f"{where}: {text!r} is not a finite number in {unit} (NaN, infinite, "
                         "or beyond the largest floating-point number, 1.8e308)")
    return converted


def from_si(value: float, unit: str) -> float:
    """Convert an SI value to ``unit`` (for display and plots)."""
    exact = _defined(unit)
    if exact is not None:
        return value * _nearest_float(_power(exact, -1))

    def convert(x):
        target = _unit(unit)
        base = registry().Quantity(1.0, target).to_base_units().units
        return registry().Quantity(x, base).to(target)

    return _by_pint(value, f"from|{unit}", convert)


class _NotConvertible(Exception):
    def __init__(self, unit: str):
        super().__init__(unit)
        self.unit = unit


class _Unreadable(Exception):
    pass


def _convert(value: float, unit_text: str, unit: str) -> float:
    """``value`` in ``unit_text`` converted to ``unit``: by `definitions` where both units
    are made of their names, else as pint converts it; `_NotConvertible` or `_Unreadable`
    with the reason if it cannot be."""
    source, target = _defined(unit_text), _defined(unit)
    if source is not None and target is not None:
        if source.dimension != target.dimension:
            raise _NotConvertible(unit_text)
        return value * _nearest_float(_product([(source, 1), (target, -1)]))
    try:
        return _by_pint(value, f"to|{unit_text}|{unit}",
                        lambda x: registry().Quantity(x, _unit(unit_text)).to(_unit(unit)))
    except Exception as exc:
        import pint  # lazy: pint is heavy; only units outside vsj's own table

        if isinstance(exc, pint.errors.DimensionalityError):
            raise _NotConvertible(f"{_unit(unit_text):~}") from None
        # pint's parser fails inside on some spellings (a KeyError for a degree sign
        # raised to the power 0): an unreadable unit too
        if isinstance(exc, KeyError):
            raise _Unreadable("pint's unit parser failed on it") from None
        if isinstance(exc, (pint.errors.PintError, ValueError, TypeError, AttributeError)):
            raise _Unreadable(str(exc)) from None
        raise


_pint_factors: dict[str, float | None] = {}


def _by_pint(value: float, key: str, convert) -> float:
    """``value`` converted by pint, ``convert(x)`` being the pint quantity x converted: as
    ``value`` times pint's factor where the conversion is a multiplication (the factor is
    kept for the rest of the process, in memory only), else by ``convert`` itself (an
    offset or logarithmic unit)."""
    if key not in _pint_factors:
        factor = float(convert(1.0).magnitude)
        multiplication = (math.isfinite(factor) and factor != 0.0
                          and float(convert(0.0).magnitude) == 0.0
                          and float(convert(3.0).magnitude) == 3.0 * factor)
        _pint_factors[key] = factor if multiplication else None
    factor = _pint_factors[key]
    return value * factor if factor is not None else float(convert(value).magnitude)


# ------------------------------------------------------------------ exact definitions

class Exact(NamedTuple):
    """A unit as an exact multiple of SI base units: ``rational * pi**pi_power``
    times m, kg, s and A raised to ``dimension``'s exponents (radians are 1)."""

    rational: Fraction
    pi_power: int
    dimension: tuple[int, int, int, int]


#: pi to 80 digits: with it, a factor holding a power of pi is still rounded to the
#: nearest float (a double carries 17 digits).
_PI = Fraction("3.1415926535897932384626433832795028841971693993751058209749445923078164062862")
_ONE = Exact(Fraction(1), 0, (0, 0, 0, 0))

# SI units that take prefixes: symbol, names, factor to the base units, dimension (m kg s A).
_SI = [("m", ("meter", "metre"), Fraction(1), (1, 0, 0, 0)),
       ("g", ("gram",), Fraction(1, 1000), (0, 1, 0, 0)),
       ("s", ("second",), Fraction(1), (0, 0, 1, 0)),
       ("A", ("ampere",), Fraction(1), (0, 0, 0, 1)),
       ("rad", ("radian",), Fraction(1), (0, 0, 0, 0)),
       ("Hz", ("hertz",), Fraction(1), (0, 0, -1, 0)),
       ("N", ("newton",), Fraction(1), (1, 1, -2, 0)),
       ("J", ("joule",), Fraction(1), (2, 1, -2, 0)),
       ("W", ("watt",), Fraction(1), (2, 1, -3, 0)),
       ("Pa", ("pascal",), Fraction(1), (-1, 1, -2, 0)),
       ("V", ("volt",), Fraction(1), (2, 1, -3, -1)),
       ("ohm", ("ohm",), Fraction(1), (2, 1, -3, -2)),
       ("\u03a9", (), Fraction(1), (2, 1, -3, -2)),  # the ohm sign
       ("H", ("henry",), Fraction(1), (2, 1, -2, -2))]
# Prefixes: symbols (micro as u, the micro sign and the Greek mu), name, power of ten.
_PREFIXES = [(("p",), "pico", -12), (("n",), "nano", -9), (("u", "\u00b5", "\u03bc"), "micro", -6),
             (("m",), "milli", -3), (("c",), "centi", -2), (("d",), "deci", -1),
             (("k",), "kilo", 3), (("M",), "mega", 6), (("G",), "giga", 9)]
_POUND = Fraction(45359237, 10**8)  # kg, exact by the 1959 agreement
# Units without prefixes: names, rational factor, power of pi, dimension.
_OTHERS = [(("deg", "degree"), Fraction(1, 180), 1, (0, 0, 0, 0)),
           (("turn", "revolution"), Fraction(2), 1, (0, 0, 0, 0)),
           (("rpm",), Fraction(2, 60), 1, (0, 0, -1, 0)),
           (("min", "minute"), Fraction(60), 0, (0, 0, 1, 0)),
           (("h", "hr", "hour"), Fraction(3600), 0, (0, 0, 1, 0)),
           (("%", "percent"), Fraction(1, 100), 0, (0, 0, 0, 0)),
           (("in", "inch"), Fraction(254, 10**4), 0, (1, 0, 0, 0)),
           (("ft", "foot"), Fraction(3048, 10**4), 0, (1, 0, 0, 0)),
           (("lb", "pound"), _POUND, 0, (0, 1, 0, 0)),
           (("oz", "ounce"), _POUND / 16, 0, (0, 1, 0, 0)),
           (("lbf",), _POUND * Fraction(980665, 10**5), 0, (1, 1, -2, 0))]  # times g_n


@functools.lru_cache(maxsize=1)
def definitions() -> dict[str, Exact]:
    """The unit names vsj converts without pint, each with its exact SI definition."""
    table = {}
    for symbol, names, factor, dimension in _SI:
        for name in (symbol, *names):
            table[name] = Exact(factor, 0, dimension)
        for symbols, prefix, power in _PREFIXES:
            scaled = Exact(factor * Fraction(10) ** power, 0, dimension)
            table.update({p + symbol: scaled for p in symbols})
            table.update({prefix + name: scaled for name in names})
    for names, factor, pi_power, dimension in _OTHERS:
        table.update({name: Exact(factor, pi_power, dimension) for name in names})
    return table


def _power(unit: Exact, exponent: int) -> Exact:
    return Exact(unit.rational ** exponent, unit.pi_power * exponent,
                 tuple(d * exponent for d in unit.dimension))


def _product(factors) -> Exact:
    """The product of (`Exact`, exponent) pairs."""
    result = _ONE
    for unit, exponent in factors:
        u = _power(unit, exponent)
        result = Exact(result.rational * u.rational, result.pi_power + u.pi_power,
                       tuple(a + b for a, b in zip(result.dimension, u.dimension)))
    return result


def _nearest_float(unit: Exact) -> float:
    """The float nearest to the unit's factor (Fraction to float rounds to nearest)."""
    return float(unit.rational * _PI ** unit.pi_power)


@functools.lru_cache(maxsize=256)
def _defined(unit: str) -> Exact | None:
    """``unit`` (of `FORM`'s grammar) as an `Exact`, or None if it is not of that grammar
    or names a unit outside `definitions`."""
    if _check_unit(unit) is not None:
        return None
    table = definitions()
    levels: list[list[list]] = [[]]  # per open parenthesis: [unit, sign, exponent] read so far
    signs = [1]  # per level: the sign of the next factor's exponent (-1 after '/')
    position = 0
    while position < len(unit):
        m = _TOKEN.match(unit, position)
        position = m.end()
        kind, token = m.lastgroup, m.group(m.lastgroup)
        if kind in ("name", "one"):
            factor = table.get(token) if kind == "name" else _ONE
            if factor is None:
                return None
            levels[-1].append([factor, signs[-1], 1])
            signs[-1] = 1
        elif kind == "power":
            levels[-1][-1][2] = int(token.lstrip("^*"))
        elif token == "(":
            levels.append([])
            signs.append(1)
        elif token == ")":
            group = _product((f, s * e) for f, s, e in levels.pop())
            signs.pop()
            levels[-1].append([group, signs[-1], 1])
            signs[-1] = 1
        else:  # * or /
            signs[-1] = -1 if token == "/" else 1
    return _product((f, s * e) for f, s, e in levels[0])


def format_quantity(value: float, unit: str, digits: int = 6) -> str:
    """Text such as ``"-0.4 cm"`` for an SI value shown in ``unit``."""
    shown = from_si(value, unit) if unit not in ("1", "") else value
    text = f"{shown:.{digits}g}"
    return text if unit in ("1", "") else f"{text} {unit}"

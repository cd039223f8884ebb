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

pint is imported only when a conversion is not yet in the cache of conversion
factors (see `cache_file`): a process that reads only units met before does not
import it at all.
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
    def convert(x):
        target = _unit(unit)
        base = registry().Quantity(1.0, target).to_base_units().units
        return registry().Quantity(x, base).to(target)

    return _scaled(value, f"from|{unit}", convert)


class _NotConvertible(Exception):
    def __init__(self, unit: str):
        super().__init__(unit)
        self.unit = unit


class _Unreadable(Exception):
    pass


def _convert(value: float, unit_text: str, unit: str) -> float:
    """``value`` in ``unit_text`` converted to ``unit``, exactly as pint converts it;
    `_NotConvertible` or `_Unreadable` with pint's reason if it cannot be."""
    try:
        return _scaled(value, f"to|{unit_text}|{unit}",
                       lambda x: registry().Quantity(x, _unit(unit_text)).to(_unit(unit)))
    except Exception as exc:
        import pint

        if isinstance(exc, pint.errors.DimensionalityError):
            raise _NotConvertible(f"{_unit(unit_text):~}") from None
        if isinstance(exc, (pint.errors.PintError, ValueError, TypeError, AttributeError)):
            raise _Unreadable(str(exc)) from None
        raise


def _scaled(value: float, key: str, convert) -> float:
    """``value`` times the cached factor ``key``; on a miss, pint's conversion
    ``convert(x)`` (a pint quantity) gives the factor, remembered when the conversion is
    a multiplication, and converts ``value`` itself when it is not."""
    factor = _factors().get(key)
    if factor is None:
        factor = _remember(key, convert)
        if factor is None:  # an offset or logarithmic unit
            return float(convert(value).magnitude)
    return value * factor


# -------------------------------------------------------------- conversion factors on disk
#
# Importing pint and building its registry costs more than a whole simulation of the
# wrist (benchmarks/simulate_cli.py times the command). A conversion between
# multiplicative units is ``value * factor``, pint's own arithmetic, so the factor pint
# computed once is kept in a small JSON file in the user's cache directory
# (``$VSJ_CACHE_DIR``, else ``$XDG_CACHE_HOME/vsj`` or ``~/.cache/vsj``),
# one per pint version. A process that finds every unit it reads there never imports pint,
# and gets the same floats bit for bit. The file is only a cache: one that is missing,
# unreadable or malformed is ignored, and a directory that cannot be written is left alone.

#: Most factors kept on disk (a parameter set uses a few dozen).
CACHE_ENTRIES = 2000


def cache_file():
    """The file of conversion factors, or None if the home directory is unknown."""
    import os
    from pathlib import Path

    folder = os.environ.get("VSJ_CACHE_DIR")
    if not folder:
        base = os.environ.get("XDG_CACHE_HOME")
        try:
            folder = Path(base) if base else Path.home() / ".cache"
        except RuntimeError:
            return None
        folder = Path(folder) / "vsj"
    return Path(folder) / f"units-pint-{_pint_version()}.json"


def _pint_version() -> str:
    """The installed pint's version, from its ``dist-info`` folder: found without
    importing pint (or importlib.metadata, which costs a short run a tenth of its time);
    where there is no such folder, the time its package was last changed."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.find_spec("pint")
    if spec is None or not spec.submodule_search_locations:
        return "none"
    package = Path(next(iter(spec.submodule_search_locations)))
    found = list(package.parent.glob("pint-*.dist-info"))
    if len(found) == 1:
        return found[0].name[len("pint-"):-len(".dist-info")]
    return f"changed-{(package / '__init__.py').stat().st_mtime_ns}"


@functools.lru_cache(maxsize=1)
def _factors() -> dict[str, float]:
    """The factors read from `cache_file` (empty if there is none usable)."""
    import json

    path = cache_file()
    try:
        data = json.loads(path.read_text(encoding="utf-8")) if path else {}
    except (OSError, ValueError):
        return {}
    if not (isinstance(data, dict) and all(
            isinstance(k, str) and type(v) is float and math.isfinite(v) and v != 0.0
            for k, v in data.items())):
        return {}
    return data


_new: dict[str, float] = {}


def _remember(key: str, convert) -> float | None:
    """pint's factor for ``key`` (``convert(x)`` is x converted), kept for this process and
    written to the cache at exit; None if the conversion is not a multiplication."""
    factor = float(convert(1.0).magnitude)
    if not (math.isfinite(factor) and factor != 0.0
            and float(convert(0.0).magnitude) == 0.0
            and float(convert(3.0).magnitude) == 3.0 * factor):
        return None
    factors = _factors()
    if len(factors) < CACHE_ENTRIES:
        factors[key] = factor
        if not _new:
            import atexit

            atexit.register(_save)
        _new[key] = factor
    return factor


def _save() -> None:
    """Merge this process's new factors into the cache file (atomically replaced)."""
    import json
    import os
    import tempfile

    path = cache_file()
    if path is None or not _new:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            old = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            old = {}
        merged = {**(old if isinstance(old, dict) else {}), **_new}
        if len(merged) > CACHE_ENTRIES:
            return
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".units-", suffix=".json")
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                json.dump(merged, f, sort_keys=True, indent=0)
            os.replace(tmp, path)
        except BaseException:
            os.unlink(tmp)
            raise
    except OSError:
        pass  # a read-only or full disk: the cache is only an optimisation


def format_quantity(value: float, unit: str, digits: int = 6) -> str:
    """Text such as ``"-0.4 cm"`` for an SI value shown in ``unit``."""
    shown = from_si(value, unit) if unit not in ("1", "") else value
    text = f"{shown:.{digits}g}"
    return text if unit in ("1", "") else f"{text} {unit}"

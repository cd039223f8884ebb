"""Unit conversion factors come from definitions in the code, never from a file.

Earlier versions kept pint's factors in ``~/.cache/vsj/units-*.json``; an edited entry
(``deg`` to ``rad`` = 1) changed a scenario's phases with exit 0 (issue 31, item 6).
These tests plant such files and check that they change nothing, that every defined
name means what pint means, and that a warm process still never imports pint.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from fractions import Fraction
from pathlib import Path

import pint
import pytest

from vsj import params, units
from vsj.errors import InputError

#: pint rounds once per multiplication: up to five along a name's chain of definitions
#: (the pound-force: grain, milligram, pound, standard gravity) and one more per name
#: combined in a text of up to three names, each by at most 2**-53 relative; the
#: factors here are exact until one last rounding.
PINT_ROUNDING = 16 * 2.0**-53

_DIMENSIONS = {"[length]": 0, "[mass]": 1, "[time]": 2, "[current]": 3}

#: Compound units, with the grammar's corner cases ("N/m s" is N s/m, as pint reads it).
COMPOUNDS = ["N m/rad", "N m s/rad", "rad/(N m)", "1/cm", "kg m^2", "g cm^2", "kg*m**2",
             "N/m s", "m/s/s", "m s**-2", "mN m/deg", "(N m)^2/J", "1/(cm mm)^2",
             "oz in^2", "lbf ft", "rpm/s", "mV/rpm", "mH/ohm", "kHz ms", "% rad",
             "µN m/turn", "kohm/(mA s)^-1", "1/s^2 m"]

#: A factor file as earlier versions wrote it, with the two wrong entries of the audit.
POISON = {"to|deg|rad": 1.0, "to|cm|m": 0.0101, "from|cm": 1.0, "to|rpm|rad/s": 1.0,
          "to|N m|N*m": 2.0}

#: What a process that reads vsj's own files and shows values prints: every SI value of
#: the bundled set, every case of fig 4.15 prepared (its 45 degree phases included), the
#: values shown in display units, and whether pint or Dask was imported.
WARM = """
import json, sys
from vsj import params, scenario, units
p = params.default()
s = scenario.load("fig-4.15")
prepared = [repr(scenario.prepare_case(s, case, p).inputs) for case in s.cases]
print(json.dumps({"values": dict(p.values), "cases": prepared,
                  "shown": [row[1] for row in p.describe()],
                  "phase": units.to_si("45 deg", "rad", where="x"),
                  "q": units.to_si("-0.4 cm", "m", where="x"),
                  "pint": "pint" in sys.modules, "dask": "dask" in sys.modules}))
"""


def _dimension(quantity) -> tuple[int, ...]:
    dims = [0, 0, 0, 0]
    for name, exponent in quantity.dimensionality.items():
        dims[_DIMENSIONS[name]] = exponent  # KeyError: a dimension vsj does not define
    return tuple(dims)


def _pint_si(unit: str) -> tuple[float, tuple[int, ...]]:
    ureg = units.registry()
    base = ureg.Quantity(1.0, ureg.Unit(unit)).to_base_units()
    return float(base.magnitude), _dimension(base)


def _run(script: str, home: Path) -> dict:
    """``script``'s JSON output from a fresh process whose caches all point into ``home``;
    the process is stopped after a minute (it needs a few seconds), so a hang fails."""
    env = {**os.environ, "HOME": str(home), "XDG_CACHE_HOME": str(home / ".cache"),
           "VSJ_CACHE_DIR": str(home / ".cache" / "vsj")}
    done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                          text=True, timeout=60.0)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def _plant(home: Path, content) -> None:
    """A factor file where earlier versions looked for one, for this pint version:
    ``content`` is its text, or makes it given its path."""
    folder = home / ".cache" / "vsj"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"units-pint-{pint.__version__}.json"
    if callable(content):
        content(path)
    else:
        path.write_text(content)


def test_every_defined_name_means_what_pint_means():
    wrong = []
    for name, defined in units.definitions().items():
        expected, dimension = _pint_si(name)
        if defined.dimension != dimension or units._nearest_float(defined) != pytest.approx(
                expected, rel=PINT_ROUNDING):
            wrong.append((name, defined, expected, dimension))
    assert wrong == []
    assert len(units.definitions()) > 300  # every prefix of every SI unit, both spellings


@pytest.mark.parametrize("unit", COMPOUNDS)
def test_compound_units_read_as_pint_reads_them(unit):
    expected, dimension = _pint_si(unit)
    defined = units._defined(unit)
    assert defined is not None and defined.dimension == dimension
    si = "*".join(f"{base}**{e}" for base, e in zip(("m", "kg", "s", "A"), dimension) if e)
    assert units.to_si(f"3 {unit}", si or "1", where="t") == pytest.approx(
        3 * expected, rel=PINT_ROUNDING)


def test_factors_are_the_nearest_floats_to_the_exact_ones():
    """Where pint's chain of rounded products misses the nearest float, vsj does not."""
    assert units.to_si("1 ft", "m", where="t") == 0.3048
    assert units.to_si("1 g cm^2", "kg*m**2", where="t") == 1e-7
    pi = Fraction("3.14159265358979323846264338327950288")  # 36 digits: beyond a double's 17
    assert units.to_si("1 rpm", "rad/s", where="t") == float(pi / 30)


def test_errors_and_infinities_from_the_definitions():
    with pytest.raises(InputError, match=r"f.toml: '1 N m s' has unit N m s, which cannot "
                                         r"be converted to 'N\*m'"):
        units.to_si("1 N m s", "N*m", where="f.toml")
    with pytest.raises(InputError, match="value 2.0 has no unit"):
        units.to_si(2.0, "m", where="f.toml")
    assert units.to_si("inf N m/rad", "N*m", where="t", infinite=True) == float("inf")
    with pytest.raises(InputError, match="not a finite number"):
        units.to_si("inf N m/rad", "N*m", where="t")
    with pytest.raises(InputError, match="too small to represent"):
        units.to_si("5e-324 mm", "m", where="t")  # the smallest float, times 1e-3


def test_display_conversions_are_the_inverse_factors():
    for unit in {spec.display for specs in params.SCHEMA.values() for spec in specs.values()}:
        expected, _ = _pint_si(unit)
        assert units.from_si(expected, unit) == pytest.approx(1.0, rel=PINT_ROUNDING)
    assert units.format_quantity(0.01234, "cm") == "1.234 cm"
    assert units.format_quantity(units.to_si("-1.45 1/cm", "1/m", where="t"), "1/cm") == \
        "-1.45 1/cm"


def test_units_outside_the_definitions_are_converted_by_pint():
    assert "meters" not in units.definitions() and "degC" not in units.definitions()
    assert units.to_si("2 meters", "m", where="t") == 2.0
    assert units.to_si("20 degC", "K", where="t") == pytest.approx(293.15, rel=2.0**-52)
    assert units.from_si(293.15, "degC") == pytest.approx(20.0, abs=293.15 * 2.0**-52)
    with pytest.raises(InputError, match="cannot read the unit of '1 furlongs_per_zz'"):
        units.to_si("1 furlongs_per_zz", "m", where="t")


def test_every_unit_in_vsjs_own_files_and_displays_is_defined():
    """So a process that reads only vsj's files never needs pint (see the warm test)."""
    data = Path(params.__file__).parent / "data"
    texts = []

    def collect(node):
        if isinstance(node, dict):
            for value in node.values():
                collect(value)
        elif isinstance(node, list):
            for value in node:
                collect(value)
        elif isinstance(node, str) and units._NUMBER.match(node):
            texts.append(node)

    for file in [*data.glob("params/*.toml"), *data.glob("scenarios/*.toml")]:
        collect(tomllib.loads(file.read_text(encoding="utf-8")))
    unit_texts = {text[units._NUMBER.match(text).end():].strip() for text in texts}
    unit_texts |= {spec.unit for specs in params.SCHEMA.values() for spec in specs.values()}
    unit_texts |= {spec.display for specs in params.SCHEMA.values() for spec in specs.values()}
    assert {"cm", "deg", "N m s/rad", "rad/(N m)"} <= unit_texts
    assert [u for u in sorted(unit_texts) if units._defined(u) is None] == []


def test_a_poisoned_factor_file_changes_nothing(tmp_path):
    """The audit's two entries (deg to rad = 1, cm to m = 0.0101) and others, planted
    where earlier versions read them: every value equals pint's, and a process that
    finds them gives what a process with an empty home gives."""
    clean = _run(WARM, tmp_path / "clean")
    _plant(tmp_path / "poisoned", json.dumps(POISON))
    poisoned = _run(WARM, tmp_path / "poisoned")
    ureg = units.registry()
    assert poisoned["phase"] == ureg.Quantity(45.0, "deg").to("rad").magnitude
    assert poisoned["q"] == ureg.Quantity(-0.4, "cm").to("m").magnitude
    assert poisoned == clean


@pytest.mark.parametrize("kind", ["not json", "binary", "directory", "fifo"])
def test_a_malformed_factor_file_is_ignored(tmp_path, kind):
    """Nothing is read from the cache directory: not even a FIFO there (which a reader
    would wait on for ever; the timeout stops the test if one does) holds a process up."""
    def make(path: Path):
        if kind == "not json":
            path.write_text("{not json")
        elif kind == "binary":
            path.write_bytes(bytes(range(256)))
        elif kind == "directory":
            path.mkdir()
        else:
            os.mkfifo(path)
    _plant(tmp_path, make)
    result = _run(WARM, tmp_path)
    assert result["phase"] == units.registry().Quantity(45.0, "deg").to("rad").magnitude
    assert result["values"] == dict(params.default().values)


def test_a_warm_process_imports_neither_pint_nor_dask_and_writes_no_cache(tmp_path):
    """The first process in a fresh home reads vsj's own files without pint, as every
    later one does, and leaves nothing in the cache directories."""
    first, second = _run(WARM, tmp_path), _run(WARM, tmp_path)
    assert first["pint"] is False and first["dask"] is False
    assert first == second
    assert not (tmp_path / ".cache").exists()

"""The cache of unit conversion factors: the same floats as pint, in a process that
never imports pint, and a cache file that can only speed things up, never break them."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys

import pint
import pytest

from vsj import units
from vsj.errors import InputError

#: (text, SI unit) pairs with factors that are not powers of ten or one.
QUANTITIES = [("-0.4 cm", "m"), ("100 rpm", "rad/s"), ("5 mN m", "N*m"),
              ("6.47e-5 kg m^2", "kg*m**2"), ("1 rad/(N m)", "rad/(N*m)"),
              ("3.7 deg", "rad"), ("12 g cm^2", "kg*m**2"), ("0.3 mm/s", "m/s"),
              ("2.5 ounce inch", "kg*m"), ("1e-3 N m s/deg", "N*m*s")]


def _pint_value(text: str, unit: str) -> float:
    number, _, unit_text = text.partition(" ")
    ureg = units.registry()
    return float(ureg.Quantity(float(number), ureg.Unit(unit_text)).to(ureg.Unit(unit)).magnitude)


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """An empty cache directory, and a process that has not read any cache file yet."""
    monkeypatch.setenv("VSJ_CACHE_DIR", str(tmp_path))
    units._factors.cache_clear()
    monkeypatch.setattr(units, "_new", {})
    yield tmp_path
    units._factors.cache_clear()


def test_conversions_equal_pints_bit_for_bit_before_and_after_caching(fresh_cache):
    first = [units.to_si(text, unit, where="test") for text, unit in QUANTITIES]
    units._save()
    units._factors.cache_clear()
    cached = json.loads(units.cache_file().read_text())
    assert len(cached) == len(QUANTITIES)
    second = [units.to_si(text, unit, where="test") for text, unit in QUANTITIES]
    expected = [_pint_value(text, unit) for text, unit in QUANTITIES]
    assert first == expected and second == expected  # == on floats: bit for bit


def test_a_cached_factor_is_what_is_used(fresh_cache):
    """The cache is read (a stored factor changes the answer), so the test above tests it."""
    units.cache_file().write_text(json.dumps({"to|cm|m": 0.5}))
    assert units.to_si("3 cm", "m", where="test") == 1.5


def test_offset_units_are_converted_by_pint_and_not_cached(fresh_cache):
    # an offset added: one rounded sum, an ulp of the result at most
    one_sum = math.ulp(293.15)
    assert units.to_si("20 degC", "K", where="test") == pytest.approx(293.15, rel=0, abs=one_sum)
    assert units.to_si("20 degC", "K", where="test") == pytest.approx(293.15, rel=0, abs=one_sum)
    assert not any("degC" in key for key in units._new)


def test_errors_are_the_same_from_the_cache(fresh_cache):
    units.to_si("1 cm", "m", where="warm")
    with pytest.raises(InputError, match=r"f.toml: '1 cm' has unit cm, which cannot be "
                                         r"converted to 'kg'"):
        units.to_si("1 cm", "kg", where="f.toml")
    with pytest.raises(InputError, match="value 2.0 has no unit"):
        units.to_si(2.0, "m", where="f.toml")
    with pytest.raises(InputError, match="cannot read the unit of '1 furlongs_per_zz'"):
        units.to_si("1 furlongs_per_zz", "m", where="f.toml")
    assert units.to_si("inf N m/rad", "N*m", where="t", infinite=True) == float("inf")
    with pytest.raises(InputError, match="not a finite number"):
        units.to_si("inf N m/rad", "N*m", where="t")


@pytest.mark.parametrize("content", ["not json", "[1, 2]", '{"to|cm|m": "0.01"}',
                                     '{"to|cm|m": 0.0}', '{"to|cm|m": NaN}'])
def test_a_malformed_cache_file_is_ignored_and_replaced(fresh_cache, content):
    units.cache_file().write_text(content)
    assert units.to_si("-0.4 cm", "m", where="test") == _pint_value("-0.4 cm", "m")
    units._save()
    assert json.loads(units.cache_file().read_text()) == {"to|cm|m": 0.01}


def test_a_directory_that_cannot_be_written_is_left_alone(fresh_cache, monkeypatch):
    blocked = fresh_cache / "file"
    blocked.write_text("")
    monkeypatch.setenv("VSJ_CACHE_DIR", str(blocked / "below-a-file"))
    assert units.to_si("5 mN m", "N*m", where="test") == _pint_value("5 mN m", "N*m")
    units._save()  # no exception, nothing written
    assert blocked.read_text() == ""


def test_display_conversions_come_from_the_cache_too(fresh_cache):
    ureg = units.registry()
    expected = float(ureg.Quantity(0.01234, "m").to("cm").magnitude)
    assert units.from_si(0.01234, "cm") == expected
    assert units.format_quantity(0.01234, "cm") == "1.234 cm"
    units._save()
    units._factors.cache_clear()
    assert units.from_si(0.01234, "cm") == expected
    assert "from|cm" in json.loads(units.cache_file().read_text())


def test_a_warm_process_does_not_import_pint(tmp_path):
    """Reading the bundled parameter set and a scenario twice: the second process finds
    every factor in the cache, does not import pint, and reads the same numbers."""
    script = ("import sys, json\n"
              "from vsj import params, scenario\n"
              "p = params.default()\n"
              "s = scenario.load('fig-4.15')\n"
              "prepared = scenario.prepare_case(s, s.cases[0], p)\n"
              "print(json.dumps([dict(p.values), repr(prepared.inputs),\n"
              "                  'pint' in sys.modules]))\n")
    env = {**os.environ, "VSJ_CACHE_DIR": str(tmp_path)}
    runs = [json.loads(subprocess.run([sys.executable, "-c", script], env=env, check=True,
                                      capture_output=True, text=True).stdout)
            for _ in range(2)]
    assert runs[0][2] is True and runs[1][2] is False
    assert runs[0][:2] == runs[1][:2]
    assert units.cache_file().name == f"units-pint-{pint.__version__}.json"

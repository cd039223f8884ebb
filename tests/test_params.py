"""Parameter files: every kind of error is named, and the CLI exits with 2."""

import math
from pathlib import Path

import numpy as np
import pytest

from vsj import params as params_module
from vsj.errors import InputError
from vsj.cli import main

DEFAULT = Path(params_module._bundled(params_module.DEFAULT_FILE)).read_text()
EPS = np.finfo(float).eps


def broken(tmp_path, old, new, name="bad.toml"):
    assert old in DEFAULT, old
    path = tmp_path / name
    path.write_text(DEFAULT.replace(old, new, 1))
    return path


def check(path, capsys):
    code = main(["params", "--check", str(path)])
    return code, capsys.readouterr().err


def test_default_set_is_valid_and_sourced(params, capsys):
    assert main(["params"]) == 0
    out = capsys.readouterr().out
    assert "report table 4.1 (I_R)" in out and "6.47e-05 kg m^2" in out
    assert all(params.sources[k] for k in params.values)


CASES = [
    ("unknown key", 'mesh_sharpness = {', 'mesh_sharpnes = {', "planetary.mesh_sharpnes: unknown key"),
    ("missing key", 'ring_inertia = { value = "6.47e-5 kg m^2", source = "report table 4.1 (I_R)" }\n',
     "", "planetary.ring_inertia: missing"),
    ("missing unit", '"6.47e-5 kg m^2"', '"6.47e-5"', "has no unit"),
    ("wrong unit", '"6.47e-5 kg m^2"', '"6.47e-5 N m"', "cannot be converted"),
    ("negative inertia", '"6.47e-5 kg m^2"', '"-6.47e-5 kg m^2"', "must be > 0"),
    ("negative friction", '"0.00080 N m s/rad"', '"-0.0008 N m s/rad"', "must be >= 0"),
    ("zero tooth count", 'value = "16"', 'value = "0"', "sun_teeth = '0': must be > 0"),
    ("nan", '"0.00125 N m"', '"nan N m"', "NaN"),
    ("q beyond the pivot's reach", 'q_min = { value = "-2.2 cm"', 'q_min = { value = "-2.8 cm"',
     "within the mechanism's reach"),
    ("unknown field", 'ring_radius = { value = "', 'ring_radius = { value = "1.5 cm", x = "',
     "unknown field"),
    ("missing source", ', source = "report table 4.1 (k_1)"', "", "missing source"),
    ("not toml", "[planetary]", "[planetary", "not valid TOML"),
]


@pytest.mark.parametrize("what,old,new,message", CASES, ids=[c[0] for c in CASES])
def test_each_error_is_named_with_exit_code_2(tmp_path, capsys, what, old, new, message):
    code, err = check(broken(tmp_path, old, new), capsys)
    assert code == 2
    assert message in err
    assert "bad.toml" in err


def test_pivot_range_must_stay_above_the_ring_pin(tmp_path, capsys):
    text = DEFAULT
    start = text.index('ring_radius = { value = "') + len('ring_radius = { value = "')
    end = text.index('"', start)
    path = tmp_path / "bad.toml"
    path.write_text(text[:start] + "2.0 cm" + text[end:])
    code, err = check(path, capsys)
    assert code == 2 and "q_min + ring_radius > 0" in err


def test_all_problems_are_reported_at_once(tmp_path, capsys):
    path = broken(tmp_path, '"6.47e-5 kg m^2"', '"-1 kg m^2"')
    path.write_text(path.read_text().replace('"0.00125 N m"', '"x N m"'))
    code, err = check(path, capsys)
    assert code == 2 and "ring_inertia" in err and "mesh_stiction" in err


def test_unreadable_file(tmp_path, capsys):
    code, err = check(tmp_path / "absent.toml", capsys)
    assert code == 2 and "cannot read parameter file" in err


def test_simulate_rejects_a_bad_parameter_file_before_writing(tmp_path, capsys):
    bad = broken(tmp_path, '"6.47e-5 kg m^2"', '"-6.47e-5 kg m^2"')
    out = tmp_path / "out"
    assert main(["simulate", "fig-4.15", "--params", str(bad), "--out", str(out)]) == 2
    assert not out.exists()
    assert "ring_inertia" in capsys.readouterr().err


#: A value written with `Parameters.to_toml` (10 significant digits in its display unit)
#: and read back: half a unit of the tenth digit, plus an ulp for each unit conversion.
TOML_ROUND_TRIP = 0.5 * 10.0 ** (1 - 10) + 2 * EPS
#: A value read in its SI unit: one multiplication by a unit factor of 1 (an ulp at most).
SAME_UNIT = EPS


def test_round_trip_through_toml(params):
    again = params_module.loads(params.to_toml(), "round trip")
    for key, value in params.values.items():
        assert again[key] == pytest.approx(value, rel=TOML_ROUND_TRIP, abs=0.0)
        assert again.sources[key] == params.sources[key]
    # values that need every digit a double has (the bundled ones are short decimals)
    spec = {f"{s}.{n}": v for s, names in params_module.SCHEMA.items() for n, v in names.items()}
    long = params.with_overrides(
        {key: f"{value * (1 + 1 / 3000)!r} {spec[key].unit}"
         for key, value in params.values.items()
         if math.isfinite(value) and value != round(value)}, origin="test")
    again = params_module.loads(long.to_toml(), "round trip")
    assert any(again[key] != value for key, value in long.values.items())  # digits were cut
    for key, value in long.values.items():
        assert again[key] == pytest.approx(value, rel=TOML_ROUND_TRIP, abs=0.0), key


def test_a_three_line_file_extends_the_bundled_set(tmp_path):
    file = tmp_path / "mine.toml"
    file.write_text('extends = "second_prototype"\n[transmission]\n'
                    'stiction = { value = "0.004 N m", source = "my bench" }\n')
    mine, base = params_module.load(file), params_module.default()
    assert mine["transmission.stiction"] == pytest.approx(0.004, rel=SAME_UNIT, abs=0.0)
    assert mine.sources["transmission.stiction"] == "my bench"
    changed = {k for k in base.values if mine.values[k] != base.values[k]}
    assert changed == {"transmission.stiction"}
    # a file can extend a file, relative to itself
    (tmp_path / "sub").mkdir()
    child = tmp_path / "sub" / "child.toml"
    child.write_text('extends = "../mine.toml"\n[differential]\n'
                     'inertia_x = { value = "1e-4 kg m^2", source = "CAD" }\n')
    grand = params_module.load(child)
    assert grand["transmission.stiction"] == pytest.approx(0.004, rel=SAME_UNIT, abs=0.0)
    assert grand["differential.inertia_x"] == pytest.approx(1e-4, rel=SAME_UNIT, abs=0.0)


def test_extends_names_the_nearest_key_and_refuses_cycles(tmp_path):
    file = tmp_path / "typo.toml"
    file.write_text('extends = "second_prototype"\n[transmission]\n'
                    'stiktion = { value = "0.004 N m", source = "my bench" }\n')
    with pytest.raises(InputError, match=r"transmission\.stiktion: unknown key \(did you mean "
                                         r"'stiction'\?\)"):
        params_module.load(file)
    bad = tmp_path / "bad.toml"
    bad.write_text('extends = "second_prototyp"\n')
    with pytest.raises(InputError, match="did you mean 'second_prototype'"):
        params_module.load(bad)
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text('extends = "b.toml"\n')
    b.write_text('extends = "a.toml"\n')
    with pytest.raises(InputError, match="cycle"):
        params_module.load(a)


def test_components_check_their_arguments_with_the_schemas_bounds():
    from vsj.components import Bearing, DCMotor, Differential

    with pytest.raises(ValueError, match=r"viscous friction of b must be >= 0 N m s/rad"):
        Bearing("b", viscous=-1e-3)
    with pytest.raises(ValueError, match=r"arctan sharpness of b must be > 0 s/rad"):
        Bearing("b", sharpness=0.0)
    with pytest.raises(ValueError, match=r"d: inertia_x must be finite"):
        Differential("d", inertia_x=float("nan"))
    # a motor takes the file's names, so the file's bound and the argument's are one
    spec = params_module.SCHEMA["motor"]["resistance"]
    with pytest.raises(ValueError, match=r"m: resistance must be > 0 ohm"):
        DCMotor("m", resistance=0.0, inductance=1e-3, torque_constant=0.01, rotor_inertia=1e-6)
    assert spec.check(0.0) == "must be > 0 ohm"

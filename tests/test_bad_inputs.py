"""Bad inputs (issue 18): every one gives exit code 2 and a message naming the file and
key (or line, or option) and what is allowed; nothing is evaluated, nothing crashes,
nothing is written.

The cases go through the command line (`vsj.cli.main`) as a user meets them: parameter
files (`vsj params --check`, `vsj simulate --params`), scenario files (`vsj simulate`),
measurement files (`vsj fit`), and options (`vsj linearize`, `export-model`, `synth`,
`fit planetary`). The unit parser gets random text from hypothesis besides.
"""

from __future__ import annotations

import math
import subprocess
import sys
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from conftest import SHORT_SCENARIO

from vsj import params as params_module
from vsj import scenario as scenarios
from vsj.cli import main
from vsj.errors import InputError
from vsj.simulate import SimulationOptions
from vsj.units import to_si

DEFAULT = Path(params_module._bundled(params_module.DEFAULT_FILE)).read_text()
#: The line of the bundled set that the unit cases rewrite.
INERTIA = 'ring_inertia = { value = "6.47e-5 kg m^2"'
TEETH = 'sun_teeth = { value = "16"'


def fails(argv, capsys, *expected: str) -> str:
    """Run the command; assert exit code 2, no traceback and every expected text."""
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err and err.startswith("vsj: error: ")
    for text in expected:
        assert text in err, (text, err)
    return err


def write(path: Path, text: str | bytes) -> Path:
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


# ------------------------------------------------------------------- unit strings

#: (value in place of ring_inertia's, what the message must say besides file and key).
UNIT_TEXTS = {
    "power tower": ("9**9**9 kg m^2", "exponents from -9 to 9"),
    "division by zero": ("1 kg m^2 / 0", "unexpected '0'"),
    "huge power": ("10**400 kg m^2", "without a unit name before it"),
    "unclosed bracket": ("(6.47e-5 kg m^2", "does not start with a number"),
    "unclosed unit bracket": ("6.47e-5 kg (m^2", "'(' that is not closed"),
    "stray bracket": ("6.47e-5 kg m^2)", "')' without its '('"),
    "nested brackets": ("6.47e-5 ((kg)) m^2", "parentheses inside parentheses"),
    "empty brackets": ("6.47e-5 kg () m^2", "empty pair of parentheses"),
    "overflowing number": ("1e400 kg m^2", "not a finite number"),
    "overflow on conversion": ("1e300 kg Gm^2", "not a finite number"),
    "underflow on conversion": ("1e-300 kg ym^2", "too small to represent"),
    "infinite": ("inf kg m^2", "not a finite number"),
    "negative infinite": ("-inf kg m^2", "not a finite number"),
    "nan": ("nan kg m^2", "NaN"),
    "two-digit exponent": ("6.47e-5 kg m^22", "unexpected '^22'"),
    "stacked exponents": ("6.47e-5 kg m^2^2", "a second exponent '^2'"),
    "symbolic exponent": ("6.47e-5 kg m^x", "unexpected '^x'"),
    "no number": ("kg m^2", "does not start with a number"),
    "empty": ("", "does not start with a number"),
    "sum": ("6.47e-5 kg m^2 + 1 kg m^2", "unexpected '+"),
    "product of numbers": ("2*3 kg m^2", "'*' without a unit name"),
    "number inside the unit": ("6.47 1e-5 kg m^2", "unexpected '1e-5"),
    "python call": ("1 __import__('os')", "unexpected \"'os')\""),
    "statement separator": ("6.47e-5 kg m^2; 1", "unexpected ';"),
    "trailing operator": ("6.47e-5 kg m^2 /", "ends with an operator"),
    "leading operator": ("6.47e-5 / kg m^2", "'/' without a unit name"),
    "unknown unit": ("6.47e-5 kg furlong^3", "furlong"),
    "wrong dimension": ("6.47e-5 kg m", "cannot be converted"),
    "hex number": ("0x10 kg m^2", "cannot read the unit"),
    "too long": ("1 " + " ".join(["kg"] * 60), "at most 100 characters"),
}


@pytest.mark.parametrize("case", sorted(UNIT_TEXTS))
def test_unit_strings_in_a_parameter_file(tmp_path, capsys, case):
    text, message = UNIT_TEXTS[case]
    path = write(tmp_path / "bad.toml",
                 DEFAULT.replace(INERTIA, f'ring_inertia = {{ value = "{text}"', 1))
    fails(["params", "--check", path], capsys, "bad.toml", "planetary.ring_inertia", message)


#: TOML values of sun_teeth that are not a number with a unit.
TOML_VALUES = {
    "infinity": ("inf", "not a finite number"),
    "nan": ("nan", "not a finite number"),
    "boolean": ("true", "got bool True"),
    "list": ("[16]", "got list"),
    "table": ("{ n = 16 }", "got dict"),
}


@pytest.mark.parametrize("case", sorted(TOML_VALUES))
def test_toml_values_that_are_not_quantities(tmp_path, capsys, case):
    value, message = TOML_VALUES[case]
    path = write(tmp_path / "bad.toml", DEFAULT.replace(TEETH, f"sun_teeth = {{ value = {value}"))
    fails(["params", "--check", path], capsys, "bad.toml", "planetary.sun_teeth", message)


def test_a_power_tower_does_not_hang_the_process(tmp_path):
    """The whole process, as a user starts it: exit 2 within seconds, no traceback."""
    path = write(tmp_path / "bad.toml",
                 DEFAULT.replace(INERTIA, 'ring_inertia = { value = "9**9**9 kg m^2"', 1))
    done = subprocess.run([sys.executable, "-m", "vsj", "params", "--check", str(path)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "planetary.ring_inertia" in done.stderr


TOKENS = st.sampled_from(["1", "9", "0", "1e400", "-", "+", ".", "e", "*", "**", "^", "/",
                          "(", ")", " ", "m", "kg", "N", "rad", "s", "cm", "nan", "inf", "x",
                          "__import__", "'", ",", ";", "9**9**9", "10**400", "2", "-1", "°",
                          "µ", "%", "\t", "\x00", "\\"])


@pytest.fixture(scope="module", autouse=True)
def _registry_loaded():
    """pint's registry is built on first use (a second or more); not part of any deadline."""
    to_si("1 m", "m", where="warm-up")


def _finite_or_input_error(text: str, unit: str) -> None:
    try:
        value = to_si(text, unit, where="test")
    except InputError as exc:
        assert str(exc).startswith("test: ")
    else:
        assert math.isfinite(value)


@settings(deadline=timedelta(seconds=2), max_examples=400)
@given(st.lists(TOKENS, max_size=14).map("".join), st.sampled_from(["m", "kg*m**2", "1"]))
@example("1°**0", "m")  # pint raised a KeyError from inside its parser
def test_token_soup_never_raises_anything_but_input_error(text, unit):
    _finite_or_input_error(text, unit)


@settings(deadline=timedelta(seconds=2), max_examples=300)
@given(st.text(max_size=40), st.sampled_from(["m", "N*m*s", "1"]))
@example("0¼", "m")  # a numeric character where a unit name starts crashed pint's parser
@example("1 m²", "m")
def test_random_text_never_raises_anything_but_input_error(text, unit):
    _finite_or_input_error(text, unit)


@settings(deadline=timedelta(seconds=2))
@given(st.floats(allow_nan=False, allow_infinity=False, min_value=-1e300, max_value=1e300)
       .filter(lambda v: v == 0.0 or abs(v) > 1e-290))  # below, the conversion underflows
def test_numbers_with_units_read_back(value):
    # repr reads back exactly; the conversion's factor (rounded once) times the value
    # (rounded once) against the correctly rounded quotient: at most 2 ulps apart
    ulps = 2 * np.finfo(float).eps
    assert to_si(f"{value!r} cm", "m", where="test") == pytest.approx(value / 100, rel=ulps,
                                                                      abs=0.0)
    assert to_si(f"{value!r} mN m/rad", "N*m", where="test") == pytest.approx(
        value / 1000, rel=ulps, abs=0.0)


# ------------------------------------------------------------------ parameter files

def test_a_byte_order_mark_is_accepted(tmp_path, capsys):
    path = write(tmp_path / "bom.toml", b"\xef\xbb\xbf" + DEFAULT.encode())
    assert main(["params", "--check", str(path)]) == 0
    assert "ok" in capsys.readouterr().out


def test_a_file_that_is_not_utf8_names_line_and_byte(tmp_path, capsys):
    data = DEFAULT.encode()
    at = data.index(b"report table 4.1 (I_R)")
    path = write(tmp_path / "latin1.toml", data[:at] + b"\xe9" + data[at:])
    line = data[:at].count(b"\n") + 1
    fails(["params", "--check", path], capsys, "latin1.toml", f"line {line}", f"byte offset {at}",
          "not UTF-8")


@pytest.mark.parametrize("encoding", ["utf-16", "utf-32"])
def test_other_encodings_are_refused(tmp_path, capsys, encoding):
    path = write(tmp_path / "wide.toml", DEFAULT.encode(encoding))
    fails(["params", "--check", path], capsys, "wide.toml", "not UTF-8")


@pytest.mark.parametrize("edit,message", [
    (('name = "second prototype"', "name = 5"), "meta.name: expected text"),
    (("# vsj parameter set", "extra = 1\n# vsj parameter set"), "unknown section [extra]"),
    ((', source = "report table 4.1 (I_R)"', ", source = 5"),
     "ring_inertia: source = 5 is not a text"),
    (('q_max = { value = "2.0 cm"', 'q_max = { value = "-2.4 cm"'), "must be below pivot.q_max"),
], ids=["meta not text", "unknown section", "source not text", "pivot range reversed"])
def test_parameter_file_structure(tmp_path, capsys, edit, message):
    assert edit[0] in DEFAULT
    path = write(tmp_path / "bad.toml", DEFAULT.replace(*edit, 1))
    fails(["params", "--check", path], capsys, "bad.toml", message)


def test_a_directory_is_not_a_parameter_file(tmp_path, capsys):
    fails(["params", "--check", tmp_path], capsys, str(tmp_path), "cannot read parameter file")


def test_simulate_with_a_bad_parameter_file_writes_nothing(tmp_path, capsys):
    bad = write(tmp_path / "bad.toml",
                DEFAULT.replace(INERTIA, 'ring_inertia = { value = "1 kg m^2 / 0"', 1))
    out = tmp_path / "out"
    fails(["simulate", "fig-4.15", "--params", bad, "--out", out], capsys, "bad.toml",
          "planetary.ring_inertia")
    assert not out.exists()


# ------------------------------------------------------------------------ scenarios

SHORT = SHORT_SCENARIO
PLANETARY = """network = "planetary-bench"
duration = "0.2 s"
[bench]
fixed = "sun"
[inputs.drive]
kind = "constant"
value = "1 rad/s"
"""
ELASTIC = """network = "elastic-bench"
duration = "0.2 s"
[bench]
q = "-0.4 cm"
[inputs.drive]
kind = "constant"
value = "0.1 rad/s"
"""


def solver(line):
    return SHORT.replace('output_step = "10 ms"\n', f'output_step = "10 ms"\n{line}\n')


def initial(line):
    return SHORT.replace('q = "-0.4 cm"\n', f"{line}\n")


def sine(old, new):
    assert old in SHORT
    return SHORT.replace(old, new)


def model(lines):
    return SHORT.replace("[solver]", f"[model]\n{lines}\n[solver]")


def extra_input(table):
    return SHORT + table


#: name -> (scenario text, key path the message names, what it says is allowed)
SCENARIOS = {
    "rtol is text": (solver('rtol = "tight"'), "solver.rtol", "does not start with a number"),
    "rtol is a boolean": (solver("rtol = true"), "solver.rtol", "got bool"),
    "rtol is zero": (solver("rtol = 0"), "solver.rtol", "must be > 0"),
    "rtol is two": (solver("rtol = 2.0"), "solver.rtol", "must be below 1"),
    "rtol is infinite": (solver("rtol = inf"), "solver.rtol", "not a finite number"),
    "rtol is nan": (solver("rtol = nan"), "solver.rtol", "not a finite number"),
    "atol is negative": (solver("atol = -1e-9"), "solver.atol", "must be > 0"),
    "max_steps is text": (solver('max_steps = "many"'), "solver.max_steps", "whole number"),
    "max_steps is fractional": (solver("max_steps = 1.5"), "solver.max_steps", "whole number"),
    "max_steps is a boolean": (solver("max_steps = true"), "solver.max_steps", "whole number"),
    "max_steps is zero": (solver("max_steps = 0"), "solver.max_steps", ">= 1"),
    "step is zero": (solver('step = "0 s"'), "solver.step", "must be > 0"),
    "step has a wrong unit": (solver('step = "1 kg"'), "solver.step", "cannot be converted"),
    "output_step is negative": (SHORT.replace('"10 ms"', '"-10 ms"'), "solver.output_step",
                                "must be > 0"),
    "slope_width is zero": (solver('slope_width = "0 rad/s"'), "solver.slope_width",
                            "must be > 0"),
    "max_step is nan": (solver('max_step = "nan s"'), "solver.max_step", "NaN"),
    "unknown method": (solver('method = "rk45"'), "solver.method",
                       "auto, dopri, rosenbrock, timestep"),
    "method is a number": (solver("method = 3"), "solver.method",
                           "auto, dopri, rosenbrock, timestep"),
    "friction is a number": (SHORT.replace('friction = "arctan"', "friction = 5"),
                             "solver.friction", "unknown friction law 5"),
    "unknown friction law": (SHORT.replace('"arctan"', '"magic"'), "solver.friction",
                             "unknown friction law 'magic'"),
    "unknown law in an override": (solver('friction_overrides = { "*.bearing_*" = "magic" }'),
                                   "solver.friction_overrides.*.bearing_*",
                                   "unknown friction law 'magic'"),
    "overrides not a table": (solver('friction_overrides = "stiction"'),
                              "solver.friction_overrides", "expected a table"),
    "override matching nothing": (solver('friction_overrides = { "nothing*" = "sign" }'),
                                  "solver", "matches no element"),
    "stiction with dopri": (SHORT.replace('"arctan"', '"stiction"\nmethod = "dopri"'),
                            "solver", "needs the time-stepping solver"),
    "stiction with rosenbrock": (SHORT.replace('"arctan"', '"stiction"\nmethod = "rosenbrock"'),
                                 "solver", "rosenbrock integrates smooth laws only"),
    "output_step not a multiple of step": (
        SHORT.replace('"arctan"', '"stiction"\nstep = "3 ms"'), "solver",
        "whole multiple of the time step"),
    "solver not a table": (SHORT.replace("[solver]\n", "").replace(
        'friction = "arctan"\noutput_step = "10 ms"\n', "").replace(
        'duration = "0.3 s"', 'duration = "0.3 s"\nsolver = "fast"'), "solver",
        "expected a table"),
    "unknown solver key": (solver('order = 5'), "solver", "unknown key(s) order"),
    "initial q is a boolean": (initial("q = true"), "initial.q", "got bool"),
    "initial q beyond the pivot range": (initial('q = "1 m"'), "initial.q",
                                         "outside the pivot range"),
    "initial q is nan": (initial('q = "nan cm"'), "initial.q", "NaN"),
    "initial angles not a table": (initial('angles = "all zero"'), "initial.angles",
                                   "expected a table"),
    "initial angle of no flange": (initial('angles = { nowhere = "1 rad" }'), "short.toml",
                                   "nowhere"),
    "initial speed without unit": (initial('speeds = { "pg_1.ring" = 5 }'),
                                   "initial.speeds.pg_1.ring", "has no unit"),
    "initial current of no motor": (initial('currents = { motor_1 = "1 A" }'), "short.toml",
                                    "unknown motor(s) motor_1"),
    "initial not a table": (SHORT.replace("[initial]\n", "").replace('q = "-0.4 cm"\n', "")
                            .replace('duration = "0.3 s"', 'duration = "0.3 s"\ninitial = 5'),
                            "initial", "expected a table"),
    "duration zero": (SHORT.replace('"0.3 s"', '"0 s"'), "duration", "must be > 0"),
    "duration infinite": (SHORT.replace('"0.3 s"', '"inf s"'), "duration", "not a finite"),
    "duration without unit": (SHORT.replace('"0.3 s"', "0.3"), "duration", "has no unit"),
    "duration missing": (SHORT.replace('duration = "0.3 s"\n', ""), "short.toml",
                         "missing 'duration'"),
    "unknown network": (SHORT.replace('"wrist"', '"bicycle"'), "network",
                        "wrist, planetary-bench, elastic-bench"),
    "network is a number": (SHORT.replace('"wrist"', "5"), "network", "is not one of"),
    "unknown elastic model": (model('elastic = "rubber"'), "model.elastic", "geometric"),
    "unknown motor model": (model('motors = "steam"'), "model.motors", "velocity, dc"),
    "linear model without stiffness": (model('elastic = "linear"'), "model",
                                       "needs linear_stiffness > 0"),
    "negative linear stiffness": (model('elastic = "linear"\nlinear_stiffness = "-1 N m"'),
                                  "model.linear_stiffness", "must be > 0"),
    "model not a table": (SHORT.replace('network = "wrist"', 'network = "wrist"\nmodel = "x"'),
                          "model", "expected a table"),
    "bench on the wrist": (SHORT.replace("[solver]", "[bench]\nfixed = \"sun\"\n[solver]"),
                           "bench", "only bench networks"),
    "fixed carrier": (PLANETARY.replace('"sun"', '"carrier"'), "bench.fixed", "sun, ring"),
    "unknown drive": (PLANETARY.replace('fixed = "sun"', 'drive = "pedal"'), "bench.drive",
                      "speed, torque"),
    "zero sensor stiffness": (PLANETARY.replace('fixed = "sun"', 'sensor_stiffness = "0 N m"'),
                              "bench.sensor_stiffness", "must be > 0"),
    "q on the planetary bench": (PLANETARY.replace('fixed = "sun"', 'q = "1 cm"'), "bench",
                                 "unknown key(s) q"),
    "elastic bench beyond the pivot range": (ELASTIC.replace('"-0.4 cm"', '"5 cm"'),
                                             "elastic bench", "outside the pivot range"),
    "linear elastic bench": (ELASTIC.replace('q = "-0.4 cm"', 'q = "-0.4 cm"\nmodel = "linear"'),
                             "bench.model", "geometric"),
    "initial q on a bench": (ELASTIC + '[initial]\nq = "1 cm"\n', "initial.q",
                             "only the wrist has a pivot"),
    "frequency zero": (sine('"2 Hz"', '"0 Hz"'), "inputs.motor_1.frequency", "must be > 0"),
    "frequency negative": (sine('"2 Hz"', '"-1 Hz"'), "inputs.motor_1.frequency",
                           "must be > 0"),
    "frequency nan": (sine('"2 Hz"', '"nan Hz"'), "inputs.motor_1.frequency", "NaN"),
    "frequency too high for memory": (sine('"2 Hz"', '"1e9 Hz"'), "inputs.motor_1",
                                      "spline knots"),
    "fade-in too short for memory": (sine('"2 Hz"', '"2 Hz"\nfade_in = "1e-300 s"'),
                                     "inputs.motor_1", "spline knots"),
    "duration too long for memory": (SHORT.replace('"0.3 s"', '"1e7 s"'), "inputs.motor_1",
                                     "spline knots"),
    "amplitude infinite": (sine('"2 rad/s"', '"inf rad/s"'), "inputs.motor_1.amplitude",
                           "not a finite"),
    "amplitude overflowing": (sine('"2 rad/s"', '"1e400 rad/s"'), "inputs.motor_1.amplitude",
                              "not a finite"),
    "offset nan": (sine('"2 Hz"', '"2 Hz"\noffset = "nan rad/s"'), "inputs.motor_1.offset",
                   "NaN"),
    "negative fade-in": (sine('"2 Hz"', '"2 Hz"\nfade_in = "-1 s"'), "inputs.motor_1.fade_in",
                         "must be >= 0"),
    "phase in metres": (sine('"2 Hz"', '"2 Hz"\nphase = "1 m"'), "inputs.motor_1.phase",
                        "cannot be converted"),
    "amplitude as arithmetic": (sine('"2 rad/s"', '"2*3 rad/s"'), "inputs.motor_1.amplitude",
                                "'*' without a unit name"),
    "kind is a number": (sine('"sine"', "5"), "inputs.motor_1.kind", "unknown input kind 5"),
    "unknown kind": (sine('"sine"', '"square"'), "inputs.motor_1.kind",
                     "unknown input kind 'square'"),
    "input not a table": (SHORT.replace('[inputs.motor_1]\nkind = "sine"\namplitude = '
                                        '"2 rad/s"\nfrequency = "2 Hz"\n',
                                        "[inputs]\nmotor_1 = 5\n"), "inputs.motor_1",
                          "a table with a 'kind'"),
    "unknown channel": (SHORT.replace("motor_1", "motor_9"), "inputs.motor_9",
                        "no input 'motor_9'"),
    "sine key on a constant": (extra_input('[inputs.tau_x]\nkind = "constant"\nvalue = "0 N m"'
                                           '\nfrequency = "1 Hz"\n'), "inputs.tau_x",
                               "unknown key(s) frequency"),
    "constant nan": (extra_input('[inputs.tau_x]\nkind = "constant"\nvalue = "nan N m"\n'),
                     "inputs.tau_x.value", "NaN"),
    "table times decrease": (extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, 1, 0.5]\n'
                                         'values = [0, 1, 2]\nunit = "N m"\n'), "inputs.tau_x",
                             "times must increase strictly"),
    "table time is text": (extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, "1 s"]\n'
                                       'values = [0, 1]\nunit = "N m"\n'),
                           "inputs.tau_x.times[1]", "expected a finite number"),
    "table time is nan": (extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, nan]\n'
                                      'values = [0, 1]\nunit = "N m"\n'),
                          "inputs.tau_x.times[1]", "expected a finite number"),
    "table lengths differ": (extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, 1, 2]\n'
                                         'values = [0, 1]\nunit = "N m"\n'), "inputs.tau_x",
                             "same length"),
    "table interpolation": (extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, 1]\n'
                                        'values = [0, 1]\nunit = "N m"\n'
                                        'interpolation = "quadratic"\n'),
                            "inputs.tau_x.interpolation", "linear, cubic"),
    "table unit is a number": (extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, 1]\n'
                                           'values = [0, 1]\nunit = 5\n'), "inputs.tau_x.unit",
                               "expected text"),
    "table time unit in kg": (extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, 1]\n'
                                          'values = [0, 1]\nunit = "N m"\ntime_unit = "kg"\n'),
                              "inputs.tau_x.time_unit", "cannot be converted"),
    "table values overflow in their unit": (
        extra_input('[inputs.tau_x]\nkind = "table"\ntimes = [0, 1]\nvalues = [0, 1e300]\n'
                    'unit = "TN m"\n'), "inputs.tau_x", "finite"),
    "steps hold zero": (extra_input('[inputs.tau_x]\nkind = "steps"\nlevels = [1]\nunit = '
                                    '"mN m"\nhold = "0 s"\nramp = "1 s"\n'),
                        "inputs.tau_x.hold", "must be > 0"),
    "steps without levels": (extra_input('[inputs.tau_x]\nkind = "steps"\nlevels = []\nunit = '
                                         '"mN m"\nhold = "1 s"\nramp = "1 s"\n'),
                             "inputs.tau_x.levels", "non-empty list"),
    "steps start negative": (extra_input('[inputs.tau_x]\nkind = "steps"\nlevels = [1]\nunit = '
                                         '"mN m"\nhold = "1 s"\nramp = "1 s"\nstart = "-1 s"\n'),
                             "inputs.tau_x.start", "must be >= 0"),
    "position on a load": (extra_input('[inputs.tau_x]\nkind = "position"\nsignal = { kind = '
                                       '"constant", value = "1 rad" }\n'), "inputs.tau_x",
                           "not a velocity source"),
    "nested position": (extra_input('[inputs.motor_2]\nkind = "position"\nsignal = { kind = '
                                    '"position" }\n'), "inputs.motor_2.signal",
                        "cannot be nested"),
    "position without signal": (extra_input('[inputs.motor_2]\nkind = "position"\n'),
                                "inputs.motor_2.signal", "a table with a 'kind'"),
    "circle period zero": (extra_input('[inputs.motor_2]\nkind = "circle"\nradius = "1 rad"\n'
                                       'period = "0 s"\n'), "inputs.motor_2.period",
                           "must be > 0"),
    "circle axis z": (extra_input('[inputs.motor_2]\nkind = "circle"\nradius = "1 rad"\n'
                                  'period = "1 s"\naxis = "z"\n'), "inputs.motor_2.axis",
                      "cos, sin"),
    "circle radius infinite": (extra_input('[inputs.motor_2]\nkind = "circle"\nradius = '
                                           '"inf rad"\nperiod = "1 s"\n'),
                               "inputs.motor_2.radius", "not a finite"),
    "circle too fast for memory": (extra_input('[inputs.motor_2]\nkind = "circle"\nradius = '
                                               '"1 rad"\nperiod = "1e-12 s"\n'),
                                   "inputs.motor_2", "spline knots"),
    "parameter override evaluated": (SHORT + '[params]\n"planetary.ring_inertia" = '
                                             '"9**9**9 kg m^2"\n',
                                     "params: planetary.ring_inertia", "exponents from -9"),
    "parameter override without section": (SHORT + '[params]\nring_inertia = "1 kg m^2"\n',
                                           "params", "'section.key'"),
    "params not a table": (SHORT.replace('network = "wrist"', 'network = "wrist"\nparams = 5'),
                           "params", "expected a table"),
    "cases not an array": (SHORT.replace('network = "wrist"', 'network = "wrist"\ncases = 5'),
                           "cases", "array of tables"),
    "duplicate case labels": (SHORT + '[[cases]]\nlabel = "a"\n[[cases]]\nlabel = "a"\n',
                              "cases[1].label", "duplicate label 'a'"),
    "bad key in a case": (SHORT + '[[cases]]\nlabel = "a"\n[[cases]]\ncolour = "red"\n',
                          "cases[1]", "unknown key(s) colour"),
    "case label a number": (SHORT + "[[cases]]\nlabel = 5\n", "cases[0].label",
                            "expected text"),
    "case with a bad value": (SHORT + '[[cases]]\nlabel = "a"\ninitial = { q = "2*3 cm" }\n',
                              "cases[0].initial.q", "'*' without a unit name"),
    "name a number": (SHORT.replace('name = "short"', "name = 5"), "name", "expected text"),
    "unknown top key": (SHORT.replace('network = "wrist"', 'network = "wrist"\ncolour = 1'),
                        "short.toml", "unknown key(s) colour"),
    "not TOML": (SHORT.replace("[solver]", "[solver"), "short.toml", "not valid TOML"),
}


@pytest.mark.parametrize("base", [SHORT, PLANETARY, ELASTIC], ids=["wrist", "planetary",
                                                                    "elastic"])
def test_the_base_scenarios_are_valid(tmp_path, params, base):
    """The cases below fail for their edit, not for the scenario they edit."""
    scen = scenarios.load(str(write(tmp_path / "short.toml", base)))
    for case in scen.cases:
        scenarios.prepare_case(scen, case, params)


@pytest.mark.parametrize("case", sorted(SCENARIOS))
def test_bad_scenarios(tmp_path, capsys, case):
    text, key, message = SCENARIOS[case]
    path = write(tmp_path / "short.toml", text)
    out = tmp_path / "out"
    fails(["simulate", path, "--out", out, "--no-plot"], capsys, "short.toml", key, message)
    assert not out.exists()


#: Key paths of SHORT that the property below rewrites (new keys included).
FUZZED_KEYS = ["name", "network", "duration", "model", "model.elastic", "bench", "solver",
               "solver.friction", "solver.method", "solver.rtol", "solver.max_steps",
               "solver.step", "solver.output_step", "solver.friction_overrides", "initial",
               "initial.q", "initial.angles", "initial.currents", "inputs", "inputs.motor_1",
               "inputs.motor_1.kind", "inputs.motor_1.amplitude", "inputs.motor_1.frequency",
               "inputs.motor_1.fade_in", "inputs.motor_1.start", "inputs.tau_x", "params",
               "cases"]
TOML_VALUE = st.one_of(
    st.integers(), st.floats(), st.booleans(), st.text(max_size=12),
    st.lists(st.one_of(st.integers(), st.floats(), st.text(max_size=4)), max_size=3),
    st.dictionaries(st.text(min_size=1, max_size=6), st.one_of(st.integers(), st.text(
        max_size=6)), max_size=2),
    st.sampled_from(["1e9 Hz", "9**9**9 s", "-1 s", "0 s", "nan s", "1 kg", "inf rad/s",
                     "1e-300 s", "1e7 s", "stiction", "timestep", "table", "circle",
                     "position", "-5 cm", "1 (s"]))


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(FUZZED_KEYS), TOML_VALUE), min_size=1, max_size=3))
def test_rewritten_scenarios_load_or_raise_input_error(params, edits):
    """Whatever value lands at whatever key, reading and preparing the scenario either
    works or raises `InputError` naming the file: nothing else escapes."""
    import tomli_w
    import tomllib

    table = tomllib.loads(SHORT)
    for key, value in edits:
        *parents, last = key.split(".")
        node = table
        for name in parents:
            if not isinstance(node.get(name), dict):
                node[name] = {}
            node = node[name]
        node[last] = value
    try:
        scen = scenarios.loads(tomli_w.dumps(table), "fuzz.toml")
        for case in scen.cases:
            scenarios.prepare_case(scen, case, params)
    except InputError as exc:
        assert str(exc).startswith("fuzz.toml"), str(exc)


def test_a_solver_table_without_keys_takes_the_simulators_defaults():
    """Every [solver] key a scenario leaves out is `SimulationOptions`' default: the
    file and the Python interface cannot drift apart."""
    text = SHORT.replace('friction = "arctan"\noutput_step = "10 ms"\n', "")
    assert text != SHORT
    (case,) = scenarios.loads(text, "defaults.toml").cases
    assert case.options == SimulationOptions()


def test_a_scenario_with_a_byte_order_mark_loads(tmp_path):
    scen = scenarios.load(str(write(tmp_path / "bom.toml", b"\xef\xbb\xbf" + SHORT.encode())))
    assert scen.name == "short"


def test_a_scenario_that_is_not_utf8(tmp_path, capsys):
    data = SHORT.encode().replace(b'"short"', b'"sh\xf6rt"')
    path = write(tmp_path / "short.toml", data)
    out = tmp_path / "out"
    fails(["simulate", path, "--out", out], capsys, "short.toml", "line 1", "byte offset 10",
          "not UTF-8")
    assert not out.exists()


def test_an_existing_output_directory_is_left_as_it_was(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "meta.json").write_text('{"earlier": true}')
    path = write(tmp_path / "short.toml", sine('"2 Hz"', '"1e9 Hz"'))
    fails(["simulate", path, "--out", out], capsys, "inputs.motor_1")
    assert sorted(p.name for p in out.iterdir()) == ["meta.json"]
    assert (out / "meta.json").read_text() == '{"earlier": true}'


# ------------------------------------------------------------------ measurement files

def points(rows):
    return "velocity [rad/s],torque [N m]\n" + "".join(f"{w},{t}\n" for w, t in rows)


GOOD_POINTS = [(w, 0.0015 * w + 0.005 * math.atan(10 * w)) for w in
               (-6, -4, -2, -1, -0.5, 0.5, 1, 2, 4, 6)]


def stiffness_file(pivot_line="# pivot: -0.4 cm\n", pivot_column=None, amplitude=0.3):
    """A loop of 200 samples, deflection back and forth, with its pivot position."""
    t = np.linspace(0, 4, 200)
    phi = amplitude * np.sin(np.pi * t)
    extra = "" if pivot_column is None else f",{pivot_column}"
    return (pivot_line + "time [s],deflection [rad],torque [N m]"
            + (",pivot [m]" if pivot_column is not None else "") + "\n"
            + "".join(f"{a:.4f},{b:.6f},{0.4 * b:.6f}{extra}\n" for a, b in zip(t, phi)))


#: name -> (file text, line the message names or None, what it says)
MEASUREMENTS = {
    "torques times 1e300": (points([(w, t * 1e300) for w, t in GOOD_POINTS]), "line 2",
                            "beyond +-10000"),
    "absurd speed": (points(GOOD_POINTS[:3] + [(1e6, 0.01)] + GOOD_POINTS[4:]), "line 5",
                     "95 000 rpm"),
    "overflowing cell": (points(GOOD_POINTS[:2] + [(1, "1e400")] + GOOD_POINTS[3:]), "line 4",
                         "finite number"),
    "infinite cell": (points(GOOD_POINTS[:2] + [(1, "-inf")] + GOOD_POINTS[3:]), "line 4",
                      "finite number"),
    "empty cell": (points(GOOD_POINTS[:2] + [(1, "")] + GOOD_POINTS[3:]), "line 4",
                   "is not a number"),
    "overflow on conversion": ("velocity [rad/s],torque [TN m]\n" + "".join(
        f"{w},{t * 1e300}\n" for w, t in GOOD_POINTS), "line 2", "beyond"),
    "evaluated header unit": ("velocity [rad/s],torque [9**9**9 N m]\n" + points(
        GOOD_POINTS).split("\n", 1)[1], "line 1", "unexpected '9**9**9"),
    "division in header unit": ("velocity [rad/s],torque [N m / 0]\n" + points(
        GOOD_POINTS).split("\n", 1)[1], "line 1", "unexpected '0'"),
    "unclosed header unit": ("velocity [rad/s],torque [(N m]\n" + points(
        GOOD_POINTS).split("\n", 1)[1], "line 1", "not closed"),
    "giant cell": (points(GOOD_POINTS[:2] + [(1, "1" * 200_000)] + GOOD_POINTS[3:]), "line 4",
                   "cannot split into cells"),
    "time beyond 300 years": ("time [s],velocity [rad/s],torque [N m]\n" + "".join(
        f"{1e11 + i},{w},{t}\n" for i, (w, t) in enumerate(GOOD_POINTS)), "line 2",
        "300 years"),
}


@pytest.mark.parametrize("case", sorted(MEASUREMENTS))
def test_bad_measurement_files(tmp_path, capsys, case):
    text, line, message = MEASUREMENTS[case]
    path = write(tmp_path / "curve.csv", text)
    out = tmp_path / "fit"
    fails(["fit", "friction", path, "--out", out, "--json"], capsys, "curve.csv", line, message)
    assert not out.exists()
    assert capsys.readouterr().out == ""


def test_the_good_points_fit(tmp_path, capsys):
    assert main(["fit", "friction", str(write(tmp_path / "curve.csv", points(GOOD_POINTS)))]) \
        == 0


@pytest.mark.parametrize("encoding,text", [("latin-1", "torque [µN m]"),
                                           ("utf-16", "torque [N m]")])
def test_measurement_files_that_are_not_utf8(tmp_path, capsys, encoding, text):
    data = points(GOOD_POINTS).replace("torque [N m]", text).encode(encoding)
    path = write(tmp_path / "curve.csv", data)
    fails(["fit", "friction", path], capsys, "curve.csv", "line 1", "not UTF-8")


#: name -> (stiffness file text, what the message says)
STIFFNESS = {
    "pivot in furlongs": (stiffness_file("# pivot: -0.4 furlong\n"), "beyond +-10 cm"),
    "pivot nan": (stiffness_file("# pivot: nan cm\n"), "NaN"),
    "pivot evaluated": (stiffness_file("# pivot: 9**9**9 cm\n"), "without a unit name"),
    "pivot in kg": (stiffness_file("# pivot: -0.4 kg\n"), "cannot be converted"),
    "pivot without unit": (stiffness_file("# pivot: -0.4\n"), "has no unit"),
    "pivot column at 80 m": (stiffness_file("", pivot_column=-80), "line 2: pivot -80 [m]"),
    "deflection in degrees called rad": (stiffness_file(amplitude=30.0), "one turn"),
}


@pytest.mark.parametrize("case", sorted(STIFFNESS))
def test_bad_stiffness_files(tmp_path, capsys, case):
    text, message = STIFFNESS[case]
    path = write(tmp_path / "loop.csv", text)
    out = tmp_path / "fit"
    fails(["fit", "stiffness", path, "--out", out], capsys, "loop.csv", message)
    assert not out.exists()


def test_a_good_loop_passes_the_pivot_check(tmp_path, capsys):
    """The stiffness cases fail for their edit: the unedited loop fits."""
    assert main(["fit", "stiffness", str(write(tmp_path / "loop.csv", stiffness_file()))]) == 0


# ------------------------------------------------------------------ command-line options

@pytest.mark.parametrize("option,value,message", [
    ("--q", "nan", "has no unit"), ("--q", "nan cm", "NaN"), ("--q", "inf cm", "not a finite"),
    ("--q", "9**9**9 cm", "without a unit name"), ("--q", "1 cm / 0", "unexpected '0'"),
    ("--q", "(1 cm", "does not start with a number"), ("--q", "1e400 cm", "finite"),
    ("--q", "-0.4", "has no unit"), ("--motor-1", "1 m", "cannot be converted"),
    ("--tau-x", "nan N m", "NaN"), ("--tau-y", "1e309 N m", "finite"),
])
def test_linearize_options(tmp_path, capsys, option, value, message):
    """Units on the command line go through the same parser as files."""
    out = tmp_path / "lin.json"
    fails(["linearize", f"{option}={value}", "--out", out], capsys, option, message)
    assert not out.exists()


def test_linearize_leaves_an_existing_model_file_alone(tmp_path, capsys):
    out = write(tmp_path / "lin.json", '{"format": "vsj-linear-model", "earlier": true}')
    fails(["linearize", "--q=2*3 cm", "--out", out], capsys, "--q")
    assert out.read_text() == '{"format": "vsj-linear-model", "earlier": true}'


@pytest.mark.parametrize("argv,expected", [
    (["--q=nan cm"], ("option --q", "NaN")), (["--period=0 s"], ("period must be > 0",)),
    (["--step=1 s^2"], ("option --step", "cannot be converted")),
    (["--linear-stiffness=1e999 N m", "--elastic", "linear"],
     ("option --linear-stiffness", "finite")),
])
def test_export_model_options(tmp_path, capsys, argv, expected):
    out = tmp_path / "wrist.json"
    fails(["export-model", "--out", out, *argv], capsys, *expected)
    assert not out.exists()


@pytest.mark.parametrize("constants,message", [
    ("nan,1,1", "c1 = nan"), ("1,inf,1", "c2 = inf"), ("-1,1,1", "must be finite and >= 0"),
    ("1,1,0", "c3 = 0.0 s/rad: must be finite and > 0"), ("0,0,1", "both 0"),
    ("1e300,1,1", "beyond the +-10000 N m"), ("a,b,c", "not a comma-separated list"),
    ("1,2", "expected 3 numbers"),
])
def test_synth_friction_constants(tmp_path, capsys, constants, message):
    out = tmp_path / "curve.csv"
    fails(["synth", "friction", "--fixed", "sun", f"--constants={constants}", "--out", out],
          capsys, "constants", message)
    assert not out.exists()


@pytest.mark.parametrize("option,value,message", [
    ("--noise", "nan", "noise = nan"), ("--noise", "-1", "from 0 to 1"),
    ("--ripple", "inf", "ripple = inf"), ("--seed", "-1", "seed = -1"),
])
def test_synth_friction_artefacts(tmp_path, capsys, option, value, message):
    out = tmp_path / "curve.csv"
    fails(["synth", "friction", "--fixed", "ring", "--report", "second", option, value,
           "--out", out], capsys, message)
    assert not out.exists()


@pytest.mark.parametrize("argv,message", [
    (["--q", "50"], "q = 50 cm: must lie in the pivot range"),
    (["--q", "1", "--play", "-1"], "play = -1.0 rad"),
    (["--q", "1", "--play", "inf"], "play = inf rad"),
    (["--q", "1", "--play", "5"], "below the deflection the hand drives"),
    (["--q", "1", "--noise", "5"], "noise = 5.0"),
])
def test_synth_stiffness_options(tmp_path, capsys, argv, message):
    out = tmp_path / "curves"
    fails(["synth", "stiffness", *argv, "--out", out], capsys, message)
    assert not out.exists()


@pytest.mark.parametrize("q", ["nan", "inf"])
def test_synth_stiffness_non_finite_q(tmp_path, capsys, q):
    fails(["synth", "stiffness", "--q", q, "--out", tmp_path / "c.csv"], capsys,
          "--q: pivot positions must be finite")


@pytest.fixture(scope="module")
def friction_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("friction")
    files = {}
    for fixed in ("sun", "ring"):
        files[fixed] = folder / f"{fixed}.csv"
        assert main(["synth", "friction", "--fixed", fixed, "--report", "second", "--form",
                     "points", "--out", str(files[fixed])]) == 0
    return files


@pytest.mark.parametrize("option,value,message", [
    ("--tooth-ratio", "nan", "tooth ratio"), ("--tooth-ratio", "1.5", "between 0 and 1"),
    ("--significance", "0", "significance"), ("--significance", "inf", "between 0 and 1"),
])
def test_fit_planetary_options(tmp_path, capsys, friction_files, option, value, message):
    out, written = tmp_path / "fit", tmp_path / "mine.toml"
    capsys.readouterr()
    fails(["fit", "planetary", "--fixed-sun", friction_files["sun"], "--fixed-ring",
           friction_files["ring"], option, value, "--out", out, "--write-params", written],
          capsys, message)
    assert not out.exists() and not written.exists()


def test_fit_planetary_with_a_bad_base_parameter_file(tmp_path, capsys, friction_files):
    bad = write(tmp_path / "base.toml",
                DEFAULT.replace(INERTIA, 'ring_inertia = { value = "10**400 kg m^2"', 1))
    written = tmp_path / "mine.toml"
    capsys.readouterr()
    code = main(["fit", "planetary", "--fixed-sun", str(friction_files["sun"]), "--fixed-ring",
                 str(friction_files["ring"]), "--params", str(bad), "--write-params",
                 str(written)])
    err = capsys.readouterr().err
    assert code == 2 and "base.toml" in err and "planetary.ring_inertia" in err
    assert not written.exists()


# ------------------------------------------------------- what a new user trips over

def test_an_output_step_longer_than_the_run_is_refused(tmp_path, capsys):
    """A 3 s output step written for a 2 s run kept the start only and called it a
    success. (A run shorter than the default step, which nobody wrote, is not refused.)"""
    path = write(tmp_path / "os.toml", 'duration = "2 s"\n[solver]\noutput_step = "3 s"\n')
    fails(["simulate", path, "--out", tmp_path / "out"], capsys, "os.toml",
          "solver.output_step = 3 s", "longer than the duration (2 s)")
    assert not (tmp_path / "out").exists()
    assert scenarios.loads('duration = "0.5 ms"\n', "short.toml").cases[0].duration == 5e-4


def test_a_run_too_long_for_the_disk_is_refused_before_its_grid_is_made(tmp_path, capsys):
    """1e7 s at 1 ms is 1e10 samples: the grid alone (80 GB) was allocated before the free
    space was checked, which ended in a MemoryError's traceback."""
    path = write(tmp_path / "long.toml", 'duration = "1e7 s"\n')
    fails(["simulate", path, "--out", tmp_path / "out"], capsys, "--out", "nothing was written")
    assert not (tmp_path / "out").exists()


def test_a_file_of_a_result_set_is_not_replaced_by_a_single_file_command(tmp_path, capsys):
    """vsj linearize --out DIR/meta.json replaced a set's file, which vsj verify then found
    changed; the manifest itself is refused too."""
    out = tmp_path / "res"
    scenario = write(tmp_path / "s.toml", SHORT_SCENARIO)
    assert main(["simulate", str(scenario), "--out", str(out)]) == 0
    capsys.readouterr()
    before = (out / "meta.json").read_bytes()
    fails(["linearize", "--out", out / "meta.json"], capsys, "result set 'simulate'",
          "vsj verify")
    fails(["linearize", "--out", out / "vsj-manifest.json"], capsys, "the manifest")
    assert (out / "meta.json").read_bytes() == before
    assert main(["verify", str(out)]) == 0


def test_a_closed_pipe_ends_the_command_quietly():
    """`vsj params | head -1`: the reader goes away; SIGPIPE's exit code, no traceback.
    The pipe's reading end is closed before the command writes (it is still importing)."""
    child = subprocess.Popen([sys.executable, "-m", "vsj", "params"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    child.stdout.close()
    err = child.stderr.read()
    assert child.wait(timeout=120) == 141, err
    assert "Traceback" not in err and "BrokenPipe" not in err


def test_an_unknown_flange_in_the_initial_state_is_named_with_its_key(tmp_path, capsys):
    path = write(tmp_path / "ang.toml", 'duration = "0.1 s"\n[initial]\n'
                                        'angles = { theta_x = "0.5 rad" }\n')
    fails(["simulate", path, "--out", tmp_path / "out"], capsys, "ang.toml",
          "initial.angles.theta_x", "did you mean 'diff.theta_x'?", "vsm_1.ring")
    assert not (tmp_path / "out").exists()


def test_the_ledger_tolerance_is_a_solver_key_with_its_range(tmp_path, capsys):
    """SimulationOptions' fields go by the same names in [solver] (the scheme is `method`):
    ledger_tolerance was refused as an unknown key."""
    scen = scenarios.loads('duration = "0.1 s"\n[solver]\nledger_tolerance = 1e-2\n', "lt.toml")
    assert scen.cases[0].options.ledger_tolerance == 1e-2
    path = write(tmp_path / "lt.toml", 'duration = "0.1 s"\n[solver]\nledger_tolerance = 5\n')
    fails(["simulate", path, "--out", tmp_path / "out"], capsys, "lt.toml", "solver",
          "ledger_tolerance must be a number in [1e-15, 1]")


def test_options_that_would_be_ignored_are_refused(tmp_path, capsys):
    """`vsj params FILE --check OTHER` checked OTHER only; --linear-stiffness without the
    linear elastic model changed nothing."""
    other = write(tmp_path / "other.toml", DEFAULT)
    fails(["params", tmp_path / "first.toml", "--check", other], capsys, "give one file",
          "first.toml", "other.toml")
    fails(["linearize", "--linear-stiffness", "0.8 N m/rad", "--out", tmp_path / "l.json"],
          capsys, "--linear-stiffness", "--elastic linear")
    assert not (tmp_path / "l.json").exists()


@pytest.mark.parametrize("fields, named", [
    ({"angles": {"diff.theta_x": math.nan}}, r"InitialState.angles\['diff.theta_x'\]"),
    ({"angles": {"diff.theta_x": math.inf}}, r"InitialState.angles\['diff.theta_x'\]"),
    ({"speeds": {"diff.theta_x": math.nan}}, r"InitialState.speeds\['diff.theta_x'\]"),
    ({"speeds": {"diff.theta_x": "x"}}, r"InitialState.speeds\['diff.theta_x'\]"),
    ({"currents": {"motor_1": True}}, r"InitialState.currents\['motor_1'\]"),
    ({"q": "1 cm"}, r"InitialState.q"),
    ({"q": -math.inf}, r"InitialState.q"),
    ({"angles": [1, 2]}, r"InitialState.angles must be a mapping"),
    ({"speeds": {3: 1.0}}, r"InitialState.speeds: names are strings"),
])
def test_an_initial_state_from_python_names_its_bad_entry(fields, named):
    """The Python API's initial state refuses what is not a finite number where it is
    made, naming the field and entry (a NaN angle reached the engine's checks as an
    internal array's entry; a NaN speed ran and failed at t = 0)."""
    from vsj.simulate import InitialState

    with pytest.raises(InputError, match=named + ".*finite number|" + named):
        InitialState(**fields)


def test_numpy_scalars_are_the_numbers_they_hold():
    """np.float32 and np.int64 durations and options give the run their float and int
    give (they were refused as "not a finite time > 0 s")."""
    from vsj import build_wrist, simulate
    from vsj.simulate import InitialState

    wrist = build_wrist(params_module.default()).assemble()
    plain = simulate(wrist, {"motor_1": 1.0}, 0.125, initial=InitialState(q=0.0025),
                     options=SimulationOptions(output_step=0.015625, max_steps=100_000))
    numpy = simulate(wrist, {"motor_1": 1.0}, np.float32(0.125),
                     initial=InitialState(q=np.float64(0.0025)),
                     options=SimulationOptions(output_step=np.float32(0.015625),
                                               max_steps=np.int64(100_000)))
    assert plain.success and numpy.success
    assert np.array_equal(plain["theta_x"], numpy["theta_x"])  # 1/8 and 1/64: exact in float32
    whole = simulate(wrist, {}, np.int64(1), options=SimulationOptions(output_step=0.5))
    assert whole.success and whole.time[-1] == 1.0


def test_an_initial_angle_that_contradicts_a_position_input_is_refused():
    """A source driven by an angle (Position) starts where its input does; an initial
    angle given for its flange as well silently won. The same value is accepted, another
    refused with both named."""
    from vsj import build_wrist, simulate
    from vsj.inputs import Position, Sine
    from vsj.simulate import InitialState

    wrist = build_wrist(params_module.default()).assemble()
    driven = {"motor_1": Position(Sine(0.5, 1.0, phase=math.pi / 2))}  # starts at 0.5 rad
    start = simulate(wrist, driven, 0.01, ports=False)["motor_1"][0]
    assert start == pytest.approx(0.5, abs=1e-15)
    same = simulate(wrist, driven, 0.01, ports=False,
                    initial=InitialState(angles={"motor_1.flange": start}))
    assert same["motor_1"][0] == start
    with pytest.raises(InputError, match=r"initial angle of motor_1.flange \(1 rad\) "
                                         r"contradicts its input 'motor_1'"):
        simulate(wrist, driven, 0.01, initial=InitialState(angles={"motor_1.flange": 1.0}))


def _python_api_calls():
    """Calls of the Python API with a wrong type or value, and what their refusal says
    (each gave a raw TypeError, AttributeError or a nonsense result)."""
    from vsj import build_wrist, linear
    from vsj.inputs import Constant, Position, Sine, Step
    from vsj.stepper import Stepper

    network = build_wrist(params_module.default())
    model = linear.linearize(params_module.default(), 0.0)
    return [
        (lambda: Sine("1", 1.0), "sine input: amplitude must be a number"),
        (lambda: Constant("1"), "constant input: level must be a number"),
        (lambda: Constant(True), "constant input: level must be a number"),
        (lambda: Step("a"), "step input: height must be a number"),
        (lambda: Position(1.0), "position input: its angle must be a vsj.inputs signal"),
        (lambda: Stepper(network), "stepper: the model must be an assembled network"),
        (lambda: Stepper(network.assemble(), "1 ms"), r"stepper: period must be > 0 s \(a number"),
        (lambda: Stepper(network.assemble(), options={}),
         "stepper: options must be a SimulationOptions"),
        (lambda: linear.bandwidth(model, "theta_x", "motor_1", drop_db=3.0),
         "drop_db must be a negative number of dB"),
        (lambda: linear.bandwidth(model, "theta_x", "motor_1", drop_db=math.nan),
         "drop_db must be a negative number of dB"),
    ]


@pytest.mark.parametrize("k", range(10))
def test_the_python_api_names_a_wrong_argument(k):
    call, message = _python_api_calls()[k]
    with pytest.raises(InputError, match=message):
        call()


def test_a_circle_of_negative_radius_is_refused():
    scen = scenarios.loads(
        'name = "c"\ndescription = "a circle"\nnetwork = "wrist"\nduration = "1 s"\n'
        '[model]\nend_effector = "driven"\n[inputs.theta_x]\nkind = "circle"\n'
        'radius = "-1.1 rad"\nperiod = "10 s"\n'
        '[inputs.theta_y]\nkind = "circle"\nradius = "1.1 rad"\nperiod = "10 s"\n'
        'axis = "sin"\n[[cases]]\nlabel = "a"\n', "circle.toml")
    with pytest.raises(InputError, match=r"inputs.theta_x.radius .*must be > 0 rad"):
        scenarios.prepare_case(scen, scen.cases[0], params_module.default())

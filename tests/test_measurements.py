"""Measurement files: units converted on reading, every bad file named with its line."""

import math

import numpy as np
import pytest

from vsj import measurements
from vsj.cli import main
from vsj.errors import InputError

EPS = np.finfo(float).eps
#: A number read and converted to SI: the decimal read to half an ulp, times a unit
#: factor rounded to half an ulp (pint's, or the cache's).
CONVERSION = 2 * EPS
#: `measurements.write` keeps 10 significant digits: half a unit of the tenth digit,
#: plus the conversions both ways.
WRITTEN = 0.5 * 10.0 ** (1 - 10) + 2 * CONVERSION

GOOD = "# a comment\ntime [s],velocity [rpm],torque [mN m],angle [deg]\n" + "".join(
    f"{0.1 * i:.1f},{60.0},{5.0 + i},{90.0 * i}\n" for i in range(6))


def write(tmp_path, text, name="m.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_units_are_converted_to_si(tmp_path):
    m = measurements.read(write(tmp_path, GOOD))
    assert m["velocity"][0] == pytest.approx(2 * math.pi, rel=CONVERSION, abs=0)  # 60 rpm
    assert m["torque"][1] == pytest.approx(6e-3, rel=CONVERSION, abs=0)  # 6 mN m
    assert m["angle"][2] == pytest.approx(math.pi, rel=CONVERSION, abs=0)  # 180 deg
    assert m.comments == ["a comment"]


@pytest.mark.parametrize("sep", [";", "\t"])
def test_separators_are_detected(tmp_path, sep):
    text = "deflection [deg]{0}torque [N m]{0}pivot [mm]\n".format(sep) + "".join(
        f"{i}{sep}{0.1 * i}{sep}14\n" for i in range(6))
    m = measurements.read(write(tmp_path, text))
    assert m["deflection"][3] == pytest.approx(math.radians(3), rel=CONVERSION, abs=0)
    assert m["pivot"][0] == pytest.approx(0.014, rel=CONVERSION, abs=0)


def test_write_then_read_round_trips_and_marks_synthetic(tmp_path):
    t = np.linspace(0, 1, 11)
    torque = t * 1e-3 / 3  # thirds: every digit counts
    path = tmp_path / "w.csv"
    measurements.write(path, {"time": (t, "s"), "torque": (torque, "mN m")},
                       ["synthetic test data"])
    m = measurements.read(path)
    np.testing.assert_allclose(m["torque"], torque, rtol=WRITTEN, atol=0)
    assert m.synthetic
    assert "torque [mN m]" in path.read_text()


BAD = {
    "missing column": ("time [s],torque [N m]\n" + "".join(f"{i},{i}\n" for i in range(6)),
                       "missing column(s) velocity"),
    "unknown unit": ("velocity [furlongs],torque [N m]\n" + "1,2\n" * 6, "furlongs"),
    "no unit": ("velocity,torque [N m]\n" + "1,2\n" * 6, "has no unit"),
    "non-numeric": ("velocity [rad/s],torque [N m]\n" + "1,2\n" * 3 + "1,abc\n" + "1,2\n" * 2,
                    "line 5: torque cell 'abc' is not a number"),
    "nan": ("velocity [rad/s],torque [N m]\n" + "1,2\n" * 3 + "nan,2\n" + "1,2\n" * 2,
            "line 5: velocity is 'nan'"),
    "too few points": ("velocity [rad/s],torque [N m]\n1,2\n2,3\n", "2 data points"),
    "time not increasing": ("time [s],velocity [rad/s],torque [N m]\n0,1,1\n1,1,1\n0.5,1,1\n"
                            "2,1,1\n3,1,1\n4,1,1\n", "line 4: time does not increase"),
    "ragged row": ("velocity [rad/s],torque [N m]\n" + "1,2\n" * 3 + "1\n" + "1,2\n" * 2,
                   "line 5: 1 cells"),
    "no separator": ("velocity [rad/s]\n" + "1\n" * 6, "separator"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_files_name_file_line_and_problem(tmp_path, capsys, case):
    text, message = BAD[case]
    path = write(tmp_path, text)
    with pytest.raises(InputError, match=str(path).replace(".", r"\.")) as info:
        measurements.read(path, required=("velocity", "torque"))
    assert message in str(info.value)
    # the command says the same and exits 2
    assert main(["fit", "friction", str(path)]) == 2
    assert message in capsys.readouterr().err


def test_missing_file_exits_2(tmp_path, capsys):
    assert main(["fit", "friction", str(tmp_path / "nope.csv")]) == 2
    assert "cannot read" in capsys.readouterr().err

"""vsj never replaces a file it did not write (issue 31, item 2): result sets take only
what a directory's manifest records as theirs, and single-file outputs (an FMU, a model
file) replace an existing file only if it carries vsj's mark, or with --force."""

from __future__ import annotations

import os

import pytest

from vsj.cli import main
from vsj.output import MANIFEST, verify, written_by_vsj

from conftest import SHORT_SCENARIO


@pytest.fixture
def scenario(tmp_path):
    path = tmp_path / "short.toml"
    path.write_text(SHORT_SCENARIO)
    return path


def test_simulate_refuses_a_users_trajectory_in_a_directory_without_a_manifest(
        tmp_path, scenario, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "trajectory.nc").write_text("the user's own data\n")
    assert main(["simulate", str(scenario), "--out", str(out), "--no-plot"]) == 2
    err = capsys.readouterr().err
    assert "did not write (trajectory.nc" in err
    assert (out / "trajectory.nc").read_text() == "the user's own data\n"
    assert sorted(os.listdir(out)) == ["trajectory.nc"]


def test_a_file_named_like_vsjs_but_not_in_the_manifest_is_not_taken(tmp_path, scenario,
                                                                       capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(scenario), "--out", str(out), "--no-plot"]) == 0
    (out / "trajectory.csv").write_text("a user's table, named as vsj would name it\n")
    assert main(["simulate", str(scenario), "--out", str(out), "--csv", "--no-plot"]) == 2
    assert "trajectory.csv" in capsys.readouterr().err
    assert (out / "trajectory.csv").read_text().startswith("a user's table")
    (out / "trajectory.csv").unlink()
    assert main(["simulate", str(scenario), "--out", str(out), "--csv", "--no-plot"]) == 0
    assert verify(out) == []
    assert (out / MANIFEST).is_file()


def test_export_model_refuses_a_foreign_file_unless_forced(tmp_path, capsys):
    target = tmp_path / "model.json"
    target.write_text('{"mine": true}\n')
    assert main(["export-model", "--out", str(target)]) == 2
    assert "vsj did not write it" in capsys.readouterr().err
    assert target.read_text() == '{"mine": true}\n'
    assert main(["export-model", "--out", str(target), "--force"]) == 0
    assert written_by_vsj(target)
    assert main(["export-model", "--out", str(target)]) == 0  # its own: replaced


def test_fmu_refuses_a_foreign_file_unless_forced(tmp_path, capsys):
    target = tmp_path / "wrist.fmu"
    target.write_bytes(b"PK\x03\x04 not an FMU of vsj's")
    assert main(["fmu", "--out", str(target), "--win64", "no"]) == 2
    assert "vsj did not write it" in capsys.readouterr().err
    assert target.read_bytes().startswith(b"PK\x03\x04 not")
    assert main(["fmu", "--out", str(target), "--win64", "no", "--force"]) == 0
    assert written_by_vsj(target)


@pytest.mark.parametrize("text, ours", [
    ("# synthetic data written by vsj 0.2.0\ntime [s]\n0\n", True),
    ("time [s]\n0\n", False),
    ('{"format": "vsj-model"}', True),
    ('{"vsj_version": "0.2"}', True),
    ('{"other": 1}', False),
    ("not json {", False),
])
def test_vsjs_mark(tmp_path, text, ours):
    path = tmp_path / "f"
    path.write_text(text)
    assert written_by_vsj(path) is ours


# ---- the Python API checks its arguments (issue 31, item 12) -------------------------

def test_simulate_says_what_an_input_must_be(params):
    import numpy as np

    import vsj
    from vsj.errors import InputError
    from vsj.inputs import Constant

    wrist = vsj.build_wrist(params).assemble()
    with pytest.raises(InputError, match=r"input 'motor_1' must be a vsj.inputs signal .* got "
                                         r"ndarray \(samples: Table\(times, values\)"):
        vsj.simulate(wrist, {"motor_1": np.array([0.0, 1.0])}, 0.1)
    with pytest.raises(InputError, match="unknown input channel 'motor_9'"):
        vsj.simulate(wrist, {"motor_9": Constant(1.0)}, 0.1)
    with pytest.raises(InputError, match="inputs must be a mapping"):
        vsj.simulate(wrist, [Constant(1.0)], 0.1)
    with pytest.raises(InputError, match="assembled network"):
        vsj.simulate(vsj.build_wrist(params), {}, 0.1)
    with pytest.raises(InputError, match="duration must be a number"):
        vsj.simulate(wrist, {}, "1 s")
    with pytest.raises(InputError, match="options must be a SimulationOptions"):
        vsj.simulate(wrist, {}, 0.1, options={"friction": "arctan"})
    # a number is a constant input
    a = vsj.simulate(wrist, {"motor_1": 1.5}, 0.05, ports=False)
    b = vsj.simulate(wrist, {"motor_1": Constant(1.5)}, 0.05, ports=False)
    assert a.success and np.array_equal(a["theta_x"], b["theta_x"])


@pytest.mark.parametrize("argv, option", [
    (["synth", "friction", "--fixed", "sun", "--report", "second", "--out", "OUT"], "--out"),
    (["synth", "stiffness", "--q", "1.4", "--out", "OUT"], "--out"),
])
def test_synth_outputs_replace_only_their_own_files(tmp_path, capsys, argv, option):
    target = tmp_path / "data.csv"
    target.write_text("time [s],torque [N m]\n0,1\n")  # a user's measurements
    args = [str(target) if a == "OUT" else a for a in argv]
    assert main(args) == 2
    assert "vsj did not write it" in capsys.readouterr().err
    assert target.read_text() == "time [s],torque [N m]\n0,1\n"
    assert main(args + ["--force"]) == 0 and written_by_vsj(target)
    assert main(args) == 0  # its own file: replaced without --force


def test_written_parameter_files_carry_vsjs_mark(tmp_path):
    sun, ring = tmp_path / "sun.csv", tmp_path / "ring.csv"
    for fixed, path in (("sun", sun), ("ring", ring)):
        assert main(["synth", "friction", "--fixed", fixed, "--report", "second", "--out",
                     str(path)]) == 0
    out = tmp_path / "mine.toml"
    out.write_text("# my own notes\n")
    base = ["fit", "planetary", "--fixed-sun", str(sun), "--fixed-ring", str(ring)]
    assert main(base + ["--write-params", str(out)]) == 2
    assert out.read_text() == "# my own notes\n"
    assert main(base + ["--write-params", str(out), "--force"]) == 0
    assert written_by_vsj(out)

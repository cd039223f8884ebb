"""Experiment files and fit options that make no sense are refused (issue 31, item 9)."""

from __future__ import annotations

import pytest

from vsj.cli import main
from vsj.errors import InputError
from vsj.identification import wrist_experiment as WE

HEAD = """[experiment]
duration = "2 s"
motors = "velocity"
"""


@pytest.mark.parametrize("signals, message", [
    ('[signals.motor_1]\nmultisine = { frequency = [0.3], amplitude = [1.0, 2.0], phase = [0, 0] }',
     "frequency has 1, amplitude has 2, phase has 2 entries"),
    ('[signals.tau_x]\npulses = { start = [0.5], width = -0.3, height = [0.05] }',
     "width = -0.3: must be > 0"),
    ('[signals.tau_x]\npulses = { start = [0.5], width = [0.3], height = [0.05] }',
     "width = [0.3]: a single number"),
    ('[signals.motor_1]\nsine = { frequency = 0, amplitude = 1.0 }', "frequency = 0.0: must be > 0"),
    ('[signals.motor_1]\nmultisine = { frequency = 0.3, amplitude = [1.0], phase = [0] }',
     "frequency = 0.3: a list of numbers"),
    ('[signals.motor_1]\nsine = { frequency = 1, amplitude = 1.0, phase = 2 }',
     "phase: unknown key"),
    ('[signals.q]\nsteps = { time = [1.0, 0.5], value = [0.0, 0.01] }', "times must increase"),
])
def test_a_component_of_the_wrong_shape_is_refused(tmp_path, signals, message):
    path = tmp_path / "exp.toml"
    path.write_text(HEAD + signals + "\n")
    with pytest.raises(InputError, match=message.replace("[", r"\[").replace("]", r"\]")):
        WE.load(path)
    assert main(["synth", "wrist", "--experiment", str(path), "--out",
                 str(tmp_path / "log.csv")]) == 2
    assert not (tmp_path / "log.csv").exists()


@pytest.mark.parametrize("option", [["--starts", "0"], ["--threads", "-3"], ["--starts", "x"]])
def test_fit_wrist_counts_must_be_at_least_one(tmp_path, capsys, option):
    log = tmp_path / "log.csv"
    log.write_text("time [s],theta_x [rad]\n0,0\n")
    with pytest.raises(SystemExit) as exit_:
        main(["fit", "wrist", str(log), *option])
    assert exit_.value.code == 2
    assert option[0] in capsys.readouterr().err

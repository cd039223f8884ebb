"""`vsj synth wrist`: the end-effector channels' ``time_offset`` is a lag behind the motor
channels, as documented, for any size and either sign (issue 30, section 2).

The logs are synthetic (`vsj.synth.wrist`, labelled so), of a short experiment.
"""

import json
from dataclasses import replace

import numpy as np
import pytest

from vsj import synth
from vsj.cli import main
from vsj.errors import InputError
from vsj.identification import wrist_experiment as WE
from vsj.identification.wrist_model import all_known_columns
from vsj.measurements import read_log

#: The fit's delay estimate lies within this fraction of the offset of it. The check is on
#: the offset's sign and size (a sign error misses by twice the offset); the estimate's
#: own error on 2 s of log is an order of magnitude smaller (tens of microseconds), and its
#: standard error is no yardstick here because issue 30 recalibrates it separately.
DELAY_TOLERANCE = 0.1
#: An offset of two sample periods at 1 kHz: the size at which the log used to end in
#: repeated timestamps.
OFFSET = 2e-3


def experiment(duration=2.0, **sensors):
    """Both motors driven by multisines and pulses on the end-effector (about 2 s)."""
    signals = {
        "motor_1": (("multisine", {"frequency": (0.7, 1.9, 4.3), "amplitude": (2.0, 1.0, 0.6),
                                   "phase": (0.0, 1.0, 2.0)}),),
        "motor_2": (("multisine", {"frequency": (1.1, 2.7, 5.1), "amplitude": (2.0, 1.0, 0.6),
                                   "phase": (0.5, 1.5, 2.5)}),),
        "tau_x": (("pulses", {"start": (0.6,), "width": 0.4, "height": (0.1,)}),),
        "tau_y": (("pulses", {"start": (1.2,), "width": 0.4, "height": (-0.1,)}),),
    }
    return WE.Experiment(duration=duration, signals=signals, q=-0.004, step=5e-4,
                         sensors=replace(WE.Sensors(), **sensors), origin="test experiment")


@pytest.mark.parametrize("offset", [OFFSET, -OFFSET])
def test_end_effector_angles_are_logged_offset_behind(params, offset):
    """Noise-free sensors: at time t the log holds the end-effector angles of t - offset
    (before the start, the wrist at rest where it starts) and the motor angles of t."""
    e = experiment(encoder_counts=2 ** 40, angle_noise=0.0, jitter=0.0, time_offset=offset)
    run = synth.wrist_run(e, params)
    assert run.time[-1] >= e.duration - offset - 1e-12  # a lead needs the run to go on
    data = synth.wrist(e, params, seed=1, run=run)
    t = data.columns["time"][0]
    resolution = 2 * np.pi / e.sensors.encoder_counts

    def logged(name, delay):  # what an ideal encoder reads, quantised as the log is
        return np.round(np.interp(t - delay, run.time, run[name]) / resolution) * resolution

    for name in ("theta_x", "theta_y"):
        np.testing.assert_array_equal(data.columns[name][0], logged(name, offset))
    np.testing.assert_array_equal(data.columns["motor_1"][0], logged("motor_1", 0.0))
    if offset > 0:
        early = t < offset
        assert early.sum() == 2  # t = 0 and 1 ms
        assert np.all(data.columns["theta_x"][0][early] == logged("theta_x", 0.0)[0])
    assert "ahead of" in " ".join(data.comments) if offset < 0 else \
        f"{offset:g} s behind" in " ".join(data.comments)


def test_a_run_too_short_for_a_lead_is_refused(params):
    e = experiment(1.0, time_offset=-OFFSET)
    short = synth.wrist_run(replace(e, sensors=WE.Sensors()), params)
    with pytest.raises(InputError, match="run_end"):
        synth.wrist(e, params, run=short)


@pytest.mark.parametrize("offset", [0.8e-3, OFFSET, -OFFSET])
def test_fit_wrist_recovers_the_offset_with_its_sign(tmp_path, capsys, offset):
    """End to end: an experiment file with ``time_offset``, `vsj synth wrist`, and the
    delay `vsj fit wrist` estimates for the end-effector channels (positive: behind; a
    log made with 0.8 ms used to come back as -0.8 ms)."""
    path = tmp_path / "experiment.toml"
    path.write_text(experiment(time_offset=offset).to_toml())
    log = tmp_path / "log.csv"
    assert main(["synth", "wrist", "--experiment", str(path), "--seed", "3",
                 "--out", str(log)]) == 0
    # every row its own sample time, a period apart (jitter sd 0.02 ms)
    time = read_log(log, all_known_columns()).columns["time"]
    assert len(time) == 2000 and np.all(np.diff(time) > 0.5e-3)
    capsys.readouterr()
    assert main(["fit", "wrist", str(log), "--free", "differential.inertia_x", "--starts", "1",
                 "--json"]) == 0
    delays = json.loads(capsys.readouterr().out)["delays"]
    for name in ("delay.theta_x", "delay.theta_y"):
        d = delays[name]
        assert np.sign(d["value"]) == np.sign(offset)
        assert abs(d["value"] - offset) <= DELAY_TOLERANCE * abs(offset), (name, d, offset)


@pytest.mark.parametrize("offset", ["5 ms", "-5 ms", "1 ms"])
def test_any_offset_gives_a_log_that_fit_wrist_reads(tmp_path, params, offset):
    """Offsets of one sample period and more, either way: one row per sample period to
    the end (they used to end in repeated timestamps)."""
    path = tmp_path / "experiment.toml"
    path.write_text(experiment(1.0).to_toml().replace('time_offset = "0.0002 s"',
                                                      f'time_offset = "{offset}"'))
    e = WE.load(path)
    assert e.sensors.time_offset == pytest.approx(float(offset.split()[0]) * 1e-3, rel=1e-12)
    log = tmp_path / "log.csv"
    assert main(["synth", "wrist", "--experiment", str(path), "--out", str(log)]) == 0
    time = read_log(log, all_known_columns()).columns["time"]
    assert len(time) == 1000 and np.all(np.diff(time) > 0.5e-3)


@pytest.mark.parametrize("key, value, message", [
    ("time_offset", '"-20 s"', "below the duration"),
    ("time_offset", '"1 min"', "below the duration"),
    ("jitter", '"0.2 ms"', "tenth of the sample period"),
])
def test_sensor_timing_out_of_range_is_refused(tmp_path, key, value, message):
    path = tmp_path / "experiment.toml"
    text = experiment(10.0).to_toml()
    line = next(line for line in text.splitlines() if line.startswith(f"{key} ="))
    path.write_text(text.replace(line, f"{key} = {value}"))
    with pytest.raises(InputError, match=message) as error:
        WE.load(path)
    assert f"sensors.{key}" in str(error.value) and str(path) in str(error.value)

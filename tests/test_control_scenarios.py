"""Controllers in scenario files (issue 33): the [controller] table read with its units,
run by `vsj simulate`, changed by cases; every bad input refused with the file and the
key path; the examples in examples/controllers run and track; the ledger closes with a
controller, limits and stiction."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from scenario_checks import fails, write
from vsj import scenario as scenarios
from vsj.cli import main
from vsj.errors import InputError

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "controllers"

#: A small closed loop: one PID on motor 1's angle driving its voltage.
BASE = """name = "ctl"
network = "wrist"
duration = "0.2 s"
[model]
motors = "dc"
pivot_drive = "dc"
[controller]
rate = "1 kHz"
[controller.references.r]
kind = "step"
height = "0.1 rad"
start = "20 ms"
[[controller.sensors]]
signal = "motor_1"
[[controller.pid]]
name = "u1"
setpoint = "r"
measurement = "motor_1"
k = "100 V/rad"
Ti = "50 ms"
Td = "2 ms"
[[controller.actuators]]
channel = "voltage_1"
command = "u1"
"""


def edit(old: str, new: str, text: str = BASE) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


def run(text: str, origin: str = "ctl.toml", **kwargs):
    return scenarios.run(scenarios.loads(text, origin), **kwargs)


# ---------------------------------------------------------------- reading and running


def test_the_table_becomes_the_controller_in_si(params):
    """Every value in SI with its unit's factor: a gain in V/deg, times in ms, an
    encoder's counts, noise in mrad, limits in mV, a current limit in mA."""
    text = edit('k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"',
                'k = "2 V/deg"\nTi = "50 ms"\nTd = "2 ms"\ny_max = "5000 mV"\n'
                'y_min = "-5 V"\nNd = 8\nwd = 1\nanti_windup = "clamping"')
    text = edit('signal = "motor_1"\n', 'signal = "motor_1"\ncounts_per_revolution = 1000\n'
                'noise = "0.5 mrad"\ndelay = 2\n', text)
    text = edit('command = "u1"\n', 'command = "u1"\nlimits = ["-4000 mV", "4 V"]\n'
                'current_limit = "800 mA"\noffset = "0.1 V"\n', text)
    scen = scenarios.loads(text, "ctl.toml")
    prepared = scenarios.prepare_case(scen, scen.cases[0], params)
    ctl = prepared.controller
    assert ctl.period == 1e-3 and ctl.seed == 0
    (sensor,) = ctl.sensors
    assert sensor.resolution == 2 * math.pi / 1000 and sensor.noise == 5e-4
    assert sensor.delay == 2
    (pid,) = ctl.blocks
    assert pid.k == pytest.approx(2 * 180 / math.pi, rel=1e-15)  # 2 V/deg in V/rad
    assert (pid.Ti, pid.Td, pid.Nd, pid.wd) == (0.05, 0.002, 8.0, 1.0)
    assert (pid.y_min, pid.y_max, pid.anti_windup) == (-5.0, 5.0, "clamping")
    (act,) = ctl.actuators
    assert act.limits == (-4.0, 4.0) and act.current_limit == pytest.approx(0.8, rel=1e-15)
    assert act.offset == 0.1
    assert ctl.references["r"].height == 0.1 and ctl.references["r"].start == 0.02
    assert prepared.plan.controller is not None  # the plan carries it into the engine


def test_simulate_runs_a_controller_and_writes_its_signals(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, BASE)), "--out", str(out)]) == 0
    import xarray as xr

    with xr.open_dataset(out / "trajectory.nc") as ds:
        reference = ds["control.r"].values[0]
        angle = ds["motor_1"].values[0]
        voltage = ds["actuator.voltage_1"].values[0]
    # the step reached: within 2 % of it 0.18 s after it (the PID of BASE settles in
    # about 0.1 s; a loop that did not close would leave the motor at rest)
    assert reference[-1] == 0.1
    assert abs(angle[-1] - 0.1) < 0.02 * 0.1
    assert np.max(np.abs(voltage)) > 0.0
    meta = json.loads((out / "meta.json").read_text())
    assert meta["success"] and meta["scenario"]["definition"]["controller"]["rate"] == "1 kHz"


def test_a_case_changes_a_controller_entry_by_name(params):
    """[cases.controller.pid.u1] changes that PID's keys and leaves the rest; a case may
    also replace a whole table (its references)."""
    text = BASE + ('[[cases]]\nlabel = "base"\n'
                   '[[cases]]\nlabel = "soft"\n[cases.controller.pid.u1]\nk = "20 V/rad"\n'
                   '[[cases]]\nlabel = "big step"\n[cases.controller.references.r]\n'
                   'height = "0.3 rad"\n'
                   '[[cases]]\nlabel = "slow"\n[cases.controller]\nrate = "500 Hz"\n')
    scen = scenarios.loads(text, "ctl.toml")
    ctls = [scenarios.prepare_case(scen, c, params).controller for c in scen.cases]
    assert [c.blocks[0].k for c in ctls] == [100.0, 20.0, 100.0, 100.0]
    assert [c.blocks[0].Ti for c in ctls] == [0.05] * 4
    assert [c.references["r"].height for c in ctls] == [0.1, 0.1, 0.3, 0.1]
    assert [c.period for c in ctls] == [1e-3, 1e-3, 1e-3, 2e-3]


def test_a_run_of_another_duration_keeps_the_controller(params):
    """`scenario.run(duration=...)` runs the case anew (not its compiled plan): the
    controller must be in that run too."""
    (r,) = run(BASE, duration=0.1)
    assert r.result.success and r.result.time[-1] == pytest.approx(0.1)
    assert "actuator.voltage_1" in r.result.signals
    assert np.max(np.abs(r.result.signals["motor_1"])) > 0.05


def test_blocks_run_in_the_order_their_inputs_need():
    """A block listed before the block whose output it reads runs after it (the file's
    order otherwise): the cascade's inner PID first in the file still reads the outer
    one's output of the same sample."""
    text = BASE.replace('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\n'
                        'measurement = "motor_1"\nk = "100 V/rad"\nTi = "50 ms"\n'
                        'Td = "2 ms"\n',
                        '[[controller.sensors]]\nsignal = "motor_1"\nquantity = "speed"\n'
                        '[[controller.pid]]\nname = "u1"\nsetpoint = "w1"\n'
                        'measurement = "motor_1.speed"\nk = "1 V s/rad"\nTi = "20 ms"\n'
                        '[[controller.pid]]\nname = "w1"\nsetpoint = "r"\n'
                        'measurement = "motor_1"\nk = "40 1/s"\n')
    scen = scenarios.loads(text, "ctl.toml")
    from vsj import params

    ctl = scenarios.prepare_case(scen, scen.cases[0], params.default()).controller
    assert [b.name for b in ctl.blocks] == ["w1", "u1"]
    assert ctl.blocks[0].k == 40.0 and ctl.blocks[1].k == 1.0


def test_a_discrete_pi_as_a_transfer_function_runs_as_the_pid_does():
    """An integrator (a pole on the unit circle) is a linear block like any other: the
    PID's sampled PI, k (1 + T / (Ti (z - 1))) with its forward-Euler integral, written as
    num, den drives motor 2 exactly as the PID block drives motor 1 (the wrist is
    symmetric in its two motors, which take the same reference)."""
    k, Ti, T = 100.0, 0.05, 1e-3
    text = edit('Td = "2 ms"\n', '') + (
        '[[controller.sensors]]\nsignal = "motor_2"\n'
        '[[controller.linear]]\nname = "u2"\ninputs = [{ r = 1.0, motor_2 = -1.0 }]\n'
        f'unit = "V/rad"\nnum = [{k}, {k * (T / Ti - 1.0)}]\nden = [1.0, -1.0]\n'
        '[[controller.actuators]]\nchannel = "voltage_2"\ncommand = "u2"\n')
    (r,) = run(text)
    s = r.result.signals
    assert r.result.success
    scale = np.max(np.abs(s["control.u1"]))
    assert scale > 1.0
    # the same arithmetic but for the order of its roundings (1e-16 relative), through
    # a stable loop: far below this bound; another integral (T/Ti off by a sample, a
    # backward-Euler sum) differs in the second digit
    assert np.max(np.abs(s["control.u1"] - s["control.u2"])) <= 1e-9 * scale


def test_an_unstable_compensator_is_taken_when_the_file_says_so(params):
    text = edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
                'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
                '[[controller.linear]]\nname = "u1"\ninputs = [{ r = 1, motor_1 = -1 }]\n'
                'num = [10.0, -9.0]\nden = [1.0, -1.5]\nallow_unstable = true\n')
    scen = scenarios.loads(text, "ctl.toml")
    (block,) = scenarios.prepare_case(scen, scen.cases[0], params).controller.blocks
    assert block.allow_unstable


# ------------------------------------------------------------------------- bad input

NO_DC = BASE.replace('[model]\nmotors = "dc"\npivot_drive = "dc"\n', "")

#: name -> (scenario text, the key path and what the message says)
BAD = {
    "unknown controller key": (edit('rate = "1 kHz"', 'rate = "1 kHz"\ngain = 3'),
                               "controller: unknown key(s) gain", "allowed: actuators"),
    "unknown block type": (BASE + '[[controller.lqr]]\nname = "x"\n',
                           "controller: unknown key(s) lqr", "linear", "pid"),
    "unknown PID key": (edit('Td = "2 ms"', 'Td = "2 ms"\nKp = 3'),
                        "controller.pid[0]: unknown key(s) Kp", "allowed:"),
    "unknown sensor quantity": (edit('signal = "motor_1"\n', 'signal = "motor_1"\n'
                                     'quantity = "torque"\n'),
                                "controller.sensors[0].quantity", "angle, speed, current, q"),
    "unknown anti-windup": (edit('Td = "2 ms"', 'Td = "2 ms"\nanti_windup = "magic"'),
                            "controller.pid[0].anti_windup", "back-calculation"),
    "gain in N m/rad for a voltage": (edit('"100 V/rad"', '"100 N m/rad"'),
                                      "controller.pid[0].k", "'100 N m/rad' has unit N m/rad",
                                      "V/rad"),
    "speed gain for an angle": (edit('"100 V/rad"', '"100 V s/rad"'),
                                "controller.pid[0].k", "cannot be converted to 'V/rad'"),
    "gain without a unit": (edit('"100 V/rad"', "100"), "controller.pid[0].k", "no unit"),
    "Ti in metres": (edit('Ti = "50 ms"', 'Ti = "50 mm"'), "controller.pid[0].Ti",
                     "cannot be converted"),
    "PID limit in N m": (edit('Td = "2 ms"', 'Td = "2 ms"\ny_max = "1 N m"'),
                         "controller.pid[0].y_max", "cannot be converted to 'V'"),
    "actuator limits in A": (edit('command = "u1"', 'command = "u1"\nlimits = ["-1 A", "1 A"]'),
                             "controller.actuators[0].limits[0]", "cannot be converted"),
    "negative rate": (edit('"1 kHz"', '"-1 kHz"'), "controller.rate", "must be > 0"),
    "zero period": (edit('rate = "1 kHz"', 'period = "0 s"'), "controller.period",
                    "must be > 0"),
    "rate in seconds": (edit('"1 kHz"', '"1 ms"'), "controller.rate", "cannot be converted"),
    "rate and period": (edit('rate = "1 kHz"', 'rate = "1 kHz"\nperiod = "1 ms"'),
                        "controller: give either rate", "not both"),
    "neither rate nor period": (edit('rate = "1 kHz"\n', ''), "controller: give either rate"),
    "faster than the time-stepper": (edit('pivot_drive = "dc"\n', 'pivot_drive = "dc"\n'
                                          '[solver]\nmethod = "timestep"\nstep = "1 ms"\n',
                                          edit('"1 kHz"', '"2 kHz"')),
                                     "controller.rate", "more often than the time-stepper",
                                     "(solver.step = 0.001 s)"),
    "not a whole number of steps": (edit('pivot_drive = "dc"\n', 'pivot_drive = "dc"\n'
                                         '[solver]\nfriction = "stiction"\nstep = "0.3 ms"\n'
                                         'output_step = "0.3 ms"\n'),
                                    "controller.rate", "not a whole number",
                                    "(solver.step = 0.0003 s)"),
    "period longer than the run": (edit('"1 kHz"', '"2 Hz"'), "controller.rate",
                                   "longer than the run"),
    "unstable transfer function": (
        edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
             'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
             '[[controller.linear]]\nname = "u1"\ninputs = [{ r = 1, motor_1 = -1 }]\n'
             'unit = "V/rad"\nnum = [10.0, -9.0]\nden = [1.0, -1.5]\n'),
        "controller.linear[0].den", "unstable", "modulus 1.5", "allow_unstable = true"),
    "allow_unstable as text": (
        edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
             'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
             '[[controller.linear]]\nname = "u1"\ninputs = [{ r = 1, motor_1 = -1 }]\n'
             'num = [10.0, -9.0]\nden = [1.0, -1.5]\nallow_unstable = "yes"\n'),
        "controller.linear[0].allow_unstable", "true or false"),
    "unstable state matrix": (
        edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
             'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
             '[[controller.linear]]\nname = "u1"\ninputs = [{ r = 1, motor_1 = -1 }]\n'
             'A = [[0.5, 1.0], [0.0, 1.2]]\nB = [[0.0], [1.0]]\nC = [[1.0, 0.0]]\n'
             'D = [[0.0]]\n'),
        "controller.linear[0].A", "modulus 1.2 > 1"),
    "improper transfer function": (
        edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
             'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
             '[[controller.linear]]\nname = "u1"\ninputs = ["motor_1"]\n'
             'num = [1.0, 0.0, 0.0]\nden = [1.0, 0.5]\n'),
        "controller.linear[0].num", "improper"),
    "matrix of the wrong size": (
        edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
             'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
             '[[controller.linear]]\nname = "u1"\ninputs = [{ r = 1, motor_1 = -1 }]\n'
             'A = [[0.5]]\nB = [[1.0, 0.0]]\nC = [[1.0]]\nD = [[0.0]]\n'),
        "controller.linear[0].B", "1 x 1 needed"),
    "unknown setpoint": (edit('setpoint = "r"', 'setpoint = "r9"'),
                         "controller.pid[0].setpoint", "unknown signal 'r9'", "r, motor_1, u1"),
    "unknown command": (edit('command = "u1"', 'command = { u1 = 1.0, u7 = 0.5 }'),
                        "controller.actuators[0].command", "unknown signal 'u7'"),
    "unknown sensor signal": (edit('signal = "motor_1"', 'signal = "motor_9"'),
                              "controller.sensors[0].signal", "unknown signal 'motor_9'",
                              "theta_x"),
    "current of no motor": (edit('signal = "motor_1"\n', 'signal = "motor_1"\n[[controller.'
                                 'sensors]]\nsignal = "theta_x"\nquantity = "current"\n'),
                            "controller.sensors[1].signal", "not a DC motor"),
    "actuator on a velocity source": (NO_DC.replace('channel = "voltage_1"',
                                                    'channel = "motor_1"'),
                                      "controller.actuators[0].channel", "velocity source",
                                      'motors = "dc"'),
    "voltage without DC motors": (NO_DC, "controller.actuators[0].channel",
                                  "no motor voltage 'voltage_1'", '[model] motors = "dc"'),
    "stiffness motor without its DC drive": (
        edit('pivot_drive = "dc"\n', '').replace('channel = "voltage_1"',
                                                 'channel = "voltage_s"'),
        "controller.actuators[0].channel", "'voltage_s'", 'pivot_drive = "dc"'),
    "actuator on no input": (edit('channel = "voltage_1"', 'channel = "brake"'),
                             "controller.actuators[0].channel", "no input 'brake'",
                             "tau_x, tau_y, voltage_1"),
    "input driven twice": (BASE + '[inputs.voltage_1]\nkind = "constant"\nvalue = "1 V"\n',
                           "inputs.voltage_1", "the controller drives 'voltage_1' "
                           "(controller.actuators[0].channel)"),
    "two actuators on one channel": (BASE + '[[controller.actuators]]\nchannel = "voltage_1"\n'
                                     'command = "u1"\n', "controller.actuators[1].channel",
                                     "driven by controller.actuators[0]"),
    "no actuator": (BASE[:BASE.index("[[controller.actuators]]")], "controller",
                    "drives nothing"),
    "reference of a position kind": (edit('kind = "step"\nheight = "0.1 rad"\n'
                                          'start = "20 ms"',
                                          'kind = "circle"\nradius = "1 rad"\n'
                                          'period = "1 s"'),
                                     "controller.references.r", "step, table"),
    "reference in volts": (edit('height = "0.1 rad"', 'height = "0.1 V"'),
                           "controller.references.r.height", "cannot be converted to 'rad'"),
    "setpoint and measurement in different units": (
        edit('signal = "motor_1"\n', 'signal = "motor_1"\n[[controller.sensors]]\n'
             'signal = "motor_1"\nquantity = "speed"\n').replace(
            'setpoint = "r"', 'setpoint = "motor_1.speed"'),
        "controller.pid[0]", "must share a unit", "rad/s", "'motor_1'"),
    "command in radians": (edit('command = "u1"', 'command = "motor_1"'),
                           "controller.actuators[0].command", "'motor_1' would be in V",
                           "sensor 'motor_1'"),
    "blocks in a loop": (edit('setpoint = "r"', 'setpoint = "u2"') + (
        '[[controller.pid]]\nname = "u2"\nsetpoint = "u1"\nmeasurement = "motor_1"\n'
        'k = "1 V/rad"\n'), "controller: the blocks 'u1', 'u2' read each other's outputs"),
    "a name used twice": (edit('[[controller.pid]]\nname = "u1"',
                               '[[controller.pid]]\nname = "r"'),
                          "controller.pid[0]: the name 'r' is already taken",
                          "controller.references.r"),
    "PID that drives nothing": (BASE + '[[controller.pid]]\nname = "spare"\nsetpoint = "r"\n'
                                'measurement = "motor_1"\nk = "1 V/rad"\n',
                                "controller.pid[1]", "drives no actuator"),
    "tracking time shorter than the period": (
        edit('Ti = "50 ms"', 'Ti = "1 ms"\nNi = 0.5'), "controller.pid[0]", "tracking time"),
    "counts on a speed": (edit('signal = "motor_1"\n', 'signal = "motor_1"\nquantity = "speed"'
                               '\ncounts_per_revolution = 100\nname = "v"\n'),
                          "controller.sensors[0].counts_per_revolution",
                          "an encoder measures an angle"),
    "zero counts": (edit('signal = "motor_1"\n', 'signal = "motor_1"\n'
                         'counts_per_revolution = 0\n'),
                    "controller.sensors[0].counts_per_revolution", "whole number of counts >= 1"),
    "negative noise": (edit('signal = "motor_1"\n', 'signal = "motor_1"\nnoise = "-1 mrad"\n'),
                       "controller.sensors[0].noise", "must be >= 0"),
    "noise in volts": (edit('signal = "motor_1"\n', 'signal = "motor_1"\nnoise = "1 mV"\n'),
                       "controller.sensors[0].noise", "cannot be converted to 'rad'"),
    "fractional delay": (edit('signal = "motor_1"\n', 'signal = "motor_1"\ndelay = 1.5\n'),
                         "controller.sensors[0].delay", "whole number of samples"),
    "delay with a unit": (edit('signal = "motor_1"\n', 'signal = "motor_1"\ndelay = "1 ms"\n'),
                          "controller.sensors[0].delay", "whole number of samples"),
    "a delay beyond the engine's arrays": (
        edit('signal = "motor_1"\n', 'signal = "motor_1"\ndelay = 1000000000\n'),
        "controller.sensors[0].delay", "from 0 to 100000000"),
    "current limit on a torque": (
        edit('command = "u1"\n', 'command = "u1"\n[[controller.actuators]]\nchannel = "tau_x"'
             '\ncommand = "t"\ncurrent_limit = "1 A"\n[[controller.pid]]\nname = "t"\n'
             'setpoint = "r"\nmeasurement = "motor_1"\nk = "1 N m/rad"\n'),
        "controller.actuators[1].current_limit", "needs a motor's voltage"),
    "weight as text": (edit('command = "u1"', 'command = { u1 = "1 V" }'),
                       "controller.actuators[0].command.u1", "finite plain number"),
    "a case changes no such block": (BASE + '[[cases]]\nlabel = "a"\n'
                                     '[cases.controller.pid.u9]\nk = "1 V/rad"\n',
                                     "cases[0].controller.pid.u9", "no pid entry named 'u9'",
                                     "'u1'"),
    "a case's bad gain": (BASE + '[[cases]]\nlabel = "a"\n[cases.controller.pid.u1]\n'
                          'k = "1 V s"\n', "cases[0].controller.pid[0].k",
                          "cannot be converted to 'V/rad'"),
    "sensors not an array": (edit('[[controller.sensors]]\nsignal = "motor_1"\n',
                                  '[controller.sensors]\nsignal = "motor_1"\n'),
                             "controller.sensors", "array of tables"),
    "both forms of a linear block": (
        edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
             'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
             '[[controller.linear]]\nname = "u1"\ninputs = ["motor_1"]\n'
             'num = [1.0]\nden = [1.0]\nD = [[1.0]]\n'),
        "controller.linear[0]", "not both"),
    "linear block's unit wrong": (
        edit('[[controller.pid]]\nname = "u1"\nsetpoint = "r"\nmeasurement = "motor_1"\n'
             'k = "100 V/rad"\nTi = "50 ms"\nTd = "2 ms"\n',
             '[[controller.linear]]\nname = "u1"\ninputs = [{ r = 1, motor_1 = -1 }]\n'
             'unit = "A/rad"\nD = [[10.0]]\n'),
        "controller.linear[0].unit", "cannot be converted to 'V/rad'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_controllers_exit_2_naming_the_key(tmp_path, capsys, case):
    text, *expected = BAD[case]
    fails(tmp_path, capsys, text, *expected)


def test_the_base_is_valid(params):
    """The cases above fail for their edit, not for BASE."""
    scen = scenarios.loads(BASE, "ctl.toml")
    scenarios.prepare_case(scen, scen.cases[0], params)


#: Key paths of BASE that the property below rewrites.
FUZZED = ["controller", "controller.rate", "controller.seed", "controller.references",
          "controller.references.r", "controller.references.r.height", "controller.sensors",
          "controller.pid", "controller.actuators", "controller.linear"]
ENTRY = ["signal", "quantity", "counts_per_revolution", "noise", "delay", "name", "setpoint",
         "measurement", "k", "Ti", "y_max", "channel", "command", "limits", "current_limit",
         "inputs", "num", "den", "A", "D", "unit"]
VALUE = st.one_of(
    st.integers(-3, 5000), st.floats(allow_nan=True), st.booleans(), st.text(max_size=8),
    st.lists(st.one_of(st.floats(-2, 2), st.integers(-2, 2), st.text(max_size=3),
                       st.lists(st.floats(-2, 2), max_size=2)), max_size=3),
    st.dictionaries(st.sampled_from(["r", "u1", "motor_1", "x"]),
                    st.one_of(st.floats(), st.text(max_size=3)), max_size=2),
    st.sampled_from(["1 kHz", "-1 kHz", "1e9 Hz", "1e-9 Hz", "100 V/rad", "1 V s/rad",
                     "1 N m/rad", "0 s", "nan s", "inf V", "r", "u1", "motor_1",
                     "motor_1.speed", "voltage_1", "tau_x", "motor_s", "speed", "q",
                     "current", "V/rad", "1 mrad", "-1 mrad"]))


@settings(max_examples=120, deadline=None)
@given(st.lists(st.one_of(
    st.tuples(st.sampled_from(FUZZED), VALUE),
    st.tuples(st.sampled_from(["controller.sensors", "controller.pid", "controller.actuators",
                               "controller.linear"]), st.sampled_from(ENTRY), VALUE)),
    min_size=1, max_size=3))
def test_rewritten_controllers_load_or_raise_input_error(params, edits):
    """Whatever lands at whatever key of [controller], reading and preparing the
    scenario either works or raises `InputError` naming the file: nothing else
    escapes."""
    import tomli_w
    import tomllib

    table = tomllib.loads(BASE)
    for edit_ in edits:
        if len(edit_) == 2:
            key, value = edit_
            *parents, last = key.split(".")
            node = table
            for name in parents:
                if not isinstance(node.get(name), dict):
                    node[name] = {}
                node = node[name]
            node[last] = value
        else:
            key, entry_key, value = edit_
            if not isinstance(table.get("controller"), dict):
                continue
            array = table["controller"].setdefault(key.split(".")[1], [{}])
            if isinstance(array, list) and array and isinstance(array[0], dict):
                array[0][entry_key] = value
    try:
        scen = scenarios.loads(tomli_w.dumps(table), "fuzz.toml")
        for case in scen.cases:
            scenarios.prepare_case(scen, case, params)
    except InputError as exc:
        assert str(exc).startswith("fuzz.toml"), str(exc)


# -------------------------------------------------------------------------- examples


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """``example(name)``: examples/controllers/<name>.toml run by `vsj simulate`; its
    signals by case label, from the trajectory file it wrote."""
    import xarray as xr

    made = {}

    def run_example(name: str) -> dict[str, dict[str, np.ndarray]]:
        if name not in made:
            out = tmp_path_factory.mktemp(name) / "out"
            assert main(["simulate", str(EXAMPLES / f"{name}.toml"), "--out", str(out)]) == 0
            with xr.open_dataset(out / "trajectory.nc") as ds:
                assert ds["success"].values.tolist() == [1] * ds.sizes["case"]
                made[name] = {str(label): {k: ds[k].values[c] for k in ds.data_vars
                                           if "time" in ds[k].dims}
                              | {"time": ds["time"].values}
                              for c, label in enumerate(ds["case"].values)}
        return made[name]

    return run_example


def window(s, name: str, start: float, end: float) -> np.ndarray:
    """Samples of signal ``name`` in ``start < t <= end``."""
    t = s["time"]
    return s[name][(t > start) & (t <= end)]


def test_every_example_is_tested():
    assert sorted(p.stem for p in EXAMPLES.glob("*.toml")) == sorted(
        ["cascade", "linear", "pid-per-motor", "sensors-and-limits", "stiction"])


def test_example_pid_per_motor(example):
    (s,) = example("pid-per-motor").values()
    e1, e2 = s["control.m1"] - s["motor_1"], s["control.m2"] - s["motor_2"]
    # the file's promise: within a few milliradians all along (ramps of 1.6 rad/s), a
    # fraction of one on the plateau
    assert np.max(np.abs(e1)) < 1e-2 and np.max(np.abs(e2)) < 1e-2
    assert np.max(np.abs(window(s, "control.m1", 0.5, 0.6) - window(s, "motor_1", 0.5, 0.6))) \
        < 1e-3
    # the stiffness motor reached its 20 rad (the pivot moved), its voltage at the motor's
    # own 24 V limit on the way, the others' far from it
    assert abs(s["motor_s"][-1] - 20.0) < 1e-3 * 20.0
    assert np.max(s["actuator.voltage_s"]) == 24.0
    assert np.max(np.abs(s["actuator.voltage_1"])) < 24.0


def test_example_cascade(example):
    (s,) = example("cascade").values()
    # the outer PID's output is the inner one's set-point, limited to 10 rad/s: it
    # reaches the limit exactly on the long ramps (0.8 rad in 50 ms)
    assert np.max(np.abs(s["control.w1"])) == 10.0
    assert np.max(np.abs(s["motor_1.speed"])) < 1.2 * 10.0  # the inner loop follows it
    # each plateau held within a milliradian over its last 50 ms
    for end in (0.4, 0.7, 1.0):
        for m in ("1", "2"):
            e = window(s, f"control.m{m}", end - 0.05, end) - window(s, f"motor_{m}",
                                                                     end - 0.05, end)
            assert np.max(np.abs(e)) < 1e-3, (end, m)


def test_example_linear(example):
    (s,) = example("linear").values()
    # one system in two forms: the voltages agree to round-off (their coefficients to
    # double rounding; through the stable loop the difference stays at that level)
    scale = np.max(np.abs(s["control.u1"]))
    assert np.max(np.abs(s["control.u1"] - s["control.u2"])) <= 1e-9 * scale
    assert scale > 1.0  # and they did act
    for start, end in ((0.25, 0.32), (0.55, 0.6)):
        e = window(s, "control.m1", start, end) - window(s, "motor_1", start, end)
        assert np.max(np.abs(e)) < 1e-3


def test_example_sensors_and_limits(example):
    cases = example("sensors-and-limits")
    s, wound = cases["anti-windup"], cases["no-anti-windup"]
    # the current limit at the step (t = 0.1 s, a sample): the voltage that drives
    # 0.5 A into the motor at its speed then, V = R I + k_t omega (motor.* parameters)
    k = int(np.searchsorted(s["time"], 0.1))
    for m in ("1", "2"):
        emf = 0.0235 * s[f"motor.motor_{m}.speed"][k]
        assert s[f"actuator.voltage_{m}"][k] == pytest.approx(2.3 * 0.5 + emf, rel=1e-12)
        assert np.max(np.abs(s[f"actuator.voltage_{m}"])) == 6.0  # then the 6 V limit
    # anti-windup: overshoot below 1 % of the step; wound up, more than 20 %, and at
    # least 5 times that with it
    for m in ("motor_1", "motor_2"):
        with_aw, without = np.max(s[m]) - 1.0, np.max(wound[m]) - 1.0
        assert with_aw < 0.01 and without > 0.2 and without > 5 * max(with_aw, 0.0), m
    # the encoder's reading: held to within a milliradian late in the run, while the
    # exact sensor's motor sits closer; the delayed, quantised reading differs from the
    # angle it reads
    assert np.max(np.abs(1.0 - window(s, "motor_1", 0.8, 1.0))) < 1e-3
    assert np.max(np.abs(1.0 - window(s, "motor_2", 0.8, 1.0))) < 1e-4
    assert np.max(np.abs(s["control.enc_1"] - s["motor_1"])) > 2 * math.pi / 4096


def test_example_stiction(example):
    cases = example("stiction")
    for label, s in cases.items():
        for m in ("1", "2"):  # each plateau held over its last 0.1 s
            for end in (0.42, 0.74):
                e = window(s, f"control.m{m}", end - 0.1, end) - window(s, f"motor_{m}",
                                                                       end - 0.1, end)
                assert np.max(np.abs(e)) < 1e-4, (label, m, end)
    stuck, smooth = cases["stiction"], cases["smooth"]
    # with stiction the end-effector side stays stuck between the moves: theta_x is the
    # same to round-off over the second plateau; with the smooth law it creeps
    hold = window(stuck, "theta_x", 0.5, 0.7)
    assert np.ptp(hold) < 1e-12 and np.max(np.abs(hold)) > 1e-4
    assert np.ptp(window(smooth, "theta_x", 0.5, 0.7)) > 1e-4
    assert np.mean(stuck["friction.tr_1.friction.stuck"]) > 0.5
    assert not np.any(smooth["friction.tr_1.friction.stuck"])


# ---------------------------------------------------------------------------- ledger


#: Round-off of the ledger per solver step: each booked term is a product of a few
#: doubles, rounded to about 1e-16 each; ten of them per step and term (as in
#: tests/test_ledger.py).
LEDGER_ROUNDOFF_PER_STEP = 1e-15


def limited_stiction_loop(elastic: str, step: str = "") -> str:
    """BASE with stiction at the default step (or ``step``), a 1 rad step through a 3 V
    and 0.4 A limit, and a second loop that pushes theta_x with a torque limited to
    20 mN m; ``elastic`` lines go into [model]."""
    text = edit('pivot_drive = "dc"\n', f'pivot_drive = "dc"\n{elastic}[solver]\n'
                f'friction = "stiction"\n{step}')
    text = edit('height = "0.1 rad"', 'height = "1 rad"', text)
    text = edit('command = "u1"\n', 'command = "u1"\nlimits = ["-3 V", "3 V"]\n'
                'current_limit = "0.4 A"\n[[controller.actuators]]\nchannel = "tau_x"\n'
                'command = "tx"\nlimits = ["-20 mN m", "20 mN m"]\n', text)
    return text.replace('duration = "0.2 s"', 'duration = "0.5 s"') + (
        '[[controller.sensors]]\nsignal = "theta_x"\n[[controller.pid]]\nname = "tx"\n'
        'setpoint = { r = -0.2 }\nmeasurement = "theta_x"\nk = "1 N m/rad"\n')


@pytest.mark.parametrize("elastic", ["linear", "geometric"])
def test_the_ledger_closes_with_a_controller_limits_and_stiction(elastic):
    """Issue 33: the ledger closes (1e-6 of the energy in play) with controllers, their
    limits active, and true stiction, at the default step (the time-stepper at 1 ms,
    the controller sampling every step). With linear springs the time-stepper books
    every step's work to round-off, so a controller's work booked wrongly would show;
    the report's geometric elastic element adds the residual of its linearisation over
    a step, of second order in the step (tests/test_stiction.py check_ledger)."""
    model = ('elastic = "linear"\nlinear_stiffness = "0.5 N m"\n' if elastic == "linear"
             else "")
    (r,) = run(limited_stiction_loop(model))
    result, s = r.result, r.result.signals
    assert result.success, result.message
    assert result.solver["name"] == "timestep" and result.solver["step"] == 1e-3
    # the limits acted: the voltage at 3 V and, at first, below it by the current
    # limit; the torque at its 20 mN m
    volts = s["actuator.voltage_1"]
    assert np.max(np.abs(volts)) == 3.0 and 0.0 < np.max(np.abs(volts[:30])) < 3.0
    assert np.max(np.abs(s["actuator.tau_x"])) == pytest.approx(0.02, rel=1e-15)
    assert sum(result.transitions.values()) > 0  # stuck and slipping
    residual = abs(result.ledger["relative_residual"])
    assert residual <= 1e-6  # the bound
    if elastic == "linear":
        assert residual <= result.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP
    else:
        (halved,) = run(limited_stiction_loop(model, 'step = "0.5 ms"\n'))
        finer = abs(halved.result.ledger["relative_residual"])
        # second order: ratio 4 when the step halves, first order 2: their geometric mean
        assert residual / finer > 2 ** 1.5, (residual, finer)


def test_a_sweep_closes_each_runs_loop_with_its_own_parameters(tmp_path, capsys):
    """A sweep runs the scenario's controller in every run, compiled with that run's
    network: a motor's voltage_limit, the default limit of its actuator, clips the
    voltage in the run that lowers it and not in the other."""
    spec = tmp_path / "sweep.toml"
    spec.write_text(f'''
[sweep]
scenario = "{EXAMPLES / 'pid-per-motor.toml'}"
seed = 1

[vary]
"motor.voltage_limit" = {{ values = ["0.5 V", "24 V"] }}

[metrics]
volts = {{ kind = "peak", signal = "actuator.voltage_1" }}
moved = {{ kind = "peak", signal = "theta_x" }}
''')
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 0
    rows = (tmp_path / "out" / "metrics.csv").read_text().splitlines()[1:]
    volts = [float(row.split(",")[-2]) for row in rows]
    moved = [float(row.split(",")[-1]) for row in rows]
    assert volts[0] == 0.5          # clipped at the lowered limit, to the bit
    assert 0.5 < volts[1] < 24.0    # the same loop, unclipped
    assert min(moved) > 0.01        # the loops moved the wrist in both runs

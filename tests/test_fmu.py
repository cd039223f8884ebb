"""The wrist FMU (`vsj.fmu`), imported by FMPy as a 20-sim or Simulink user's tool would.

FMPy is the independent importer: it validates the FMU, loads its binary and
calls the FMI 2.0 functions. The FMU's results are compared with vsj's own
`simulate` and with the step function (`vsj.stepper`, the same held inputs).

What "the same inputs" can mean. The FMU holds its inputs over each
communication step. Efforts (external torques, DC-motor voltages) held that way
are given to `simulate` exactly by a `vsj.inputs.Hold`, and the time-stepper
evaluates them mid-step in both: the results agree to round-off. A velocity
source held that way changes its speed in a jump at each communication point;
the FMU (the step function) applies the jump between two steps, `simulate`'s
time-stepper inside one (its trapezoidal positions see half of it), a first-order
difference of the scheme, not of the FMU.
So the fig-4.15 motion with stiction is checked on DC motors driven by held
voltages, and the velocity-driven fig-4.15 with smooth friction (dopri, where the
FMU's held speeds differ from the scenario's smooth ones by O(h^2)) at a 0.25 ms
communication step against `simulate` of the scenario itself.
"""

import json
import re
import shutil
import struct
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2False,
                        fmi2True)
from fmpy.validation import validate_fmu

from vsj import fmu, params, scenario
from vsj.cli import main
from vsj.engine.core import IMPULSE_REL
from vsj.errors import InputError
from vsj.inputs import Constant, Hold
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.simulate.signals import catalogue
from vsj.wrist import WristOptions, build_wrist

H = 1e-3
Q0 = -0.01
EPS = np.finfo(float).eps
#: FMU against `vsj simulate`, a fraction of each signal's range: the acceptance of the
#: FMU's issue (a requirement on the FMU, not a numerical tolerance); each comparison
#: also checks the bound its numerics give.
OF_RANGE = 1e-6
#: The FMU's q: the pivot angle is set from q0 by asin and read back by sin, a few
#: roundings of the crank radius.
Q_ROUND_TRIP = 4 * EPS * params.default().pivot.amplitude


def same_engine(steps: int, elements: int, span: float, value: float) -> float:
    """How far two builds of the engine (the FMU's binary, compiled by fmu.build, and
    vsj's extension, under whatever flags) may part on the same inputs [the signal's
    unit]: with true stiction each step decides each friction element's impulse to
    IMPULSE_REL of the slip scale, so the states drift apart by at most steps x
    elements x IMPULSE_REL of their range ``span`` (the regression tubes' model), above
    a few ulps of the signal's size ``value``."""
    return steps * elements * IMPULSE_REL * span + 4 * EPS * value


def frictions(wrist_options=None) -> int:
    """The number of friction elements of the wrist."""
    return len(build_wrist(params.default(), wrist_options).assemble().frictions)
#: FMU outputs and the `simulate` signals they are
SIGNALS = {"theta_x": "theta_x", "theta_y": "theta_y",
           "deflection_1": "spring.vsm_1.deflection", "deflection_2": "spring.vsm_2.deflection",
           "q": "q", "motor_1_angle": "motor_1", "motor_2_angle": "motor_2",
           "motor_1_speed": "motor_1.speed", "motor_2_speed": "motor_2.speed"}


@pytest.fixture(scope="module")
def wrist_fmu(wrist_fmu_file):
    """The default FMU, built once per session (shared with test_fmu_refusals.py)."""
    return wrist_fmu_file(friction="stiction", step=H, q0=Q0, win64=False)


def refs(path):
    return {v.name: v.valueReference for v in read_model_description(str(path)).modelVariables}


def held_inputs(tau_x, duration):
    names = ["motor_1", "motor_2", "motor_s", "tau_x", "tau_y"]
    rows = [(0.0, 0, 0, 0, tau_x, 0), (duration, 0, 0, 0, tau_x, 0)]
    return np.array(rows, dtype=[("time", float)] + [(n, float) for n in names])


class Slave:
    """One FMPy instance of the FMU, stepped by hand."""

    def __init__(self, path, unzipped, name="wrist", start=None, tolerance=None,
                 initialize=True):
        """Instantiated and, with ``initialize``, initialised (`start`)."""
        md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.fmu.instantiate()
        if initialize:
            self.start(start, tolerance)

    def start(self, start=None, tolerance=None, setup=True):
        """Set up the experiment (with the importer's ``tolerance``, if given; not with
        ``setup`` False) and initialise, with the parameter values ``start``."""
        if setup:
            self.fmu.setupExperiment(tolerance=tolerance, startTime=0.0)
        self.fmu.enterInitializationMode()
        for key, value in (start or {}).items():
            self.fmu.setReal([self.vr[key]], [value])
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def step(self, inputs, steps=1, h=H):
        for _ in range(steps):
            for key, value in inputs.items():
                self.fmu.setReal([self.vr[key]], [value])
            self.fmu.doStep(self.t, h)
            self.t += h

    def get(self, *names):
        return np.array(self.fmu.getReal([self.vr[n] for n in names]))

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


@pytest.fixture(scope="module")
def unzipped(wrist_fmu):
    directory = extract(str(wrist_fmu[0]))
    yield directory
    shutil.rmtree(directory, ignore_errors=True)


def test_fmpy_validates_the_fmu_and_the_binary_exports_every_fmi2_function(wrist_fmu, unzipped):
    path, info = wrist_fmu
    assert validate_fmu(str(path)) == []
    header = (Path(fmu.__file__).parent / "fmi" / "fmi2.h").read_text()
    declared = set(re.findall(r"FMI2_EXPORT [^;]*?\b(fmi2\w+)\(", header))
    assert len(declared) == 44
    binary = Path(unzipped) / "binaries" / "linux64" / "vsj_wrist.so"
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(binary)], capture_output=True,
                             text=True, check=True).stdout
    exported = set(re.findall(r" T (fmi2\w+)", symbols))
    assert declared <= exported
    # the engine (vsj_*) and the FMU's internal functions (fmu__*) stay hidden
    assert set(re.findall(r" T (\w+)", symbols)) == declared
    md = read_model_description(str(path))
    variables = {v.name: v for v in md.modelVariables}
    assert variables["transmission.stiction"].causality == "parameter"
    assert variables["transmission.stiction"].variability == "tunable"
    assert variables["transmission.stiction"].unit == "N.m"
    assert variables["theta_x"].causality == "output" and variables["theta_x"].unit == "rad"
    # the outputs that are signals of a run say what the run's signal table says
    table = {s.name: s for s in catalogue(build_wrist(params.default()).assemble(),
                                          ports=False)}
    for name, signal in fmu.OUTPUTS:
        if signal is not None:
            assert variables[name].description == table[signal].description, name
            assert variables[name].unit == table[signal].unit.replace(" ", "."), name  # FMI's
    assert variables["pivot_q0"].start == str(Q0) or float(variables["pivot_q0"].start) == Q0
    assert {"planetary.sun_teeth", "transmission.ratio"} <= set(info["constant"])
    for name in ("sources/vsj_fmu.c", "sources/timestep.c", "sources/buildDescription.xml",
                 "resources/model.vsjm", "resources/fmu.txt", "modelDescription.xml"):
        assert (Path(unzipped) / name).is_file(), name
    # an importer builds from sources/ with the files buildDescription.xml lists: every
    # file of the engine and of the FMI layer is there, and every .c file is listed
    shipped = {p.name for p in (Path(unzipped) / "sources").iterdir()}
    package = Path(fmu.__file__).parent
    for folder in (package / "engine" / "c", package / "fmi"):
        assert {p.name for p in folder.glob("*.[ch]")} <= shipped, folder
    listed = re.findall(r'<SourceFile name="([^"]+)"/>',
                        (Path(unzipped) / "sources" / "buildDescription.xml").read_text())
    assert sorted(listed) == sorted(name for name in shipped if name.endswith(".c"))


def test_a_held_wrist_under_a_torque_matches_vsj_simulate_and_does_not_drift(wrist_fmu):
    path, _ = wrist_fmu
    out = simulate_fmu(str(path), stop_time=2.0, step_size=H, output_interval=H,
                       input=held_inputs(0.3, 2.0),
                       output=["theta_x", "theta_y", "q", "n_stuck", "deflection_1"])
    structure = build_wrist(params.default()).assemble()
    ref = simulate(structure, {"tau_x": Constant(0.3)}, 2.0, initial=InitialState(q=Q0),
                   options=SimulationOptions(friction="stiction", step=H, output_step=H))
    assert ref.success
    steps, elements = ref.solver["steps"], len(structure.frictions)
    span = max(np.ptp(ref[name]) for name in ("theta_x", "theta_y"))  # the wrist's motion
    for name in ("theta_x", "theta_y"):
        size = np.max(np.abs(ref[name]))
        allowed = same_engine(steps, elements, span, size)
        assert np.max(np.abs(out[name] - ref[name])) <= allowed, name
    assert np.all(np.abs(out["q"] - Q0) <= Q_ROUND_TRIP)
    settled = out["time"] >= 1.0
    # held by true stiction: no creep beyond the impulse solver's tolerance
    assert np.ptp(out["theta_x"][settled]) <= same_engine(steps, elements, span, 0.0)
    assert out["n_stuck"][-1] > 0


def test_time_varying_commands_match_the_step_function(wrist_fmu, unzipped):
    from vsj.stepper import Stepper

    path, _ = wrist_fmu
    stepper = Stepper.wrist(params.default(), None, H,
                            options=SimulationOptions(friction="stiction", step=H),
                            method="timestep")
    state = stepper.initial_state(InitialState(q=Q0))
    slave = Slave(path, unzipped)
    rows = stepper.angle_rows(["theta_x", "theta_y"])
    worst, angles = 0.0, []
    for k in range(1500):
        t = k * H
        u = {"motor_1": 3.0 * np.sin(2 * np.pi * 0.5 * t),
             "motor_2": 3.0 * np.cos(2 * np.pi * 0.5 * t), "motor_s": 0.0,
             "tau_x": 0.0, "tau_y": 0.05}
        inputs = np.array([u[n] for n in stepper.input_names])
        state = stepper.step(state, inputs)
        slave.step(u)
        angles.append(rows @ state)
        worst = max(worst, float(np.max(np.abs(slave.get("theta_x", "theta_y") - angles[-1]))))
    slave.close()
    angles = np.array(angles)
    assert worst <= same_engine(len(angles), frictions(), np.max(np.ptp(angles, axis=0)),
                                np.max(np.abs(angles)))


def test_two_instances_give_the_results_of_two_separate_runs(wrist_fmu, unzipped):
    path, _ = wrist_fmu
    loads = {"tau_x": 0.3}
    alone = []
    for stiction in (0.001, 0.01):
        s = Slave(path, unzipped, start={"transmission.stiction": stiction})
        s.step(loads, 300)
        alone.append(s.get("theta_x"))
        s.close()
    a = Slave(path, unzipped, "a", start={"transmission.stiction": 0.001})
    b = Slave(path, unzipped, "b", start={"transmission.stiction": 0.01})
    for _ in range(300):
        a.step(loads)
        b.step(loads)
    together = [a.get("theta_x"), b.get("theta_x")]
    a.close()
    b.close()
    assert np.array_equal(together[0], alone[0]) and np.array_equal(together[1], alone[1])
    assert not np.array_equal(alone[0], alone[1])


def test_a_tunable_parameter_changes_the_result_as_a_parameter_file_does(wrist_fmu, unzipped):
    path, _ = wrist_fmu
    changed = {"differential.stiction": 0.02, "planetary.ring_inertia": 1.2e-4}
    s = Slave(path, unzipped, start=changed)
    s.step({"tau_x": 0.3}, 800)
    theta = s.get("theta_x")[0]
    s.close()
    overridden = params.default().with_overrides(
        {"differential.stiction": "0.02 N m", "planetary.ring_inertia": "1.2e-4 kg m^2"},
        origin="test")
    ref = simulate(build_wrist(overridden).assemble(), {"tau_x": Constant(0.3)}, 0.8,
                   initial=InitialState(q=Q0),
                   options=SimulationOptions(friction="stiction", step=H, output_step=H))
    default = simulate(build_wrist(params.default()).assemble(), {"tau_x": Constant(0.3)}, 0.8,
                       initial=InitialState(q=Q0),
                       options=SimulationOptions(friction="stiction", step=H, output_step=H))
    allowed = same_engine(ref.solver["steps"], frictions(), np.ptp(ref["theta_x"]),
                          abs(theta))
    assert abs(theta - ref["theta_x"][-1]) <= allowed
    assert abs(theta - default["theta_x"][-1]) > 1e-4


def test_get_set_and_serialized_state_repeat_a_step_bit_for_bit(wrist_fmu, unzipped):
    path, _ = wrist_fmu
    s = Slave(path, unzipped)
    u = {"motor_1": 2.0, "motor_2": -1.0, "tau_y": 0.1}
    s.step(u, 200)
    saved = s.fmu.getFMUstate()
    blob = s.fmu.serializeFMUstate(saved)
    s.step(u, 150)
    first = s.get("theta_x", "theta_y", "deflection_1", "power_dissipated")
    s.fmu.setFMUstate(saved)
    s.t = 0.2
    s.step(u, 150)
    again = s.get("theta_x", "theta_y", "deflection_1", "power_dissipated")
    restored = s.fmu.deSerializeFMUstate(blob)
    s.fmu.setFMUstate(restored)
    s.t = 0.2
    s.step(u, 150)
    thawed = s.get("theta_x", "theta_y", "deflection_1", "power_dissipated")
    s.fmu.freeFMUstate(saved)
    s.fmu.freeFMUstate(restored)
    s.close()
    assert np.array_equal(first, again) and np.array_equal(first, thawed)
    assert first[3] > 0.0  # friction dissipates while the motors drive


def test_a_state_carries_the_power_outputs_of_its_last_step(wrist_fmu, unzipped):
    """The power outputs are worked out from the last step's ledger when they are read;
    a state taken before they were ever read carries them all the same, and so does its
    serialized form, and a restored instance reports them until it steps again."""
    path, _ = wrist_fmu
    s = Slave(path, unzipped)
    u = {"motor_1": 2.0, "motor_2": -1.0, "tau_y": 0.1}
    s.step(u, 200)
    saved = s.fmu.getFMUstate()  # the powers not read yet
    blob = s.fmu.serializeFMUstate(saved)
    expected = s.get("power_in", "power_dissipated")
    s.step({"motor_1": -3.0}, 20)
    moved_on = s.get("power_in", "power_dissipated")
    s.fmu.setFMUstate(saved)
    restored = s.get("power_in", "power_dissipated")
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(blob))
    thawed = s.get("power_in", "power_dissipated")
    s.fmu.freeFMUstate(saved)
    s.close()
    assert expected[1] > 0.0  # friction dissipates while the motors drive
    assert not np.array_equal(moved_on, expected)  # the later steps' powers differ
    assert np.array_equal(restored, expected) and np.array_equal(thawed, expected)


def test_a_state_taken_while_stuck_repeats_the_breakaway_bit_for_bit(wrist_fmu, unzipped):
    """The state round trip across a stick-to-slip transition: saved while true
    stiction holds the wrist, restored after it broke away; the steps that follow
    repeat, with every element's stick/slip decision, to the last bit."""
    path, _ = wrist_fmu
    s = Slave(path, unzipped)
    names = ("theta_x", "theta_y", "deflection_1", "deflection_2", "power_dissipated")

    def stuck():
        return s.fmu.getInteger([s.vr["n_stuck"]])[0]

    s.step({"tau_x": 0.02}, 300)  # below breakaway: the wrist holds
    held = stuck()
    assert held > 0
    saved = s.fmu.getFMUstate()
    blob = s.fmu.serializeFMUstate(saved)
    t_saved = s.t

    def breakaway():
        rows = []
        for k in range(200):  # a torque that breaks it loose, then a reversal
            s.step({"tau_x": 0.6 if k < 100 else -0.6})
            rows.append([*s.get(*names), stuck()])
        return np.array(rows)

    first = breakaway()
    assert first[:, -1].min() < held  # elements slipped free after the save
    assert np.ptp(first[:, 0]) > 1e-3  # and the wrist moved
    s.fmu.setFMUstate(saved)
    s.t = t_saved
    again = breakaway()
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(blob))
    s.t = t_saved
    thawed = breakaway()
    s.fmu.freeFMUstate(saved)
    s.close()
    assert np.array_equal(first, again) and np.array_equal(first, thawed)


def test_a_state_carries_pivot_q0_and_the_stop_time(wrist_fmu, unzipped):
    """An FMU state keeps what the experiment it was taken in set: pivot_q0 (the next
    initialization's pivot position) and the stop time. Taken before initialization at
    one q0 and given back after another was set, it initializes at its own; taken in an
    experiment that runs to 1 s and given back in one set up to stop at 0.05 s, it steps
    past 0.05 s. Both through fmi2SetFMUstate and through its serialized bytes."""
    path, _ = wrist_fmu
    s = Slave(path, unzipped, name="q0", initialize=False)
    q_a, q_b = -0.012, 0.004
    # a state is the instance as it stands, even with q0 outside a pivot range set since
    # (fmi2ExitInitializationMode checks q0 against the range, where it is used)
    s.fmu.setReal([s.vr["pivot.q_min"]], [0.0])
    outside = s.fmu.getFMUstate()
    s.fmu.setFMUstate(outside)
    s.fmu.freeFMUstate(outside)
    s.fmu.reset()
    s.fmu.setReal([s.vr["pivot_q0"]], [q_a])
    before = s.fmu.getFMUstate()  # not initialized yet: q_a is what it starts from
    frozen = s.fmu.deSerializeFMUstate(s.fmu.serializeFMUstate(before))
    for state in (before, frozen):
        s.fmu.setReal([s.vr["pivot_q0"]], [q_b])
        s.fmu.setFMUstate(state)
        assert s.get("pivot_q0")[0] == q_a
        s.fmu.setupExperiment(startTime=0.0, stopTime=1.0)
        s.start(setup=False)
        assert abs(s.get("q")[0] - q_a) <= Q_ROUND_TRIP
        s.fmu.reset()
    s.fmu.setupExperiment(startTime=0.0, stopTime=1.0)
    s.start(setup=False)
    s.step({"tau_x": 0.1}, 20)
    running = s.fmu.getFMUstate()
    frozen_running = s.fmu.deSerializeFMUstate(s.fmu.serializeFMUstate(running))
    for state in (running, frozen_running):
        s.fmu.reset()
        s.fmu.setupExperiment(startTime=0.0, stopTime=0.05)
        s.start(setup=False)
        with pytest.raises(FMICallException):  # this experiment's stop time holds here
            s.step({"tau_x": 0.1}, 60)
        s.fmu.setFMUstate(state)
        s.t = 20 * H
        s.step({"tau_x": 0.1}, 60)  # to 0.08 s: the state's experiment runs to 1 s
        assert s.t > 0.05
    for state in (before, frozen, running, frozen_running):
        s.fmu.freeFMUstate(state)
    s.close()


def test_a_state_of_an_experiment_without_a_stop_time_reads_back(wrist_fmu, unzipped):
    """An importer may pass an undefined stop time as infinity or NaN; the state of such
    an experiment serializes and reads back."""
    path, _ = wrist_fmu
    s = Slave(path, unzipped, name="open", initialize=False)
    for undefined in (float("inf"), float("nan")):
        s.fmu.fmi2SetupExperiment(s.fmu.component, fmi2False, 0.0, 0.0, fmi2False, undefined)
        s.start(setup=False)
        s.step({"tau_x": 0.1}, 3)
        state = s.fmu.getFMUstate()
        thawed = s.fmu.deSerializeFMUstate(s.fmu.serializeFMUstate(state))
        s.fmu.setFMUstate(thawed)
        s.step({"tau_x": 0.1}, 3)  # and steps on, with no stop time
        for st in (state, thawed):
            s.fmu.freeFMUstate(st)
        s.fmu.reset()
    s.fmu.freeInstance()


def test_a_state_taken_after_a_failed_step_serializes_and_reads_back(wrist_fmu, unzipped):
    """A step that overflows the model fails and leaves the state as it was; a state
    taken then (the instance in its error state) serializes and reads back, and holds
    the last good step's values. Before, the failed step's non-finite numbers stayed in
    the time-stepper's history, and the bytes were refused as holding them."""
    path, _ = wrist_fmu
    s = Slave(path, unzipped)
    names = ("theta_x", "theta_y", "deflection_1", "q")
    s.step({"tau_x": 0.1}, 5)
    good = s.get(*names)
    s.fmu.setReal([s.vr["tau_x"]], [1e306])
    with pytest.raises(FMICallException):
        s.fmu.doStep(s.t, H)
    failed = s.fmu.getFMUstate()
    thawed = s.fmu.deSerializeFMUstate(s.fmu.serializeFMUstate(failed))
    s.fmu.setFMUstate(thawed)
    assert np.array_equal(s.get(*names), good)
    for state in (failed, thawed):
        s.fmu.freeFMUstate(state)
    s.fmu.reset()
    s.fmu.freeInstance()


def test_debug_logging_follows_the_categories_asked_for(wrist_fmu, unzipped):
    """fmi2SetDebugLogging's categories: the model description's three, logAll for
    every message; an unknown one is refused and changes nothing. Information (the
    ledger's closing at fmi2Terminate) reaches the logger only under logAll; a warning
    and an error reach it whatever is asked, logging off included (FMI 2.0 has the
    logger called for the status they explain)."""
    path, _ = wrist_fmu
    md = read_model_description(str(path))
    assert [c.name for c in md.logCategories] == ["logStatusError", "logStatusWarning",
                                                  "logAll"]
    vr = refs(path)
    slave, messages = logged_instance(path, unzipped)

    def run(tau_x=0.0, steps=1):
        """The ledger's and the springs' messages of a short run (``steps`` steps under
        ``tau_x``) that ends with fmi2Terminate, then a reset."""
        del messages[:]
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        slave.setReal([vr["tau_x"]], [tau_x])
        for k in range(steps):
            slave.fmi2DoStep(slave.component, k * H, H, fmi2True)  # fmi2Warning: no raise
        slave.terminate()
        slave.reset()
        return [text for text in messages if "ledger" in text or "spring" in text]

    assert run()  # logging on from fmi2Instantiate: every category
    slave.setDebugLogging(True, ["logStatusError"])
    assert run() == []  # information is logAll's
    del messages[:]
    with pytest.raises(FMICallException):
        slave.setDebugLogging(True, ["logEvents"])  # not one of this FMU's
    assert any("logEvents" in text and "logAll" in text for text in messages)
    assert run() == []  # the refused call left the categories as they were
    slave.setDebugLogging(True, ["logStatusWarning", "logAll"])
    assert run()
    slave.setDebugLogging(True, [])  # none named: all
    assert run()
    slave.setDebugLogging(False, [])
    assert run() == []
    # 100 N m drives a spring past its end stop within 0.1 s: a warning, said logging off
    assert any("spring" in text for text in run(tau_x=100.0, steps=100))
    del messages[:]
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        slave.setReal([vr["transmission.stiction"]], [-1.0])
    assert any("outside its range" in text for text in messages)  # logging off: errors too
    slave.exitInitializationMode()
    slave.terminate()
    slave.freeInstance()


def logged_instance(path, unzipped):
    """An instance of the FMU at ``path`` with logging on: ``(slave, messages)``, the
    messages its logger receives collected in the list."""
    messages = []
    md = read_model_description(str(path))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="vsj_wrist",
                      instanceName="bad")
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(
        lambda env, name, status, category, text: messages.append(text.decode()))
    slave.instantiate(callbacks=callbacks, loggingOn=True)
    return slave, messages


def test_bad_calls_are_errors_with_a_logged_reason(wrist_fmu, unzipped):
    path, _ = wrist_fmu
    vr = refs(path)
    slave, messages = logged_instance(path, unzipped)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    with pytest.raises(FMICallException):
        slave.setReal([vr["transmission.stiction"]], [-1.0])
    with pytest.raises(FMICallException):
        slave.setReal([vr["pivot_q0"]], [1.0])
    slave.exitInitializationMode()
    with pytest.raises(FMICallException):
        slave.setReal([vr["tau_x"]], [float("nan")])
    with pytest.raises(FMICallException):
        slave.doStep(0.5, H)  # not the FMU's time
    slave.doStep(0.0, H)
    slave.terminate()
    slave.freeInstance()
    text = " ".join(messages)
    assert "outside its range" in text and "not finite" in text
    assert "communication point" in text


# -- the same scenario through FMPy and through vsj simulate ---------------------------------

def held_table(names, times, commands):
    """FMPy's input for commands held from times[k] to times[k + 1], communication points
    ``times`` a step apart: one row per point. FMPy sets the inputs at the start of each
    communication step, at the very time of a row (its interpolation weights there are 0
    and 1: the row's values exactly), and the FMU holds them over the step. (FMPy's mark
    of a jump, two rows at the same time, would make it scan its list of input events
    from the start at every step, a cost quadratic in the steps.)"""
    rows = [(times[k], *commands[k]) for k in range(len(times) - 1)]
    rows.append((times[-1], *commands[-1]))
    return np.array(rows, dtype=[("time", float)] + [(n, float) for n in names])


def worst_of_range(out, ref, names, every=1):
    """The largest deviation of each FMU output from `simulate`, as a fraction of the
    signal's range (a floor of 1e-9 for a constant signal such as q)."""
    worst = {}
    for name in names:
        mine, theirs = out[name][::every], ref[SIGNALS[name]]
        assert mine.shape == theirs.shape, name
        worst[name] = float(np.max(np.abs(mine - theirs)) / max(np.ptp(theirs), 1e-9))
    return worst


def test_hold_input_holds_each_value_until_the_next_time():
    hold = Hold((0.0, 0.5, 1.0), (1.0, -2.0, 3.0))
    assert list(hold.value([0.0, 0.25, 0.5, 0.75, 1.0, 2.0])) == [1.0, 1.0, 1.0, -2.0, -2.0, 3.0]
    knots, coef = hold.pieces(1.5)
    assert np.array_equal(coef[:, 0], [1.0, -2.0, 3.0]) and not coef[:, 1:].any()
    # each change just after its time: a step ending there still sees the old value
    assert 0.5 < knots[1] < 0.5 + 1e-6 and 1.0 < knots[2] < 1.0 + 1e-6 and knots[-1] == 1.5


@pytest.mark.parametrize("method", ["dopri", "rosenbrock"])
def test_fig_4_15_with_smooth_friction_matches_vsj_simulate(tmp_path, method):
    """The velocity-driven fig-4.15 motion (arctan friction, either adaptive scheme in
    the FMU, dopri in vsj simulate): the FMU gets the mean speed of the scenario's
    motor angles over each 0.25 ms communication step."""
    scen = scenario.load("fig-4.15")
    case = scen.cases[1]  # q = -1 cm
    wrist_options = WristOptions(**scen.table["model"])
    motion = scenario.parse_inputs(case, case.build(params.default()))
    h, duration = 2.5e-4, 2.5
    path = tmp_path / "smooth.fmu"
    info = fmu.build(path, params.default(), wrist_options=wrist_options,
                     friction=case.options.friction, step=H, q0=case.initial.q, win64=False,
                     method=method)
    assert info["method"] == method
    t = np.arange(int(round(duration / h)) + 1) * h
    names = ["motor_1", "motor_2", "motor_s", "tau_x", "tau_y"]
    commands = np.zeros((len(t) - 1, len(names)))
    for j, name in enumerate(("motor_1", "motor_2")):
        commands[:, j] = np.diff(motion[name].value(t)) / h
    commands[:, 4] = 0.05
    # the motor speeds are the held commands themselves, O(h) off the smooth ones
    outputs = [n for n in SIGNALS if n != "q" and not n.endswith("_speed")]
    out = simulate_fmu(str(path), stop_time=duration, step_size=h, output_interval=h,
                       input=held_table(names, t, commands), output=outputs + ["q"])
    options = SimulationOptions(friction=case.options.friction, output_step=H)
    ref = simulate(build_wrist(params.default(), wrist_options).assemble(),
                   {**motion, "tau_y": Constant(0.05)}, duration, initial=case.initial,
                   options=options)
    assert ref.success and ref.solver["name"] == "dopri"
    worst = worst_of_range(out, ref, outputs, every=int(round(H / h)))
    assert max(worst.values()) <= OF_RANGE, worst
    # the numerics: the held speeds put each motor angle at most h^2 / 8 x its largest
    # acceleration off the smooth one between communication points (equal at them), a
    # slowly varying offset that reaches every output through kinematic gains below 1;
    # both runs add their scheme's global error, rtol of the signal's size plus atol
    # (proportional to rtol with a constant below 1, test_convergence.py; the FMU runs
    # with the same default tolerances)
    fine = np.linspace(0.0, duration, 20001)
    acceleration = max(np.max(np.abs(np.gradient(np.gradient(motion[m].value(fine), fine),
                                                 fine)[2:-2])) for m in ("motor_1", "motor_2"))
    for name in outputs:
        size = np.max(np.abs(ref[SIGNALS[name]]))
        allowed = h * h / 8 * acceleration + 2 * (options.rtol * size + options.atol)
        assert worst[name] * max(np.ptp(ref[SIGNALS[name]]), 1e-9) <= allowed, name
    assert np.ptp(ref["theta_x"]) > 0.5  # the circle was drawn
    assert np.all(np.abs(out["q"] - case.initial.q) <= Q_ROUND_TRIP)


def test_fig_4_15_circle_with_stiction_on_dc_motors_matches_vsj_simulate(tmp_path):
    """The fig-4.15 circle (0.5 Hz, phases +-45 degrees, 2 s fade-in) driven through
    DC motors by held voltages, with true stiction: identical inputs in both."""
    h, duration, q0 = 2.5e-4, 2.0, -0.01
    wrist_options = WristOptions(elastic="exponential", motors="dc")
    path = tmp_path / "dc.fmu"
    fmu.build(path, params.default(), wrist_options=wrist_options, friction="stiction",
              step=h, q0=q0, win64=False)
    names = [v.name for v in read_model_description(str(path)).modelVariables
             if v.causality == "input"]
    assert {"voltage_1", "voltage_2"} <= set(names)
    n = int(round(duration / h))
    t = np.arange(n + 1) * h
    commands = fmu.cross_check_commands(names, h, n)
    commands[:, names.index("tau_y")] = 0.05
    out = simulate_fmu(str(path), stop_time=duration, step_size=h, output_interval=h,
                       input=held_table(names, t, commands),
                       output=list(SIGNALS) + ["n_stuck"])
    held = {name: Hold(tuple(t[:-1]), tuple(commands[:, j])) for j, name in enumerate(names)}
    ref = simulate(build_wrist(params.default(), wrist_options).assemble(), held, duration,
                   initial=InitialState(q=q0),
                   options=SimulationOptions(friction="stiction", step=h, output_step=h))
    assert ref.success and ref.solver["name"] == "timestep"
    worst = worst_of_range(out, ref, list(SIGNALS))
    assert max(worst.values()) <= OF_RANGE, worst
    # the same time-stepper on identical inputs in two builds of the engine
    elements = frictions(wrist_options)
    for name in SIGNALS:
        span = max(np.ptp(ref[SIGNALS[name]]), 1e-9)
        allowed = same_engine(ref.solver["steps"], elements, span,
                              np.max(np.abs(ref[SIGNALS[name]])))
        assert worst[name] * span <= allowed, name
    assert np.ptp(ref["theta_x"]) > 0.3 and np.max(out["n_stuck"]) > 0


# -- the cross-check folder -------------------------------------------------------------------

@pytest.fixture(scope="module")
def cross_check_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("xc")
    info = fmu.cross_check(root, params.default(), friction="stiction", step=H, q0=Q0)
    return root, info


def fmpy_cross_check_run(folder):
    """What FMPy's cross-check (``python -m fmpy.cross_check --simulate``) does with a
    folder: the FMU with its input file, at the options' step, to the stop time."""
    from fmpy.util import read_csv, read_ref_opt_file

    name = folder.name
    options = read_ref_opt_file(str(folder / f"{name}_ref.opt"))
    reference = read_csv(str(folder / f"{name}_ref.csv"))
    result = simulate_fmu(str(folder / f"{name}.fmu"), validate=False,
                          step_size=options["StepSize"], stop_time=options["StopTime"],
                          input=read_csv(str(folder / f"{name}_in.csv")),
                          output=list(reference.dtype.names[1:]))
    return options, reference, result


def test_cross_check_folder_passes_fmpy_validation(cross_check_dir):
    from fmpy.cross_check import validate_result
    from fmpy.cross_check.validate_vendor_repo import validate_repo

    root, info = cross_check_dir
    platforms = info["platforms"]
    assert validate_repo(str(root)) == (len(platforms), 0, [])
    folder = root / "fmus" / "2.0" / "cs" / "linux64" / "vsj" / fmu.__version__ / "vsj_wrist"
    assert sorted(p.name for p in folder.iterdir()) == [
        "README.md", "vsj_wrist.fmu", "vsj_wrist_in.csv", "vsj_wrist_ref.csv",
        "vsj_wrist_ref.opt"]
    options, reference, result = fmpy_cross_check_run(folder)
    assert options["StopTime"] == fmu.CROSS_CHECK_DURATION
    assert validate_result(result=result, reference=reference, t_start=options["StartTime"],
                           t_stop=options["StopTime"]) is None
    # far inside FMPy's band (10 % of the range): the same numbers, at each reference time
    # (FMPy's time is a sum of steps, rounded once per step)
    at = np.searchsorted(result["time"], reference["time"] + 1e-9, side="right") - 1
    steps = int(round(options["StopTime"] / options["StepSize"]))
    np.testing.assert_allclose(result["time"][at], reference["time"], rtol=0,
                               atol=steps * EPS * options["StopTime"])
    # the reference is vsj's own step function on the same held inputs: two builds of
    # the engine (the FMU's time-stepper at H, period by period)
    engine_steps = int(round(options["StopTime"] / H))
    for name in reference.dtype.names[1:]:
        span = max(np.ptp(reference[name]), 1e-9)
        allowed = same_engine(engine_steps, frictions(), span, np.max(np.abs(reference[name])))
        assert allowed <= OF_RANGE * span  # within the acceptance
        assert np.max(np.abs(result[name][at] - reference[name])) <= allowed, name
    assert np.ptp(reference["theta_x"]) > 0.5
    # the importer's side of the cross-check: a result folder, validated by FMPy as well
    import fmpy

    out = (root / "results" / "2.0" / "cs" / "linux64" / "FMPy" / fmpy.__version__ / "vsj"
           / fmu.__version__ / "vsj_wrist")
    out.mkdir(parents=True)
    (out / "passed").write_text("")
    header = ",".join(f'"{n}"' for n in result.dtype.names)
    np.savetxt(out / "vsj_wrist_out.csv", result, delimiter=",", header=header, comments="",
               fmt="%.17g")
    assert validate_repo(str(root)) == (len(platforms), 1, [])
    # and the check can fail: a reference that is off is caught
    wrong = reference.copy()
    wrong["theta_x"] = 2 * wrong["theta_x"] + 0.1
    assert validate_result(result=result, reference=wrong, t_start=options["StartTime"],
                           t_stop=options["StopTime"]) is not None


@pytest.mark.skipif(fmu.compiler("win64") is None,
                    reason="x86_64-w64-mingw32-gcc is not installed (Debian: apt-get install "
                           "gcc-mingw-w64-x86-64): no win64 DLL to check")
def test_win64_dll_exports_every_fmi2_function_and_builds_warning_free(cross_check_dir,
                                                                        tmp_path):
    import zipfile

    root, info = cross_check_dir
    assert "win64" in info["platforms"]
    assert info["warnings"] == {}  # -Wall -Wextra, linux64 and mingw-w64 alike
    folder = root / "fmus" / "2.0" / "cs" / "win64" / "vsj" / fmu.__version__ / "vsj_wrist"
    with zipfile.ZipFile(folder / "vsj_wrist.fmu") as archive:
        archive.extract("binaries/win64/vsj_wrist.dll", tmp_path)
    dll = tmp_path / "binaries" / "win64" / "vsj_wrist.dll"
    objdump = shutil.which("x86_64-w64-mingw32-objdump") or "objdump"
    text = subprocess.run([objdump, "-p", str(dll)], capture_output=True, text=True,
                          check=True).stdout
    assert "pei-x86-64" in text
    title = "[Ordinal/Name Pointer] Table"
    table = text[text.index(title) + len(title):].split("\n\n")[0]
    exported = set(re.findall(r"\[\s*\d+\]\s+(\w+)", table))
    header = (Path(fmu.__file__).parent / "fmi" / "fmi2.h").read_text()
    declared = set(re.findall(r"FMI2_EXPORT [^;]*?\b(fmi2\w+)\(", header))
    assert len(declared) == 44 and declared <= exported
    assert exported == declared  # the engine's own functions stay inside
    imported = set(re.findall(r"DLL Name: (\S+)", text))
    assert imported <= {"KERNEL32.dll", "msvcrt.dll"}  # nothing an importer lacks


class _Compiled(Exception):
    """Raised in place of compiling: the test wanted to know whether it would."""


def _would_compile(*args):
    raise _Compiled


def test_another_process_reuses_a_compiled_binary_and_never_a_damaged_one(
        tmp_path, monkeypatch, wrist_fmu_file):
    """`fmu.compile_binary` keeps what it compiles in `fmu.cache_dir` (this session's:
    conftest's ``VSJ_CACHE``), so that another process builds an FMU without the
    compiler: a process with an empty memory gets the very binary this session's FMU
    carries. An entry whose binary (one bit) or record (the compiler's words, the file
    mode, the record's shape) was damaged is compiled anew, never used; and a compile
    that failed is not remembered as if it had succeeded."""
    path, _ = wrist_fmu_file()  # this session has compiled the binary: it is in the cache
    with zipfile.ZipFile(path) as archive:
        carried = archive.read(f"binaries/linux64/{fmu.MODEL_IDENTIFIER}.so")
    cache = tmp_path / "cache"
    shutil.copytree(fmu.cache_dir().parent, cache)
    monkeypatch.setenv("VSJ_CACHE", str(cache))
    monkeypatch.setattr(fmu, "_compile", _would_compile)
    monkeypatch.setattr(fmu, "_COMPILED", {})  # as a fresh process
    out = tmp_path / "binary.so"
    assert fmu.compile_binary("linux64", out) == ""  # what the compiler said: nothing
    assert out.read_bytes() == carried
    [record] = [p for p in (cache / "fmu").glob("*.json")
                if json.loads(p.read_text())["key"].startswith("('linux64'")]
    binary = record.with_suffix(".bin")
    damaged = bytearray(carried)
    damaged[len(damaged) // 2] ^= 1
    binary.write_bytes(bytes(damaged))
    monkeypatch.setattr(fmu, "_COMPILED", {})
    with pytest.raises(_Compiled):
        fmu.compile_binary("linux64", out)
    binary.write_bytes(carried)
    meta = json.loads(record.read_text())
    for damaged_record in ({**meta, "said": "warning: made up"}, {**meta, "mode": 0o6755},
                           {**meta, "mode": "755"}, [meta]):
        record.write_text(json.dumps(damaged_record))
        monkeypatch.setattr(fmu, "_COMPILED", {})
        with pytest.raises(_Compiled):
            fmu.compile_binary("linux64", out)
    record.write_text(json.dumps(meta))
    monkeypatch.setenv("VSJ_CACHE", str(tmp_path / "empty"))  # nothing kept: it compiles,
    monkeypatch.setattr(fmu, "_COMPILED", {})
    with pytest.raises(_Compiled):  # and the compile fails
        fmu.compile_binary("linux64", out)
    monkeypatch.setenv("VSJ_CACHE", str(cache))
    assert fmu.compile_binary("linux64", out) == "" and out.read_bytes() == carried


def test_the_binary_is_compiled_once_per_process_for_the_same_files(tmp_path):
    """`fmu.compile_binary` keeps what it compiled (`fmu._COMPILED`): a second build of this
    process gets the same bytes, file mode and compiler's words; the key digests every
    file the binary is compiled from, so an edited source or header is compiled anew."""
    first, second = tmp_path / "first.so", tmp_path / "second.so"
    said = fmu.compile_binary("linux64", first)
    assert fmu.compile_binary("linux64", second) == said
    assert first.read_bytes() == second.read_bytes()
    assert first.stat().st_mode == second.stat().st_mode
    assert [key[0] for key in fmu._COMPILED].count("linux64") == 1  # one compile, kept
    copies = []
    for path in fmu._source_paths():
        copies.append(tmp_path / "sources" / path.name)
        copies[-1].parent.mkdir(exist_ok=True)
        shutil.copy(path, copies[-1])
    digest = fmu._sources_digest(copies)
    for edited in (next(p for p in copies if p.suffix == ".h"),
                   next(p for p in copies if p.suffix == ".c")):
        original = edited.read_bytes()
        edited.write_bytes(original + b"\n")
        assert fmu._sources_digest(copies) != digest, edited.name
        edited.write_bytes(original)
    assert fmu._sources_digest(copies) == digest


def test_each_source_is_compiled_apart_and_every_warning_or_failure_is_reported(tmp_path):
    """`fmu._compile` compiles the sources side by side, one object each, then links
    them: the linked binary exports what both sources define, every source's warnings
    reach what the compiler said, and a failing compile or link raises `InputError` with
    the compiler's words (the first failure), leaving no binary behind."""
    cc = fmu.compiler("linux64")
    flags = ["-std=c99", "-O2", "-Wall", "-Wextra", "-fPIC"]
    link = ["-shared"]
    one, two = tmp_path / "one.c", tmp_path / "two.c"
    one.write_text("int vsj_test_one(void) { return 1; }\n")
    two.write_text("int vsj_test_two(int a) { int unused_here; return a + 1; }\n")
    out = tmp_path / "both.so"
    binary, mode, said = fmu._compile(cc, flags, link, [str(one), str(two)], "linux64", out)
    symbols = subprocess.run(["nm", "-D", "--defined-only", str(out)], capture_output=True,
                             text=True, check=True).stdout
    assert "vsj_test_one" in symbols and "vsj_test_two" in symbols
    assert binary == out.read_bytes() and mode & 0o100  # executable by its owner
    assert "unused_here" in said and "two.c" in said and "one.c" not in said
    broken = tmp_path / "broken.c"
    broken.write_text("int vsj_test_broken(void) { return missing_name; }\n")
    for sources, extra, words in (([one, broken], [], "missing_name"),
                                  ([one], ["-lvsj-no-such-library"], "vsj-no-such-library")):
        target = tmp_path / f"failed-{len(extra)}.so"
        with pytest.raises(InputError, match=words) as failed:
            fmu._compile(cc, flags, link + extra, [str(s) for s in sources], "linux64", target)
        assert "building the linux64 binary failed" in str(failed.value)
        assert not target.exists()


def test_the_tolerances_given_to_vsj_fmu_are_the_ones_its_model_integrates_to(tmp_path,
                                                                               capsys):
    """``vsj fmu --rtol --atol`` reach the scheme settings of the model the FMU carries
    (resources/model.vsjm, whose header `vsj.export.program_bytes` writes); left out,
    they are the simulator's defaults; out of range, the command refuses them."""
    def settings(path):
        with zipfile.ZipFile(path) as archive:
            blob = archive.read("resources/model.vsjm")
        assert blob[:4] == b"VSJP"
        _, _, rtol, atol, _, _ = struct.unpack_from("<qddddq", blob, 16)
        return rtol, atol

    tight, default = tmp_path / "tight.fmu", tmp_path / "default.fmu"
    common = ["--friction", "arctan", "--method", "dopri", "--win64", "no"]
    assert main(["fmu", "--out", str(tight), *common, "--rtol", "1e-9", "--atol", "1e-11"]) == 0
    assert main(["fmu", "--out", str(default), *common]) == 0
    assert settings(tight) == (1e-9, 1e-11)
    assert settings(default) == (SimulationOptions().rtol, SimulationOptions().atol)
    capsys.readouterr()
    assert main(["fmu", "--out", str(tmp_path / "bad.fmu"), *common, "--rtol", "0.5"]) == 2
    assert "rtol" in capsys.readouterr().err
    assert not (tmp_path / "bad.fmu").exists()


def circle(slave, steps):
    """``theta_x``, ``theta_y`` of ``slave`` after each of ``steps`` communication steps
    of the fig-4.15-like circle (motor speeds 3 rad/s at 0.5 Hz, 90 degrees apart)."""
    out = []
    for k in range(steps):
        t = k * H
        slave.step({"motor_1": 3.0 * np.sin(np.pi * t), "motor_2": 3.0 * np.cos(np.pi * t),
                    "tau_y": 0.05})
        out.append(slave.get("theta_x", "theta_y"))
    return np.array(out)


def test_an_importers_tolerance_drives_the_adaptive_schemes(tmp_path, wrist_fmu, unzipped):
    """The relative tolerance an importer passes to fmi2SetupExperiment replaces the model
    file's rtol (atol scaled alike) for the run it sets up: the model file's own value
    gives the run without one bit for bit, a looser one a less accurate run. fmi2Reset
    returns to the model file's (set up again or not), an FMU state carries the
    tolerance it was taken at, and one outside vsj's range is an error with its reason.
    The time-stepper's fixed step has no tolerance: it takes any and ignores it."""
    own = SimulationOptions().rtol
    path = tmp_path / "dopri.fmu"
    fmu.build(path, params.default(), friction="arctan", method="dopri", step=H, q0=Q0,
              win64=False)
    assert float(read_model_description(str(path)).defaultExperiment.tolerance) == own
    directory = extract(str(path))
    runs = {}
    for tolerance in (None, own, 1e-3, 1e-10):
        slave = Slave(path, directory, tolerance=tolerance)
        runs[tolerance] = circle(slave, 400)
        if tolerance == 1e-3:  # the same instance reset, initialised without a set-up
            slave.fmu.reset()
            slave.start(setup=False)
            runs["reset, not set up"] = circle(slave, 400)
            slave.fmu.reset()  # reset, set up with it and again without: the last counts
            slave.fmu.setupExperiment(tolerance=1e-3, startTime=0.0)
            slave.start()
            runs["set up again"] = circle(slave, 400)
        slave.close()
    for again in (own, "reset, not set up", "set up again"):
        assert np.array_equal(runs[None], runs[again]), again
    # against the run at 1e-10: the looser tolerance, the larger the error
    error = {k: np.max(np.abs(runs[k] - runs[1e-10])) for k in (own, 1e-3)}
    assert 0.0 < error[own] < error[1e-3]
    # a state taken at 1e-3, serialized, set into an instance set up without a tolerance
    loose, other = Slave(path, directory, tolerance=1e-3), Slave(path, directory, "other")
    circle(loose, 200)
    blob = loose.fmu.serializeFMUstate(loose.fmu.getFMUstate())
    other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(blob))
    other.t = loose.t
    assert np.array_equal(circle(other, 200), circle(loose, 200))
    loose.close()
    other.close()

    bad, messages = logged_instance(path, directory)
    for tolerance in (0.5, 0.0, float("nan")):
        with pytest.raises(FMICallException):
            bad.setupExperiment(tolerance=tolerance, startTime=0.0)
    bad.freeInstance()
    shutil.rmtree(directory, ignore_errors=True)
    assert sum("the tolerance (relative) must be from 1e-14 to 1e-2" in m
               for m in messages) == 3

    stiction, _ = wrist_fmu  # the time-stepper's FMU
    assert read_model_description(str(stiction)).defaultExperiment.tolerance is None
    fixed = []
    for tolerance in (None, 1e-3, 0.5):
        slave = Slave(stiction, unzipped, tolerance=tolerance)
        fixed.append(circle(slave, 200))
        slave.close()
    assert np.array_equal(fixed[0], fixed[1]) and np.array_equal(fixed[0], fixed[2])

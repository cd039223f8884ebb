"""The wrist FMU (`vsj.fmu`), imported by FMPy as a 20-sim or Simulink user's tool would.

FMPy is the independent importer: it validates the FMU, loads its binary and
calls the FMI 2.0 functions. The FMU's results are compared with vsj's own
`simulate` (constant inputs, which the FMU holds over a communication step
exactly as `simulate` applies them) and with the step function (`vsj.stepper`,
the same held inputs) for time-varying commands.
"""

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE
from fmpy.validation import validate_fmu

from vsj import fmu, params
from vsj.inputs import Constant
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import build_wrist

H = 1e-3
Q0 = -0.01
#: FMU against vsj's own engine: the same C code on the same inputs
SAME = 1e-9


@pytest.fixture(scope="module")
def wrist_fmu(tmp_path_factory):
    path = tmp_path_factory.mktemp("fmu") / "wrist.fmu"
    info = fmu.build(path, params.default(), friction="stiction", step=H, q0=Q0, win64=False)
    return path, info


def refs(path):
    return {v.name: v.valueReference for v in read_model_description(str(path)).modelVariables}


def held_inputs(tau_x, duration):
    names = ["motor_1", "motor_2", "motor_s", "tau_x", "tau_y"]
    rows = [(0.0, 0, 0, 0, tau_x, 0), (duration, 0, 0, 0, tau_x, 0)]
    return np.array(rows, dtype=[("time", float)] + [(n, float) for n in names])


class Slave:
    """One FMPy instance of the FMU, stepped by hand."""

    def __init__(self, path, unzipped, name="wrist", start=None):
        md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
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
    assert not any(s.startswith("vsj_") for s in re.findall(r" T (\w+)", symbols))
    md = read_model_description(str(path))
    variables = {v.name: v for v in md.modelVariables}
    assert variables["transmission.stiction"].causality == "parameter"
    assert variables["transmission.stiction"].variability == "tunable"
    assert variables["transmission.stiction"].unit == "N.m"
    assert variables["theta_x"].causality == "output" and variables["theta_x"].unit == "rad"
    assert variables["pivot_q0"].start == str(Q0) or float(variables["pivot_q0"].start) == Q0
    assert {"planetary.sun_teeth", "transmission.ratio"} <= set(info["constant"])
    for name in ("sources/vsj_fmu.c", "sources/timestep.c", "sources/buildDescription.xml",
                 "resources/model.json", "resources/fmu.txt", "modelDescription.xml"):
        assert (Path(unzipped) / name).is_file(), name


def test_a_held_wrist_under_a_torque_matches_vsj_simulate_and_does_not_drift(wrist_fmu):
    path, _ = wrist_fmu
    out = simulate_fmu(str(path), stop_time=2.0, step_size=H, output_interval=H,
                       input=held_inputs(0.3, 2.0),
                       output=["theta_x", "theta_y", "q", "n_stuck", "deflection_1"])
    structure = build_wrist(params.default()).assemble()
    ref = simulate(structure, {"tau_x": Constant(0.3)}, 2.0, initial=InitialState(q=Q0),
                   options=SimulationOptions(friction="stiction", step=H, output_step=H))
    assert ref.success
    for name in ("theta_x", "theta_y"):
        span = max(np.ptp(ref[name]), 1e-3)
        assert np.max(np.abs(out[name] - ref[name])) <= 1e-6 * span, name
    assert np.allclose(out["q"], Q0, atol=1e-12)
    settled = out["time"] >= 1.0
    assert np.ptp(out["theta_x"][settled]) == 0.0  # held by true stiction: no creep at all
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
    worst = 0.0
    for k in range(1500):
        t = k * H
        u = {"motor_1": 3.0 * np.sin(2 * np.pi * 0.5 * t),
             "motor_2": 3.0 * np.cos(2 * np.pi * 0.5 * t), "motor_s": 0.0,
             "tau_x": 0.0, "tau_y": 0.05}
        inputs = np.array([u[n] for n in stepper.input_names])
        state = stepper.step(state, inputs)
        slave.step(u)
        worst = max(worst, float(np.max(np.abs(slave.get("theta_x", "theta_y")
                                               - rows @ state))))
    slave.close()
    assert worst <= SAME


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
    assert abs(theta - ref["theta_x"][-1]) <= 1e-9
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


def test_bad_calls_are_errors_with_a_logged_reason(wrist_fmu, unzipped):
    path, _ = wrist_fmu
    messages = []
    md = read_model_description(str(path))
    vr = refs(path)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="vsj_wrist",
                      instanceName="bad")
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(
        lambda env, name, status, category, text: messages.append(text.decode()))
    slave.instantiate(callbacks=callbacks, loggingOn=True)
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

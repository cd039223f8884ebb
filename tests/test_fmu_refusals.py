"""What the wrist FMU must refuse or report (issue 31, item 8), through FMPy.

An FMU runs inside tools that cannot see its physics: whatever vsj refuses or
reports elsewhere, the FMU refuses or reports to its importer, through the
logger, with fmi2Error (the instance cannot go on) or fmi2Warning (it can).
Each test drives the FMU's binary through FMPy and, where the same run exists
in `vsj simulate`, asks the same question of both.
"""

import math
import re
import shutil
import struct
import uuid

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2True

from vsj import fmu, params, scenario
from vsj.errors import InputError
from vsj.inputs import Constant
from vsj.params import RELATIONS, SCHEMA
from vsj.simulate import INTO_STOP, InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist

H = 1e-3
Q0 = -0.01
#: the FMU against `vsj simulate` of the same held efforts: the same C code on the same
#: inputs (the time-stepper restarted at each communication point), equal to round-off
SAME = 1e-9
#: the coarse time-stepper step of the second FMU, at which the ledger does not close
COARSE = 0.01
OK, WARNING, ERROR = 0, 1, 3


def _build(tmp_path_factory, name, **options):
    path = tmp_path_factory.mktemp(name) / f"{name}.fmu"
    fmu.build(path, params.default(), q0=Q0, win64=False, **options)
    unzipped = extract(str(path))
    return path, unzipped


@pytest.fixture(scope="module")
def wrist(wrist_fmu_file):
    """The default FMU: true stiction on the time-stepper at 1 ms (built once per session,
    shared with test_fmu.py; unzipped here into a directory of this module's own)."""
    path, _ = wrist_fmu_file(friction="stiction", step=H, q0=Q0, win64=False)
    unzipped = extract(str(path))
    yield path, unzipped
    shutil.rmtree(unzipped, ignore_errors=True)


@pytest.fixture(scope="module")
def other(tmp_path_factory):
    """Another vsj FMU of the same sizes: arctan friction on the time-stepper at 10 ms."""
    path, unzipped = _build(tmp_path_factory, "other", friction="arctan", method="timestep",
                            step=COARSE)
    yield path, unzipped
    shutil.rmtree(unzipped, ignore_errors=True)


@pytest.fixture(scope="module")
def dc(tmp_path_factory):
    """A wrist on DC motors (voltage inputs with a voltage limit)."""
    path, unzipped = _build(tmp_path_factory, "dc", friction="stiction", step=H,
                            wrist_options=WristOptions(motors="dc"))
    yield path, unzipped
    shutil.rmtree(unzipped, ignore_errors=True)


class Instance:
    """One FMPy instance of an FMU whose logger keeps what the FMU said, as
    (status, message) pairs."""

    def __init__(self, built, *, start=None, stop_time=None, initialize=True, name="wrist"):
        path, unzipped = built
        md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.said = []
        self.callbacks = fmi2CallbackFunctions()
        self.callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda env, who, status, category, text: self.said.append((status, text.decode())))
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier,
                             instanceName=name)
        self.fmu.instantiate(callbacks=self.callbacks, loggingOn=True)
        self.t = 0.0
        if initialize:
            self.fmu.setupExperiment(startTime=0.0, stopTime=stop_time)
            self.fmu.enterInitializationMode()
            for key, value in (start or {}).items():
                self.fmu.setReal([self.vr[key]], [value])
            self.fmu.exitInitializationMode()

    def set(self, **values):
        self.fmu.setReal([self.vr[k] for k in values], list(values.values()))

    def step(self, h=H, **inputs):
        """One fmi2DoStep; returns its status (an error raises FMICallException)."""
        if inputs:
            self.set(**inputs)
        status = self.fmu.fmi2DoStep(self.fmu.component, self.t, h, fmi2True)
        self.t += h
        return status

    def get(self, *names):
        return np.array(self.fmu.getReal([self.vr[n] for n in names]))

    def messages(self, status):
        return [text for s, text in self.said if s == status]

    def close(self):
        self.fmu.freeInstance()


def refused(call, *args, **kwargs):
    """Whether an FMI call ended in fmi2Error."""
    try:
        call(*args, **kwargs)
    except FMICallException as exc:
        assert exc.status == ERROR
        return True
    return False


# -- fmi2Instantiate ---------------------------------------------------------------------------

def test_instantiate_refuses_a_wrong_or_empty_guid(wrist, other):
    """FMI 2.0 (fmi2Instantiate): the FMU checks the GUID against its own, so that an
    importer holding another FMU's modelDescription.xml cannot run this binary."""
    guid = read_model_description(str(wrist[0])).guid
    foreign = read_model_description(str(other[0])).guid
    assert foreign != guid
    for wrong in ("", "{" + str(uuid.UUID(int=0)) + "}", foreign):
        messages = []
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(
            lambda env, who, status, category, text: messages.append((status, text.decode())))
        slave = FMU2Slave(guid=wrong, unzipDirectory=wrist[1], modelIdentifier="vsj_wrist")
        with pytest.raises(Exception, match="Failed to instantiate"):
            slave.instantiate(callbacks=callbacks)
        slave.freeLibrary()
        assert any(s == ERROR and "GUID" in text and guid in text for s, text in messages), \
            messages
    right = Instance(wrist)
    assert right.step(tau_x=0.1) == OK
    right.close()


def test_the_map_holds_its_reals_as_bits_that_no_locale_reads_otherwise(wrist):
    """resources/fmu.txt gives every real number as the 16 hexadecimal digits of its bits
    (an importer that set a decimal comma, as Qt applications do, cannot misread them),
    and the FMU's C sources convert no decimal text: no scanf of a real, no strtod."""
    import re
    from pathlib import Path

    text = (Path(wrist[1]) / "resources" / "fmu.txt").read_text()
    assert text.startswith("vsj-fmu 3\n")
    pivot = next(line for line in text.splitlines() if line.startswith("pivot "))
    assert re.fullmatch(r"pivot [0-9a-f]{16}", pivot)
    assert struct.unpack(">d", bytes.fromhex(pivot.split()[1]))[0] == Q0
    assert not re.search(r"\b\d+\.\d+(e[-+]?\d+)?\b", text.split("\n", 2)[2])  # no decimal
    root = Path(fmu.__file__).parent
    for source in [*(root / "fmi").glob("*.c"), *(root / "engine" / "c").glob("*.c")]:
        code = source.read_text()
        for pattern in (r'scanf\([^;]*%l?[fge]', r"\bstrto[df]\(", r"\bato[fi]\("):
            assert not re.search(pattern, code), (source.name, pattern)


# -- FMU states --------------------------------------------------------------------------------

def _fnv1a(data: bytes) -> bytes:
    """The checksum that ends a serialized state: 64-bit FNV-1a of the bytes before it."""
    h = 0xCBF29CE484222325
    for byte in data:
        h = ((h ^ byte) * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return struct.pack("=Q", h)


def _patched(blob: bytes, old: float, new: float) -> bytes:
    """``blob`` with every copy of the double ``old`` replaced by ``new``, its checksum
    made right again (what a damaged or forged state looks like to the FMU)."""
    body = blob[:-8]
    assert struct.pack("=d", old) in body
    body = body.replace(struct.pack("=d", old), struct.pack("=d", new))
    return body + _fnv1a(body)


def _state_after(built, steps, **inputs):
    s = Instance(built)
    for _ in range(steps):
        s.step(**inputs)
    blob = s.fmu.serializeFMUstate(s.fmu.getFMUstate())
    return s, blob


def test_a_state_of_this_fmu_round_trips_and_ends_with_its_checksum(wrist):
    s, blob = _state_after(wrist, 20, tau_x=0.3)
    assert blob[-8:] == _fnv1a(blob[:-8])  # the layout the other state tests rely on
    before = s.get("theta_x", "deflection_1")
    s.step(tau_x=0.3)
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(blob))
    assert np.array_equal(s.get("theta_x", "deflection_1"), before)
    s.close()


@pytest.fixture(scope="module")
def smooth(tmp_path_factory):
    """An FMU on dopri (arctan friction): its integrator keeps no stick/slip history."""
    path, unzipped = _build(tmp_path_factory, "smooth", friction="arctan", method="dopri",
                            step=H)
    yield path, unzipped
    shutil.rmtree(unzipped, ignore_errors=True)


def test_a_serialized_state_holds_the_state_and_nothing_else(smooth):
    """Two processes that take the same steps serialize the same bytes. A dopri FMU has
    no stick/slip history, and the state's place for it holds zeros, not whatever bytes
    the heap held (which differ from process to process)."""
    import subprocess
    import sys

    path, unzipped = smooth
    code = f"""
import hashlib
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave
md = read_model_description({str(path)!r})
vr = {{v.name: v.valueReference for v in md.modelVariables}}
# heap garbage first, so that fresh memory is not zero by chance
junk = [bytes([k % 251]) * 4096 for k in range(2000)]
del junk[::2]
f = FMU2Slave(guid=md.guid, unzipDirectory={str(unzipped)!r},
              modelIdentifier=md.coSimulation.modelIdentifier, instanceName="a")
f.instantiate()
f.setupExperiment(startTime=0.0)
f.enterInitializationMode()
f.exitInitializationMode()
for k in range(20):
    f.setReal([vr["tau_x"]], [0.3])
    f.doStep(k * {H!r}, {H!r})
print(hashlib.sha256(f.serializeFMUstate(f.getFMUstate())).hexdigest())
"""
    digests = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              check=True).stdout for _ in range(3)}
    assert len(digests) == 1


def test_a_state_of_another_vsj_fmu_is_refused(wrist, other):
    """A state serialized by another vsj FMU of the same sizes (another friction law and
    step) is refused by the fingerprint its header carries; so is its in-memory state."""
    theirs, blob = _state_after(other, 5, tau_x=0.3)
    mine, own = _state_after(wrist, 5, tau_x=0.3)
    assert len(blob) == len(own)  # only the fingerprint tells them apart
    assert refused(mine.fmu.deSerializeFMUstate, blob)
    assert any("another FMU" in text for text in mine.messages(ERROR)), mine.said
    assert refused(mine.fmu.setFMUstate, theirs.fmu.getFMUstate())
    assert mine.step(tau_x=0.3) == OK  # the refusals changed nothing
    theirs.close()
    mine.close()


@pytest.mark.parametrize("damage", ["flipped byte", "truncated", "format version"])
def test_a_damaged_state_is_refused(wrist, damage):
    s, blob = _state_after(wrist, 20, tau_x=0.3)
    if damage == "flipped byte":
        middle = len(blob) // 2
        bad = blob[:middle] + bytes([blob[middle] ^ 0x10]) + blob[middle + 1:]
    elif damage == "truncated":
        bad = blob[:-1]
    else:  # the header: magic (4 bytes), then the format version (4 bytes)
        body = blob[:4] + struct.pack("=I", 1 + struct.unpack("=I", blob[4:8])[0]) + blob[8:-8]
        bad = body + _fnv1a(body)
    assert refused(s.fmu.deSerializeFMUstate, bad)
    assert s.messages(ERROR), s.said
    s.close()


@pytest.mark.parametrize("what", ["time", "input"])
def test_a_state_holding_nan_is_refused(wrist, what):
    """A state whose time or values are not finite (then fmi2GetReal would answer NaN
    with fmi2OK) is refused, even with a right checksum."""
    tau = 0.123456789  # a value no other field of the state holds
    s, blob = _state_after(wrist, 20, tau_x=tau)
    t = 0.0
    for _ in range(20):
        t += H  # the FMU's clock, added up as it does
    bad = _patched(blob, t if what == "time" else tau, math.nan)
    assert refused(s.fmu.deSerializeFMUstate, bad)
    assert any("not finite" in text for text in s.messages(ERROR)), s.said
    s.close()


def _history(blob: bytes) -> tuple[int, int]:
    """Where a serialized state's stick/slip history lies: ``(start, end)`` in ``blob``
    (the block before the checksum, its length the header's fifth size)."""
    (size,) = struct.unpack_from("=q", blob, 8 + 64 + 4 * 8)  # magic, format, GUID, sizes
    end = len(blob) - 8
    return end - size, end


@pytest.mark.parametrize("what", ["an angle", "a count"])
def test_a_state_whose_stick_slip_history_holds_what_it_cannot_is_refused(wrist, what):
    """The time-stepper's history in a serialized state (its angles first, its per
    element counts last) is checked as the state's other values are: a NaN angle, or a
    count at 2^63 - 1 (one more step would overflow it), is refused with its name even
    with a right checksum; the untouched state is taken and steps on."""
    s, blob = _state_after(wrist, 20, tau_x=0.3)
    start, end = _history(blob)
    if what == "an angle":
        patch, at, name = struct.pack("=d", math.nan), start, "time-stepper's x"
    else:
        patch, at, name = struct.pack("=q", 2 ** 63 - 1), end - 8, "time-stepper's transitions"
    body = blob[:at] + patch + blob[at + len(patch):end]
    assert refused(s.fmu.deSerializeFMUstate, body + _fnv1a(body))
    assert any(name in text for text in s.messages(ERROR)), s.said
    s.fmu.setFMUstate(s.fmu.deSerializeFMUstate(blob))
    assert s.step(tau_x=0.3) == OK
    s.close()


# -- fmi2DoStep --------------------------------------------------------------------------------

@pytest.mark.parametrize("point,h", [(math.nan, H), (math.inf, H), (-math.inf, H),
                                     (0.0, math.nan), (0.0, 0.0), (0.0, -H), (0.0, math.inf)])
def test_do_step_refuses_a_non_finite_point_or_step(wrist, point, h):
    s = Instance(wrist)
    assert refused(s.fmu.doStep, point, h)
    assert s.messages(ERROR)
    assert s.step() == OK  # a refused call leaves the instance as it was
    s.close()


def test_do_step_refuses_a_step_longer_than_one_call_takes_and_goes_on(wrist):
    """A communication step of more internal steps than one call takes (vsj.h:
    VSJ_MAX_PERIOD_STEPS, 1e7; the time-stepper's step is 1 ms) is refused with the limit
    named, before any step is taken: the instance is not in the error state and steps on."""
    s = Instance(wrist)
    assert s.step(tau_x=0.3) == OK
    assert refused(s.fmu.doStep, s.t, 1e5)
    assert any("more than 10000000 steps" in text and "split it" in text
               for text in s.messages(ERROR)), s.said
    assert s.step(tau_x=0.3) == OK
    s.close()


def test_a_communication_step_takes_more_steps_than_the_files_step_function_bound(wrist):
    """The FMU takes up to VSJ_MAX_PERIOD_STEPS internal steps a communication step
    (c-api-fmu.md), whatever the exported step function's max_steps (100 000): 200 s of
    1 ms steps go through in one call."""
    s = Instance(wrist)
    assert s.step(h=200.0, tau_x=0.01) == OK
    assert np.all(np.isfinite(s.get("theta_x", "theta_y")))
    s.close()


def test_the_state_machine_refuses_terminate_out_of_turn_and_values_after_it(wrist):
    """FMI 2.0's state machine: fmi2Terminate only after initialization, once; no
    fmi2SetReal once terminated (fmi2Reset starts the instance anew)."""
    early = Instance(wrist, initialize=False)
    assert refused(early.fmu.terminate)
    assert any("fmi2Terminate: only after initialization" in t for t in early.messages(ERROR))
    early.close()
    s = Instance(wrist)
    assert s.step(tau_x=0.01) == OK
    s.fmu.terminate()
    assert refused(s.set, tau_x=0.02)
    assert any("the instance is terminated" in t for t in s.messages(ERROR)), s.said
    assert refused(s.fmu.terminate)
    s.fmu.reset()
    s.fmu.setupExperiment(startTime=0.0)
    s.fmu.enterInitializationMode()
    s.fmu.exitInitializationMode()
    s.t = 0.0
    assert s.step(tau_x=0.02) == OK
    s.close()


def test_do_step_refuses_to_pass_the_stop_time(wrist):
    """FMI 2.0 (fmi2SetupExperiment): with a stop time defined, a step past it is an error."""
    s = Instance(wrist, stop_time=5 * H)
    for _ in range(5):
        assert s.step(tau_x=0.3) == OK
    assert refused(s.step)
    assert any("stop time" in text for text in s.messages(ERROR)), s.said
    s.close()
    early = Instance(wrist, initialize=False)
    assert refused(early.fmu.setupExperiment, None, 1.0, 0.5)  # a stop before the start
    early.close()


# -- parameters --------------------------------------------------------------------------------

def _file_refuses(key, value):
    section, name = key.split(".", 1)
    unit = SCHEMA[section][name].unit
    text = repr(float(value)) if unit == "1" else f"{float(value)!r} {unit}"
    try:
        params.default().with_overrides({key: text}, origin="test")
    except InputError:
        return True
    return False


def _candidates(spec, value):
    """Values at and beyond a parameter's bounds, zero, non-finite values, and values
    that move it far enough to break the relations it takes part in."""
    out = {0.0, -value, 0.5 * value, 2.0 * value, -1.0, math.inf, -math.inf}
    nudge = 1e-6 * (abs(value) if value else 1.0)
    for bound in (spec.minimum, spec.maximum):
        if bound is not None:
            out |= {bound, bound - nudge, bound + nudge}
    return sorted(out) + [math.nan]


def test_each_tunable_parameter_is_refused_where_a_parameter_file_refuses_it(wrist):
    """Every tunable parameter, at its bounds (an excluded minimum such as a zero
    stiffness or sharpness included), at zero, non-finite, and far enough to break a
    relation between keys (`vsj.params.RELATIONS`): fmi2SetReal refuses it exactly
    when a parameter file with that value is refused. One exception: a file may make
    an end stop rigid ('inf N m/rad'); in an FMU that is a change of the model's
    structure, refused (export another FMU for it)."""
    md = read_model_description(str(wrist[0]))
    tunable = [v for v in md.modelVariables if v.variability == "tunable"]
    s = Instance(wrist, initialize=False)
    disagree, kinds = [], set()
    for variable in tunable:
        section, name = variable.name.split(".", 1)
        spec = SCHEMA[section][name]
        start = float(variable.start)
        for x in _candidates(spec, start):
            fmu_refuses = refused(s.fmu.setReal, [variable.valueReference], [x])
            if spec.infinite and x == math.inf:
                assert fmu_refuses and not _file_refuses(variable.name, x)
            elif fmu_refuses != _file_refuses(variable.name, x):
                disagree.append((variable.name, x, fmu_refuses))
            if fmu_refuses:
                kinds.add("strict" if spec.strict and x == spec.minimum else
                          "relation" if any(variable.name == k for r in RELATIONS
                                            for k, _ in r.terms) and spec.check(x) is None
                          else "bound")
            else:
                s.fmu.setReal([variable.valueReference], [start])
    s.close()
    assert not disagree, disagree
    assert kinds == {"strict", "relation", "bound"}  # each kind of refusal was exercised
    said = " ".join(s.messages(ERROR))
    assert "planetary.mesh_sharpness" in said and "must be > 0" in said
    assert "pivot.q_min must be below pivot.q_max" in said


def test_a_pivot_range_that_leaves_out_where_the_pivot_stands_is_refused_while_stepping(
        wrist):
    """During a run the pivot stands where it is (q = Q0, -1 cm): a pivot range that
    leaves it out is refused with that position named (the next step would fail and put
    the instance into the error state); one that holds it is taken, and the run goes on."""
    s = Instance(wrist)
    assert s.step(tau_x=0.3) == OK
    assert refused(s.set, **{"pivot.q_min": -0.5e-3})
    assert any("the pivot stands at q = -0.01 m" in text for text in s.messages(ERROR)), s.said
    assert s.step(tau_x=0.3) == OK
    s.set(**{"pivot.q_min": -0.015})
    assert s.step(tau_x=0.3) == OK
    s.close()


def test_a_refused_parameter_change_leaves_the_instance_as_it_was(wrist):
    """A call that sets a good and a bad value sets neither: the run that follows is the
    run of an instance that never saw the call."""
    s = Instance(wrist, initialize=False)
    bad = {"planetary.ring_inertia": 1.2e-4, "pivot.q_min": 0.021}  # above q_max
    assert refused(s.fmu.setReal, [s.vr[k] for k in bad], list(bad.values()))
    s.fmu.setupExperiment(startTime=0.0)
    s.fmu.enterInitializationMode()
    s.fmu.exitInitializationMode()
    untouched = Instance(wrist)
    for _ in range(50):
        s.step(tau_x=0.3)
        untouched.step(tau_x=0.3)
    assert np.array_equal(s.get("theta_x", "theta_y"), untouched.get("theta_x", "theta_y"))
    s.close()
    untouched.close()


# -- the physical checks of vsj simulate -------------------------------------------------------

def _simulate(tau, duration, friction="stiction", step=H, wrist_options=None, inputs=None):
    """`vsj simulate` of the run an FMU makes (always the time-stepper, as the FMUs here)."""
    structure = build_wrist(params.default(), wrist_options).assemble()
    return simulate(structure, inputs or {"tau_x": Constant(tau)}, duration,
                    initial=InitialState(q=Q0),
                    options=SimulationOptions(friction=friction, solver="timestep", step=step,
                                              output_step=step))


def test_a_diverging_run_is_an_error_as_in_vsj_simulate_and_a_saved_state_recovers(wrist):
    """tau_x = 1e12 N m: `vsj simulate` fails the run (a spring ten turns past its end
    stop); the FMU fails the step at the same time, goes to the error state, and a
    state saved before takes the instance back (FMI 2.0, fmi2Error)."""
    ref = _simulate(1e12, 0.01)
    assert not ref.success and "diverged" in ref.message
    failed_at = float(re.search(r"at t = ([0-9.e+-]+) s", ref.message).group(1))
    s = Instance(wrist)
    saved = s.fmu.getFMUstate()
    steps = 0
    while not refused(s.step, H, tau_x=1e12):
        steps += 1
        assert steps < 10
    assert math.isclose((steps + 1) * H, failed_at, rel_tol=1e-9)  # the failed step's end
    assert any("diverged" in text and "vsm_" in text for text in s.messages(ERROR)), s.said
    assert refused(s.fmu.doStep, (steps + 1) * H, H)  # the error state: no more steps
    s.fmu.setFMUstate(saved)
    s.t = 0.0
    assert s.step(tau_x=0.3) == OK
    s.fmu.freeFMUstate(saved)
    s.close()


@pytest.mark.parametrize("tau", [100.0, 1.0, 0.3])
def test_a_spring_driven_past_its_stop_is_a_warning_as_in_vsj_simulate(wrist, tau):
    """`vsj simulate` warns when a spring goes `INTO_STOP` past its end stop; the FMU
    returns fmi2Warning from the step where it first does, once per spring, and goes
    on. At 0.3 N m neither warns."""
    duration = 0.1
    ref = _simulate(tau, duration)
    assert ref.success
    warned = {re.search(r"spring (\w+)", w).group(1) for w in ref.warnings
              if w.startswith("spring")}
    s = Instance(wrist)
    statuses = [s.step(tau_x=tau) for _ in range(int(round(duration / H)))]
    said = s.messages(WARNING)
    s.close()
    assert {re.search(r"spring (\w+)", w).group(1) for w in said} == warned
    assert (tau > 0.5) == bool(warned)
    stop = params.default()["elastic_element.end_stop"]
    for name in warned:  # warned at the first sample where vsj simulate is past
        past = np.abs(ref[f"spring.{name}.deflection"]) - stop > INTO_STOP
        first = int(np.flatnonzero(past)[0])
        steps = [k + 1 for k, status in enumerate(statuses) if status == WARNING]
        assert any(ref.time[first] == pytest.approx(k * H, rel=1e-9) for k in steps), name
    assert statuses.count(WARNING) <= len(warned) and set(statuses) <= {OK, WARNING}


def test_a_motor_above_its_voltage_limit_is_a_warning_as_in_vsj_simulate(dc):
    limit = params.default()["motor.voltage_limit"]
    for volts in (1.25 * limit, 0.8 * limit):
        ref = _simulate(0.0, 0.005, wrist_options=WristOptions(motors="dc"),
                        inputs={"voltage_1": Constant(volts)})
        s = Instance(dc)
        statuses = [s.step(voltage_1=volts) for _ in range(5)]
        said = s.messages(WARNING)
        s.close()
        over = volts > limit
        assert bool(ref.warnings) == over and bool(said) == over
        assert statuses[0] == (WARNING if over else OK) and set(statuses[1:]) == {OK}
        if over:
            assert "motor_1" in said[0] and f"{limit:g} V limit" in said[0]


def _ledger_said(instance):
    """The relative residual the FMU gave for its energy ledger at fmi2Terminate."""
    found = [float(m.group(1)) for _, text in instance.said
             if (m := re.search(r"ledger.*?residual is ([0-9.e+-]+) of the energy", text))]
    assert len(found) == 1, instance.said
    return found[0]


#: the FMU prints its ledger's residual to 6 significant digits
PRINTED = 5e-6


@pytest.mark.parametrize("which", ["other", "wrist"])
def test_the_energy_ledger_is_judged_at_terminate_as_in_vsj_simulate(wrist, other, which):
    """The run from initialization to fmi2Terminate is judged by its energy ledger, as
    `vsj simulate` judges a run: arctan friction on the time-stepper at 10 ms leaves a
    residual above the ledger tolerance (the scheme's first-order error), stiction at
    1 ms closes it. The FMU's residual is vsj simulate's (0.3 N m keeps the springs off
    their stops, where the two runs are the same to round-off)."""
    built, friction, step = (other, "arctan", COARSE) if which == "other" else (wrist,
                                                                                 "stiction", H)
    duration, tau = 0.5, 0.3
    ref = _simulate(tau, duration, friction=friction, step=step)
    s = Instance(built)
    for _ in range(int(round(duration / step))):
        s.step(step, tau_x=tau)
    fails = refused(s.fmu.terminate)
    residual = _ledger_said(s)
    s.close()
    assert fails == (not ref.success) == (which == "other")
    expected = ref.ledger["relative_residual"]
    assert abs(residual - expected) <= PRINTED * expected + SAME


def test_the_energy_ledger_counts_the_jumps_of_held_speeds(wrist):
    """Velocity-driven motors held at a new speed each step change the kinetic energy in
    a jump between steps, work that no integrator sees; the ledger counts it, so that a
    sound run (2 s of the fig-4.15 motion at 1 ms; uncounted, the jumps leave a residual
    above the tolerance) passes the check."""
    scen = scenario.load("fig-4.15")
    case = scen.cases[0]
    motion = scenario.parse_inputs(case, case.build(params.default()))
    steps = 2000
    t = np.arange(steps + 1) * H
    speeds = {name: np.diff(motion[name].value(t)) / H for name in ("motor_1", "motor_2")}
    s = Instance(wrist)
    for k in range(steps):
        assert s.step(motor_1=speeds["motor_1"][k], motor_2=speeds["motor_2"][k]) == OK
    s.fmu.terminate()
    residual = _ledger_said(s)
    s.close()
    assert residual <= SimulationOptions().ledger_tolerance


def test_the_energy_ledger_counts_a_parameter_changed_between_steps(wrist):
    """A stiffer spring set between two steps holds more energy at once, energy no step
    put in; the ledger counts it as the importer's (uncounted, the run would fail with a
    residual of about half the energy in play)."""
    s = Instance(wrist)
    for k in range(300):
        s.step(tau_x=0.3, motor_1=math.sin(k / 50))
    stiffness = s.get("elastic_element.spring_stiffness")[0]
    s.set(**{"elastic_element.spring_stiffness": 1.5 * stiffness})
    for k in range(300, 600):
        s.step(tau_x=0.3, motor_1=math.sin(k / 50))
    s.fmu.terminate()
    residual = _ledger_said(s)
    s.close()
    assert residual <= SimulationOptions().ledger_tolerance

"""The engine under AddressSanitizer and UndefinedBehaviorSanitizer (``make sanitize``).

Builds the extension and the C example with ``-fsanitize=address,undefined``
into a scratch directory, then, in a process that preloads the sanitizer
runtime, runs what the engine does for users: every regression scenario
(smooth, stiction, both elastic models, benches), the MSL drive trains
(clutches, brakes, breakaway peaks), sampled controllers in every scheme, the FMU
through FMPy (its refusals and
checks included), batches on two threads with
both solvers, the step function with all three methods, the C example on
good and bad model files, and the binding's refusal of bad arrays. Any
sanitizer report ends the run with a non-zero exit code.

    python tests/sanitize.py [SCRATCH_DIR]
"""

from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
ENGINE = ROOT / "src" / "vsj" / "engine"
# -g1: the line tables a report's stack trace needs, without the full debug information
# (which doubles the compiler's work here)
FLAGS = ["-fsanitize=address,undefined", "-fno-sanitize-recover=undefined",
         "-fno-omit-frame-pointer", "-g1", "-O1"]


def compiler() -> str:
    for cc in (os.environ.get("CC"), "gcc", "cc", "clang"):
        if not cc:
            continue
        if shutil.which(cc):
            return cc
    raise SystemExit("sanitize: no C compiler")


def is_clang(cc: str) -> bool:
    done = subprocess.run([cc, "--version"], capture_output=True, text=True)
    return "clang" in done.stdout


def flags(cc: str) -> list[str]:
    """The sanitizer flags; clang links its sanitizer runtime into a shared library only
    when asked (GCC's is shared by default)."""
    return FLAGS + (["-shared-libsan"] if is_clang(cc) else [])


def runtime(cc: str) -> str:
    """The sanitizer runtime to preload into Python (which is not instrumented)."""
    name = (f"libclang_rt.asan-{platform.machine()}.so" if is_clang(cc) else "libasan.so")
    return subprocess.run([cc, f"-print-file-name={name}"], capture_output=True, text=True,
                          check=True).stdout.strip()


def build(scratch: Path) -> tuple[Path, Path]:
    """The package with an instrumented engine (in scratch/pkg) and the example.

    The engine's sources are compiled once, as C99 with the sanitizer flags, into
    objects that the extension, the C example and the FMU's binary all link: the three
    run the same instrumented engine code, and the compiler's work (most of what this
    job costs) is not done three times."""
    cc = compiler()
    FLAGS = flags(cc)
    pkg = scratch / "pkg"
    shutil.rmtree(pkg, ignore_errors=True)
    shutil.copytree(ROOT / "src" / "vsj", pkg / "vsj",
                    ignore=shutil.ignore_patterns("*.so", "__pycache__"))
    engine_sources = sorted((ENGINE / "c").glob("*.c"))
    objects_dir = scratch / "engine-objects"
    shutil.rmtree(objects_dir, ignore_errors=True)
    objects_dir.mkdir()
    # one compiler run, each source to <name>.o in objects_dir (position independent, for
    # the shared libraries; an executable links such objects too)
    subprocess.run([cc, "-std=c99", *FLAGS, "-fPIC", "-I", str(ENGINE / "c"), "-c",
                    *map(str, engine_sources)], cwd=objects_dir, check=True)
    objects = [str(objects_dir / f"{source.stem}.o") for source in engine_sources]
    include = sysconfig.get_paths()["include"]
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    subprocess.run([cc, *FLAGS, "-shared", "-fPIC", "-I", include, "-o",
                    str(pkg / "vsj" / f"_core{suffix}"), str(ROOT / "src" / "vsj" / "_core.c"),
                    *objects, "-lm"], check=True)
    example = scratch / "step_wrist"
    subprocess.run([cc, "-std=c99", *FLAGS, "-I", str(ENGINE / "c"), "-o", str(example),
                    str(ROOT / "examples" / "c" / "step_wrist.c"), *objects, "-lm"],
                   check=True)
    fmi = ROOT / "src" / "vsj" / "fmi"
    subprocess.run([cc, "-std=c99", *FLAGS, "-shared", "-fPIC", "-I", str(ENGINE / "c"), "-I",
                    str(fmi), "-o", str(scratch / "vsj_wrist.so"),
                    *map(str, sorted(fmi.glob("*.c"))), *objects, "-lm"], check=True)
    return pkg, example


WORKLOAD = r'''
import json, struct, subprocess, sys
from pathlib import Path
import numpy as np
sys.path.insert(0, str(Path(sys.argv[1])))
import vsj
from vsj import export, scenario as scenarios
from vsj import _core
from vsj.simulate import InitialState, SimulationOptions, simulate_batch
from vsj.stepper import Stepper

spec = __import__("importlib.util").util.spec_from_file_location(
    "make_references", sys.argv[2] + "/tests/references/make_references.py")
refs = __import__("importlib.util").util.module_from_spec(spec)
spec.loader.exec_module(refs)
assert "pkg" in vsj._core.__file__, vsj._core.__file__

for name in refs.REFERENCES:                      # the scenarios
    refs.run(name)
    print("scenario", name, flush=True)
for name in ("planetary-fixed-sun", "fig-4.15-dc-motors"):  # the Rosenbrock steps, ledger
    refs.run(name, {"method": "rosenbrock"})
    print("rosenbrock", name, flush=True)

rng = np.random.default_rng(1)                    # the splines' tridiagonal solve, pivoting
for n in (1, 2, 3, 17):
    a, d, c = rng.normal(size=n - 1), 1e-9 * rng.normal(size=n), rng.normal(size=n - 1)
    assert vsj._core.solve_tridiagonal(a, d, c, rng.normal(size=n)) == 0
print("tridiagonal", flush=True)

params = vsj.params.default()
from vsj.inputs import Table                       # end stops: compliant and rigid
from vsj.simulate import simulate
from vsj.wrist import WristOptions, build_wrist
for stiffness in ("50 N m/rad", "1e7 N m/rad"):
    p = params.with_overrides({"elastic_element.end_stop_stiffness": stiffness}, origin="s")
    r = simulate(build_wrist(p, WristOptions(elastic="geometric")).assemble(),
                 {"tau_x": Table((0.0, 1.0, 2.0), (0.0, 20.0, 20.0))}, 2.0,
                 initial=InitialState(q=-0.01),
                 options=SimulationOptions(friction="stiction", output_step=0.01))
    assert r.success and "end stop vsm_1" in r.ledger["dissipated"], r.message
print("end stops", flush=True)
from vsj import msl                                # clutches, brakes, peaks, spring-damper
for name, build in msl.EXAMPLES.items():
    example = build()
    r = example.simulate(1e-3)
    assert r.success and msl.check(example, r, msl.reference(example)).passed, name
    print("msl", name, flush=True)
sys.path.insert(0, sys.argv[2] + "/tests")         # controllers: every scheme, each part
import test_control as control_tests
for solver in ("dopri", "rosenbrock", "timestep"):
    control_tests.test_actuators_hold_between_samples_and_change_only_at_them(solver)
for method in ("dopri", "timestep"):                # the step function's controller
    control_tests.test_the_step_function_runs_the_controller_at_its_own_period(method)
for check in ("test_sensors_quantise_delay_and_add_seeded_noise",
              "test_a_linear_block_runs_python_controls_discrete_system",
              "test_a_current_limit_bounds_the_voltage_by_the_back_emf",
              "test_stiction_and_a_controller_close_the_ledger",
              "test_batches_and_blocks_give_the_bits_of_a_single_run",
              "test_the_engine_refuses_a_block_that_reads_a_later_output"):
    getattr(control_tests, check)()
print("controllers", flush=True)
import test_contact as contact_tests               # contacts: every scheme, stiction
for solver in ("dopri", "rosenbrock"):
    contact_tests.test_a_linear_contact_gives_the_closed_form_peak_and_duration(solver)
contact_tests.test_the_time_stepper_keeps_a_linear_contacts_energy(1e-3)
contact_tests.test_a_joint_held_against_a_wall_by_stiction_does_not_creep("stiction")
for elastic in ("geometric", "exponential"):
    contact_tests.test_the_ledger_closes_with_contacts_a_controller_and_stiction_at_the_default_step(
        elastic, True)
print("contacts", flush=True)
scen = scenarios.load("fig-4.15")
prep = scenarios.prepare_case(scen, scen.cases[0], params)
structure, inputs = prep.structure, prep.inputs
for friction in ("arctan", "stiction"):           # batches on two threads
    b = simulate_batch(structure, inputs, 1.0, initials=[InitialState(q=q) for q in
                       np.linspace(-0.02, 0.015, 6)],
                       options=SimulationOptions(friction=friction, output_step=0.01),
                       threads=2)
    assert b.success.all()
    print("batch", friction, flush=True)

for method, friction in (("dopri", "arctan"), ("rosenbrock", "arctan"), ("rk4", "arctan"),
                         ("timestep", "stiction")):
    stepper = Stepper.wrist(params, period=1e-3, method=method,
                            options=SimulationOptions(friction=friction))
    state = stepper.initial_state(InitialState(q=-0.01))
    for k in range(50):
        stepper.step(state, [0.3 * np.sin(k / 7), 0.2, 0.0, 0.02, -0.01], out=state)
    stepper.jacobian(state, [0.0] * 5)
    print("step", method, flush=True)
    document = export.model_document(stepper, params=params, initial=InitialState(q=-0.01))
    path = Path(sys.argv[3]) / f"wrist-{method}.vsjm"
    export.write_model(path, document, stepper)
    done = subprocess.run([sys.argv[4], str(path), "100"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    good = path.read_bytes()

    def sealed(data):
        return data[:-8] + struct.pack("<Q", export._fnv1a(data[:-8]))

    def edited(name, values):  # an array of the model replaced, both checksums remade
        old = np.asarray(getattr(stepper.model, name), dtype="<i8").tobytes()
        start = good.index(b"VSJM")
        length = struct.unpack("<q", good[start - 8:start])[0]
        blob = sealed(good[start:start + length].replace(old, np.asarray(values, "<i8").tobytes()))
        return sealed(good[:start] + blob + good[start + length:])

    for data, message in ((good[:-100], "damaged"), (sealed(good[:-100] + good[-8:]), "trunc"),
                          (edited("xc", [7] * len(stepper.model.xc)), "column"),
                          (edited("xp", [0, 10 ** 15] + list(stepper.model.xp[2:])),
                           "must not decrease"),
                          (edited("xp", list(stepper.model.xp[:-1]) + [10 ** 15]),
                           "truncated")):
        path.write_bytes(data)  # a column out of range; pointers past the columns
        done = subprocess.run([sys.argv[4], str(path), "3"], capture_output=True, text=True)
        assert done.returncode == 2 and message in done.stderr, done.stderr
    print("example", method, flush=True)

model = stepper.model                              # the binding refuses bad arrays
for change in ({"xc": np.full_like(model.xc, 10 ** 9)}, {"first": model.first + 10 ** 6},
               {"code": np.full_like(model.code, -5)}, {"mass": model.mass[:-1]},
               {"par": np.full_like(model.par, np.nan)}, {"xp": model.xp[::-1].copy()}):
    try:
        vsj.engine.core.native(model._replace(**change))
    except (ValueError, TypeError):
        pass
    else:
        raise AssertionError(f"accepted a bad model: {list(change)}")
print("refusals", flush=True)

import shutil                                      # the FMU: two instances, state, bad calls
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from vsj import fmu as fmu_module
fmu_path = Path(sys.argv[3]) / "wrist.fmu"
instrumented = Path(sys.argv[3]) / "vsj_wrist.so"


def compile_binary(kind, out):                     # the FMU carries the instrumented binary
    assert kind == "linux64", kind
    shutil.copy(instrumented, out)
    return ""


fmu_module.compile_binary = compile_binary
fmu_module.build(fmu_path, params, win64=False)
unzipped = extract(str(fmu_path))
assert (Path(unzipped) / "binaries" / "linux64" / "vsj_wrist.so").read_bytes() == \
    instrumented.read_bytes()
md = read_model_description(str(fmu_path))
vr = {v.name: v.valueReference for v in md.modelVariables}
slaves = []
for name, stiction in (("a", 0.001), ("b", 0.01)):
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier="vsj_wrist",
                  instanceName=name)
    s.instantiate()
    s.setupExperiment(tolerance=2.0 if name == "a" else None, startTime=0.0)  # ignored
    s.enterInitializationMode()
    s.setReal([vr["transmission.stiction"]], [stiction])
    s.exitInitializationMode()
    slaves.append(s)
t = 0.0
for k in range(200):
    for s in slaves:
        s.setReal([vr["motor_1"], vr["tau_x"]], [np.sin(t), 0.2])
        s.doStep(t, 1e-3 if k % 2 else 2.5e-3)
    t += 1e-3 if k % 2 else 2.5e-3
state = slaves[0].getFMUstate()
blob = slaves[0].serializeFMUstate(state)
again = slaves[0].deSerializeFMUstate(blob)
slaves[0].setFMUstate(again)
slaves[0].getReal([vr[n] for n in ("theta_x", "q", "power_in", "motor_1_speed")])
slaves[0].getInteger([0])
for bad in (lambda s: s.setReal([vr["tau_x"]], [float("nan")]),
            lambda s: s.doStep(99.0, 1e-3), lambda s: s.getReal([12345]),
            lambda s: s.setReal([vr["pivot.q_min"]], [0.05]),   # breaks a relation
            lambda s: s.setReal([vr["planetary.mesh_sharpness"]], [0.0]),
            lambda s: s.doStep(float("nan"), 1e-3)):
    try:
        bad(slaves[1])
    except Exception:
        pass
    else:
        raise AssertionError("the FMU accepted a bad call")
for damaged in (blob[:-1], blob[:100], blob[:-8] + bytes(8), bytes(len(blob))):
    try:                                           # refused states: damaged or not a state
        slaves[0].deSerializeFMUstate(damaged)
    except Exception:
        pass
    else:
        raise AssertionError("the FMU accepted a damaged state")
stranger = FMU2Slave(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=unzipped,
                     modelIdentifier="vsj_wrist", instanceName="stranger")
try:
    stranger.instantiate()
except Exception:
    stranger.freeLibrary()
else:
    raise AssertionError("the FMU accepted a wrong GUID")
slaves[1].setReal([vr["tau_x"]], [1e12])          # a run that diverges: the error state
for k in range(10):
    try:
        slaves[1].doStep(t + k * 1e-3, 1e-3)
    except Exception:
        break
else:
    raise AssertionError("the FMU did not stop a diverged run")
failed = slaves[1].getFMUstate()                  # taken in the error state: its history
slaves[1].freeFMUstate(slaves[1].deSerializeFMUstate(slaves[1].serializeFMUstate(failed)))
slaves[1].freeFMUstate(failed)
slaves[0].setDebugLogging(True, ["logStatusWarning", "logAll"])   # log categories
try:
    slaves[0].setDebugLogging(True, ["logEvents"])
except Exception:
    pass
else:
    raise AssertionError("the FMU accepted an unknown log category")
slaves[0].freeFMUstate(state)
slaves[0].freeFMUstate(again)
slaves[1].reset()
slaves[0].terminate()  # the reset one is instantiated again: FMI 2.0 allows no terminate
for s in slaves:
    s.freeInstance()
smooth_path = Path(sys.argv[3]) / "smooth.fmu"      # dopri: the importer's tolerance
fmu_module.build(smooth_path, params, friction="arctan", method="dopri", win64=False)
smooth_dir = extract(str(smooth_path))
smooth_md = read_model_description(str(smooth_path))
s = FMU2Slave(guid=smooth_md.guid, unzipDirectory=smooth_dir, modelIdentifier="vsj_wrist",
              instanceName="smooth")
s.instantiate()
for bad in (2.0, 0.0, float("nan")):
    try:
        s.setupExperiment(tolerance=bad, startTime=0.0)
    except Exception:
        pass
    else:
        raise AssertionError(f"the FMU accepted a tolerance of {bad}")
s.setupExperiment(tolerance=1e-4, startTime=0.0)
s.enterInitializationMode()
s.exitInitializationMode()
smooth_vr = {v.name: v.valueReference for v in smooth_md.modelVariables}
for k in range(50):
    s.setReal([smooth_vr["motor_1"]], [np.sin(k * 1e-3)])
    s.doStep(k * 1e-3, 1e-3)
state = s.getFMUstate()
again = s.deSerializeFMUstate(s.serializeFMUstate(state))
s.setFMUstate(again)
s.freeFMUstate(state)
s.freeFMUstate(again)
s.reset()
s.enterInitializationMode()
s.exitInitializationMode()
s.doStep(0.0, 1e-3)
s.terminate()
s.freeInstance()
print("fmu", flush=True)
'''


def main(argv: list[str]) -> int:
    scratch = Path(argv[1]) if len(argv) > 1 else Path(tempfile.mkdtemp(prefix="vsj-san-"))
    scratch.mkdir(parents=True, exist_ok=True)
    pkg, example = build(scratch)
    env = dict(os.environ)
    # and the C++ runtime with it: an extension that throws C++ exceptions (matplotlib's
    # font module, which python-control imports) needs it loaded when ASan starts
    cxx = subprocess.run([compiler(), "-print-file-name=libstdc++.so.6"], capture_output=True,
                         text=True).stdout.strip()
    env["LD_PRELOAD"] = " ".join([runtime(compiler())] + ([cxx] if Path(cxx).is_file() else []))
    # Python's allocator keeps memory at exit by design: leak reports would be its own
    env["ASAN_OPTIONS"] = "detect_leaks=0:abort_on_error=1"
    env["UBSAN_OPTIONS"] = "halt_on_error=1:print_stacktrace=1"
    env["PYTHONMALLOC"] = "malloc"
    # the C example is a plain program: there leaks count
    example_env = "ASAN_OPTIONS=detect_leaks=1"
    wrapper = scratch / "step_wrist.sh"
    wrapper.write_text(f"#!/bin/sh\n{example_env} exec {example} \"$@\"\n")
    wrapper.chmod(0o755)
    done = subprocess.run([sys.executable, "-c", WORKLOAD, str(pkg), str(ROOT), str(scratch),
                           str(wrapper)], env=env, capture_output=True, text=True)
    sys.stdout.write(done.stdout)
    sys.stderr.write(done.stderr)
    reports = [line for line in (done.stdout + done.stderr).splitlines()
               if "Sanitizer" in line or "runtime error:" in line]
    if done.returncode != 0 or reports:
        print(f"sanitize: FAILED (exit {done.returncode}, {len(reports)} sanitizer lines)",
              file=sys.stderr)
        return 1
    print("sanitize: no error reported (AddressSanitizer, UndefinedBehaviorSanitizer)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

"""The engine's public C API: a C program loads an exported wrist and steps it.

`examples/c/step_wrist.c` is built here with the system C compiler from the
engine's sources alone (no Python), fed a model file from ``vsj export-model``
and a sequence of inputs, and compared with the Python step function (the
same engine, in another build: `same_engine`) and with `vsj.simulate.simulate`
(both to their error tolerance).
"""

import math
import os
import struct
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import _once
from vsj import components as C
from vsj import export
from vsj.cli import main
from vsj.engine.core import IMPULSE_REL, OK, TOO_MANY_STEPS
from vsj.engine.plan import METHODS
from vsj.inputs import Constant
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import Stepper
from vsj.wrist import build_wrist

ROOT = Path(__file__).resolve().parents[1]
ENGINE = ROOT / "src" / "vsj" / "engine" / "c"
EXAMPLE = ROOT / "examples" / "c" / "step_wrist.c"
EPS = np.finfo(float).eps


def same_engine(stepper, periods: int, size: np.ndarray, span: np.ndarray) -> np.ndarray:
    """How far the example (built here with -std=c99 -O2, which does not contract
    multiply-adds) and vsj's extension (setuptools' flags with -std=c99, and whatever
    $CFLAGS adds: make portable's fma configuration contracts them) may part after
    ``periods`` periods [each output's unit], per output
    of size ``size`` and range ``span``. Two builds round differently; then dopri's
    step control may accept other steps, and each run is only as good as its
    tolerance, restarted every period: periods x 2 (rtol |y| + atol) (so is
    rosenbrock's). rk4's fixed
    substeps add a few ulps of the state each. The time-stepper with true stiction
    decides each element's impulse to IMPULSE_REL of the slip scale: steps x elements x
    IMPULSE_REL of the range (the regression tubes' model). The printed 17 digits and
    the output rows' dot products add a few ulps."""
    options, method = stepper.options, stepper.method
    if method in ("dopri", "rosenbrock"):
        allowed = periods * 2 * (options.rtol * size + options.atol)
    elif method == "rk4":
        allowed = periods * stepper.substeps * 4 * EPS * size
    else:
        steps = periods * max(1, round(stepper.period / options.step))
        allowed = steps * len(stepper.structure.frictions) * IMPULSE_REL * span
    return allowed + 4 * EPS * size


def compiler() -> str:
    """$CC if set (as `make portable` sets it), else the system's compiler."""
    for cc in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if cc and shutil.which(cc):
            return cc
    raise RuntimeError("no C compiler found (vsj's install needs one, see the README)")


#: Extra flags of the configuration under test (`make portable`'s optimisation and
#: contraction settings), after the example's own.
EXTRA_FLAGS = os.environ.get("VSJ_TEST_CFLAGS", "").split()


#: The flags the C programs here are built with: C99, every warning an error, and the
#: configuration's own.
C_FLAGS = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", *EXTRA_FLAGS]


def cc(*args: str) -> None:
    """Run the C compiler with ``C_FLAGS`` and the engine's headers; what it said on a failure."""
    done = subprocess.run([compiler(), *C_FLAGS, "-I", str(ENGINE), *args], capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr[-3000:]


@pytest.fixture(scope="session")
def engine_objects(tmp_path_factory) -> list[str]:
    """The engine's C sources compiled once per test session (`conftest._once`: the
    workers share them), for the C programs here to link: the engine alone, no Python."""
    def make(out: Path) -> list[str]:
        out.mkdir(parents=True, exist_ok=True)
        for source in sorted(ENGINE.glob("*.c")):
            cc("-c", "-o", str(out / f"{source.stem}.o"), str(source))
        return sorted(f"{source.stem}.o" for source in ENGINE.glob("*.c"))

    names, out = _once(tmp_path_factory, "engine-objects", make)
    return [str(out / name) for name in names]


@pytest.fixture(scope="session")
def step_wrist(tmp_path_factory, engine_objects) -> Path:
    """The C example, built once per test session (`conftest._once`: the workers share
    it; test_control.py runs it too)."""
    def make(out: Path) -> None:
        out.mkdir(parents=True, exist_ok=True)
        cc("-o", str(out / "step_wrist"), str(EXAMPLE), *engine_objects, "-lm")

    return _once(tmp_path_factory, "step-wrist", make)[1] / "step_wrist"


def random_inputs(stepper, periods: int, seed: int) -> np.ndarray:
    """Inputs for ``periods`` periods that move every output: random motor speeds and a
    random load (an output that stays at round-off has no range to scale the engines'
    parting by, `same_engine`)."""
    rng = np.random.default_rng(seed)
    inputs = np.zeros((periods, stepper.n_inputs))
    inputs[:, 0] = rng.normal(0.0, 0.5, periods)   # motor_1 speed
    inputs[:, 1] = rng.normal(0.0, 0.5, periods)   # motor_2 speed
    inputs[:, 3] = rng.normal(0.0, 0.05, periods)  # tau_x
    return inputs


def steps_as_python(stepper, document, inputs: np.ndarray, data: np.ndarray) -> np.ndarray:
    """The outputs the Python stepper gives over ``inputs`` from the file's initial state
    (a row per period, the start first), asserted within `same_engine` of the C
    program's ``data``; returned."""
    state = np.array(document["initial_state"])
    rows = np.array([o["row"] for o in document["outputs"]])
    expected = [rows @ state]
    for u in inputs:
        stepper.step(state, u, out=state)
        expected.append(rows @ state)
    expected = np.array(expected)
    allowed = same_engine(stepper, len(inputs), np.max(np.abs(expected), axis=0),
                          np.ptp(expected, axis=0))
    assert np.all(np.max(np.abs(data[:, 1:-1] - expected), axis=0) <= allowed)
    return expected


def run_example(exe, model: Path, periods: int, inputs: np.ndarray | None, tmp_path):
    args = [str(exe), str(model), str(periods)]
    if inputs is not None:
        path = tmp_path / "inputs.csv"
        np.savetxt(path, np.atleast_2d(inputs), delimiter=",", fmt="%.17g")
        args.append(str(path))
    done = subprocess.run(args, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.strip().splitlines()
    header = lines[0].split(",")
    data = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    return header, data


def export_wrist(tmp_path, params, **kwargs) -> tuple[Path, dict, object]:
    initial = kwargs.pop("initial", InitialState(q=-0.01))
    inputs = kwargs.pop("inputs", None)
    stepper = export.wrist_stepper(params, **kwargs)
    document = export.model_document(stepper, params=params, initial=initial, inputs=inputs)
    path = tmp_path / "wrist.vsjm"
    export.write_model(path, document, stepper)
    return path, document, stepper


@pytest.mark.parametrize("method", ["dopri", "rosenbrock", "rk4", "timestep"])
def test_the_c_program_steps_the_wrist_as_python_does(step_wrist, params, tmp_path, method):
    options = SimulationOptions(friction="stiction" if method == "timestep" else "arctan")
    path, document, stepper = export_wrist(tmp_path, params, options=options, method=method)
    periods = 60
    inputs = random_inputs(stepper, periods, 3)
    header, data = run_example(step_wrist, path, periods, inputs, tmp_path)
    names = [o["name"] for o in document["outputs"]]
    assert header == ["time [s]"] + [f"{n} [rad]" for n in names] + ["q [m]"]
    steps_as_python(stepper, document, inputs, data)
    # q: the pivot drive held still; its angle set from q by asin and read back by sin
    assert np.all(np.abs(data[:, -1] + 0.01) <= 4 * EPS * params.pivot.amplitude)
    assert np.ptp(data[:, names.index("theta_x") + 1]) > 1e-3  # the wrist moved


def test_the_c_program_agrees_with_simulate(step_wrist, params, tmp_path):
    options = SimulationOptions(rtol=1e-12, atol=1e-14)
    initial = InitialState(q=0.005, angles={"vsm_1.ring": 0.1})
    values = {"motor_1": 0.5, "motor_2": 0.2, "tau_x": 0.03}
    path, document, stepper = export_wrist(tmp_path, params, options=options, initial=initial,
                                           inputs=values)
    inputs = stepper.input_vector(values)
    periods = 200
    header, data = run_example(step_wrist, path, periods, inputs, tmp_path)
    result = simulate(build_wrist(params).assemble(),
                      {k: Constant(v) for k, v in values.items()}, periods * 1e-3,
                      initial=initial, options=options,
                      ports=False)
    assert result.success
    for name in ("theta_x", "theta_y", "phi_1", "phi_2"):
        column = header.index(f"{name} [rad]")
        # each run within its tolerance of the exact motion (test_convergence); the
        # example restarts dopri every period, so its errors may add up over them
        size = np.max(np.abs(result[name]))
        allowed = (periods + 1) * (options.rtol * size + options.atol)
        assert np.max(np.abs(data[:, column] - result[name])) <= allowed, name
    assert np.ptp(data[:, header.index("theta_x [rad]")]) > 1e-2


def test_export_model_command_writes_what_the_library_reads(step_wrist, tmp_path):
    path = tmp_path / "dc.vsjm"
    assert main(["export-model", "--out", str(path), "--motor-model", "dc",
                 "--friction", "stiction", "--q=-1cm"]) == 0
    data = path.read_bytes()
    assert data[:4] == b"VSJP" and struct.unpack("<q", data[16:24])[0] == METHODS["timestep"]
    for name in (b"motor_s", b"tau_x", b"tau_y", b"voltage_1", b"voltage_2"):
        assert name in data
    header, data = run_example(step_wrist, path, 20, [0.0, 0.0, 0.0, 3.0, -3.0], tmp_path)
    assert data.shape == (21, len(header))
    assert np.ptp(data[:, header.index("theta_y [rad]")]) > 0.0  # the motors turned


def _sealed(data: bytes) -> bytes:
    """``data`` with its checksum (the last 8 bytes) made right again."""
    return data[:-8] + struct.pack("<Q", export._fnv1a(data[:-8]))


def _with_code(document, stepper, code) -> bytes:
    """The program file of ``stepper`` with its model's law codes replaced (past the
    Python checks: the bytes are edited and both checksums remade)."""
    data = export.program_bytes(document, stepper)
    old = np.asarray(stepper.model.code, dtype="<i8").tobytes()
    new = np.asarray(code, dtype="<i8").tobytes()
    assert data.count(old) == 1
    start = data.index(b"VSJM")
    length = struct.unpack("<q", data[start - 8:start])[0]
    blob = _sealed(data[start:start + length].replace(old, new))
    return _sealed(data[:start] + blob + data[start + length:])


@pytest.mark.parametrize("change, message", [
    (lambda d, s: b"{\"format\": \"vsj-model\"}\n", "not a vsj model file"),
    (lambda d, s: _sealed(export.program_bytes(d, s)[:4] + b"\x09"
                          + export.program_bytes(d, s)[5:]), "another format version"),
    (lambda d, s: bytes([b ^ (1 if k == 100 else 0)
                         for k, b in enumerate(export.program_bytes(d, s))]), "damaged"),
    (lambda d, s: _sealed(export.program_bytes(d, s)[:-80] + b"\0" * 8), "truncated"),
    (lambda d, s: export.program_bytes({**d, "solver": {**d["solver"], "rtol": -1.0}}, s),
     "its tolerances are out of range (rtol in [1e-14, 1e-2]"),
    # the tolerances within vsj's ranges (rtol 1e-14..1e-2, atol 1e-20..1e-2), a step
    # count a period can take
    (lambda d, s: export.program_bytes({**d, "solver": {**d["solver"], "rtol": 1e-300}}, s),
     "its tolerances are out of range"),
    (lambda d, s: export.program_bytes({**d, "solver": {**d["solver"], "atol": math.inf}}, s),
     "atol in [1e-20, 1e-2]"),
    (lambda d, s: export.program_bytes({**d, "solver": {**d["solver"], "max_steps": 0}}, s),
     "its max_steps is not a whole number >= 1"),
    (lambda d, s: export.program_bytes({**d, "initial_state": [math.nan, *d["initial_state"][1:]]},
                                       s), "initial state is not finite"),
    (lambda d, s: export.program_bytes({**d, "initial_state": d["initial_state"][:-1],
                                        "outputs": [{**o, "row": o["row"][:-1]}
                                                    for o in d["outputs"]]}, s),
     "initial state does not fit"),
    (lambda d, s: export.program_bytes({**d, "inputs": d["inputs"][:-1]}, s),
     "inputs do not fit"),
    (lambda d, s: _with_code(d, s, [99] * len(s.model.code)), "unknown law"),
])
def test_a_bad_model_file_is_refused_with_its_reason(step_wrist, params, tmp_path, change,
                                                     message):
    path, document, stepper = export_wrist(tmp_path, params, method="dopri")
    path.write_bytes(change(document, stepper))
    done = subprocess.run([str(step_wrist), str(path), "3"], capture_output=True, text=True)
    assert done.returncode == 2
    assert message in done.stderr and str(path) in done.stderr


def test_the_engine_sources_need_only_the_c_standard_library():
    for source in list(ENGINE.glob("*.[ch]")) + [EXAMPLE]:
        includes = [line for line in source.read_text().splitlines()
                    if line.startswith("#include <")]
        allowed = {"ctype", "errno", "locale", "math", "stdarg", "stddef", "stdint", "stdio",
                   "stdlib", "string",
                   "sanitizer/asan_interface"}  # only in builds under AddressSanitizer
        for line in includes:
            assert line[len("#include <"):-len(".h>")] in allowed, (source.name, line)


LEDGER_DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include "vsj.h"

/* ledger_step MODEL PERIODS SPEED: steps MODEL with its first input held at SPEED and
 * prints each period's energy ledger (vsj_n_acc values) on a line. */
int main(int argc, char **argv) {
    char message[512];
    vsj_loaded *loaded;
    vsj_work *work;
    double *state, *ledger, *inputs;
    long periods, p;
    int64_t i;
    if (argc != 4 || !(loaded = vsj_load_model(argv[1], message, sizeof message)))
        return 2;
    work = vsj_work_new(&loaded->model);
    state = malloc((size_t)vsj_step_state_size(&loaded->model) * sizeof(double));
    ledger = malloc((size_t)vsj_n_acc(&loaded->model) * sizeof(double));
    inputs = calloc((size_t)loaded->n_inputs + 1, sizeof(double));
    if (!work || !state || !ledger || !inputs)
        return 2;
    for (i = 0; i < vsj_step_state_size(&loaded->model); i++)
        state[i] = loaded->initial_state[i];
    inputs[0] = strtod(argv[3], NULL);
    periods = strtol(argv[2], NULL, 10);
    for (p = 0; p < periods; p++) {
        if (vsj_step(&loaded->model, work, &loaded->scheme, state, inputs, loaded->period,
                     ledger) != VSJ_OK)
            return 1;
        for (i = 0; i < vsj_n_acc(&loaded->model); i++)
            printf(i ? " %.17g" : "%.17g", ledger[i]);
        printf("\n");
    }
    free(state);
    free(ledger);
    free(inputs);
    vsj_work_free(work);
    vsj_free_loaded(loaded);
    return 0;
}
"""


def test_a_source_on_the_channel_of_a_still_pivots_drive_ends_each_step_at_its_angle(
        tmp_path, engine_objects):
    """The time-stepper leaves a still pivot's drive unevaluated at the steps' ends, but
    not the channel it reads when another source reads it too: a velocity source on the
    pivot drive's channel, holding a linear spring against the ground, must load it by
    exactly its held speed times the time. The step function's ledger shows it: each
    period the spring's own work is minus its energy's change,
    -1/2 k ((u t1)^2 - (u t0)^2)."""
    stiffness, speed, periods = 50.0, 2.0, 3
    net = Network("shared channel")
    net.add(C.VelocitySource("drive", "w"), C.SpringDamper("spring", stiffness=stiffness),
            C.Fixed("ground"), C.Inertia("body", 1e-3), C.TorqueSource("load", "tau"),
            C.VelocitySource("pivot_drive", "w"),
            C.PivotMechanism("pivot", amplitude=0.02, ratio=10.0, inertia=1e-4))
    net.connect("drive.flange", "spring.a").connect("spring.b", "ground.flange")
    net.connect("body.flange", "load.flange").connect("pivot_drive.flange", "pivot.input")
    stepper = Stepper(net.assemble(), 1e-3, method="timestep",
                      options=SimulationOptions(friction="viscous", step=1e-4))
    assert stepper.input_names[0] == "w"
    model = tmp_path / "shared.vsjm"
    export.write_model(model, export.model_document(stepper), stepper)
    source = tmp_path / "ledger_step.c"
    source.write_text(LEDGER_DRIVER)
    exe = tmp_path / "ledger_step"
    cc("-o", str(exe), str(source), *engine_objects, "-lm")
    done = subprocess.run([str(exe), str(model), str(periods), repr(speed)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    ledgers = np.array([[float(v) for v in line.split()] for line in done.stdout.splitlines()])
    sizes = stepper.model.sizes
    # the ledger's order (engine/c/ledger.c): sources, loads, motors' supplies, friction,
    # motors' resistance, then the springs' own work
    spring = (sizes["n_sources"] + sizes["n_loads"] + 2 * sizes["n_motors"]
              + sizes["n_frictions"])
    t = np.arange(periods + 1) * stepper.period
    expected = -0.5 * stiffness * np.diff((speed * t) ** 2)  # the spring's own work
    # the spring's deflection is the source's angle to round-off (a few operations a
    # step, ten steps a period), and the trapezoidal rule is exact for a linear spring
    assert np.allclose(ledgers[:, spring], expected, rtol=100 * EPS, atol=0.0), \
        (ledgers[:, spring], expected)


ROWS_DRIVER = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "vsj.h"

static int same_row(const vsj_model *m, int64_t a, int64_t b) {
    int64_t i;
    if (m->xp[a + 1] - m->xp[a] != m->xp[b + 1] - m->xp[b] || m->xp[a + 1] == m->xp[a]
        || m->up[a + 1] - m->up[a] != m->up[b + 1] - m->up[b])
        return 0;
    for (i = 0; i < m->xp[a + 1] - m->xp[a]; i++)
        if (m->xc[m->xp[a] + i] != m->xc[m->xp[b] + i] || m->xv[m->xp[a] + i] != m->xv[m->xp[b] + i])
            return 0;
    for (i = 0; i < m->up[a + 1] - m->up[a]; i++)
        if (m->uc[m->up[a] + i] != m->uc[m->up[b] + i] || m->uv[m->up[a] + i] != m->uv[m->up[b] + i])
            return 0;
    return 1;
}

static int period(const vsj_loaded *l, vsj_work *w, const double *s0, const double *u,
                  double *s) {
    memcpy(s, s0, (size_t)vsj_step_state_size(&l->model) * sizeof(double));
    return vsj_step(&l->model, w, &l->scheme, s, u, l->period, NULL);
}

/* rows_step MODEL: a period on a work, the rows of each pair of friction elements on one
 * shaft split in place (the second's free part scaled by 1.25), a period again on that
 * work and one on a fresh work; prints the pairs split, whether the two periods after
 * the change are equal bit for bit, and whether they differ from the one before. */
int main(int argc, char **argv) {
    char message[512];
    vsj_loaded *l;
    vsj_work *work, *fresh;
    double *s0, *before, *reused, *again, *u;
    int64_t size, a, b, i, f, pairs = 0;
    if (argc != 2 || !(l = vsj_load_model(argv[1], message, sizeof message)))
        return 2;
    size = vsj_step_state_size(&l->model);
    work = vsj_work_new(&l->model);
    fresh = vsj_work_new(&l->model);
    s0 = malloc((size_t)size * sizeof(double));
    before = malloc((size_t)size * sizeof(double));
    reused = malloc((size_t)size * sizeof(double));
    again = malloc((size_t)size * sizeof(double));
    u = calloc((size_t)l->n_inputs + 1, sizeof(double));
    if (!work || !fresh || !s0 || !before || !reused || !again || !u)
        return 2;
    memcpy(s0, l->initial_state, (size_t)size * sizeof(double));
    for (i = 0; i < l->n_inputs; i++)
        u[i] = 0.3 + 0.1 * (double)i;
    if (period(l, work, s0, u, before) != VSJ_OK)
        return 1;
    f = l->model.n_frictions;
    for (b = 0; b < f; b++)
        for (a = 0; a < b; a++)
            if (same_row(&l->model, a, b)) {
                double *xv = (double *)l->model.xv; /* the caller's own arrays */
                for (i = l->model.xp[b]; i < l->model.xp[b + 1]; i++)
                    xv[i] *= 1.25;
                pairs++;
                break;
            }
    if (period(l, work, s0, u, reused) != VSJ_OK || period(l, fresh, s0, u, again) != VSJ_OK)
        return 1;
    printf("%lld %d %d\n", (long long)pairs,
           memcmp(reused, again, (size_t)size * sizeof(double)) == 0,
           memcmp(reused, before, (size_t)size * sizeof(double)) != 0);
    free(s0); free(before); free(reused); free(again); free(u);
    vsj_work_free(work);
    vsj_work_free(fresh);
    vsj_free_loaded(l);
    return 0;
}
"""


@pytest.mark.parametrize("method", ["dopri", "rosenbrock", "rk4"])
def test_a_period_after_rows_changed_in_place_reads_the_new_rows(params, tmp_path,
                                                                engine_objects, method):
    """The evaluation notes which friction elements share a slip row (the wrist has
    several: a bearing and a lever on one shaft) and evaluates such a slip once. A C
    program splits each such pair's rows in place between two periods of the step
    function: the period after the change equals one on a fresh work, bit for bit, and
    differs from the period before (no element keeps the slip it no longer shares)."""
    model, _, _ = export_wrist(tmp_path, params, method=method)
    source = tmp_path / "rows_step.c"
    source.write_text(ROWS_DRIVER)
    exe = tmp_path / "rows_step"
    cc("-o", str(exe), str(source), *engine_objects, "-lm")
    done = subprocess.run([str(exe), str(model)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    pairs, equal, moved = (int(v) for v in done.stdout.split())
    assert pairs >= 4 and equal == 1 and moved == 1


def test_the_file_carries_the_steps_a_period_may_take(step_wrist, params, tmp_path):
    """A stepper's bound on a period's steps (max_steps) goes into the file: the C library
    stops a period at it as the Python stepper does, where before it took up to ten
    million steps. Two steps cannot take dopri over a 1 ms period of these inputs."""
    path, document, stepper = export_wrist(tmp_path, params, method="dopri")
    document = {**document, "solver": {**document["solver"], "max_steps": 2}}
    path.write_bytes(export.program_bytes(document, stepper))
    inputs = np.zeros((1, stepper.n_inputs))
    inputs[0, 0] = 3.0  # motor_1 turning
    args = [str(step_wrist), str(path), "1", str(tmp_path / "in.csv")]
    np.savetxt(tmp_path / "in.csv", inputs, delimiter=",", fmt="%.17g")
    done = subprocess.run(args, capture_output=True, text=True)
    assert done.returncode != 0 and "maximum number of steps" in done.stderr, done.stderr
    limited = Stepper.wrist(params, period=1e-3, method="dopri", max_steps=2)
    with pytest.raises(Exception, match="maximum number of steps"):
        limited.step(limited.initial_state(InitialState(q=-0.01), inputs[0]), inputs[0])
    # the exported bound (the stepper's default) lets the same period through
    assert document["solver"]["max_steps"] == 2 and stepper.max_steps > 2
    header, data = run_example(step_wrist, export_wrist(tmp_path, params, method="dopri")[0],
                               1, inputs, tmp_path)
    assert np.all(np.isfinite(data))


def test_a_time_step_longer_than_the_period_loads_and_steps_as_python_steps(step_wrist, params,
                                                                            tmp_path):
    """`vsj export-model --step 2ms` with 1 ms periods: each period is one shortened step,
    in the C library as in the Python stepper (the loader refused the file it wrote)."""
    options = SimulationOptions(friction="stiction", step=2e-3)
    path, document, stepper = export_wrist(tmp_path, params, options=options,
                                           method="timestep")
    periods = 20
    inputs = random_inputs(stepper, periods, 5)
    header, data = run_example(step_wrist, path, periods, inputs, tmp_path)
    expected = steps_as_python(stepper, document, inputs, data)
    names = [o["name"] for o in document["outputs"]]
    assert np.ptp(expected[:, names.index("theta_x")]) > 1e-4  # the wrist moved


CHECKS_C = r"""
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "vsj.h"

/* vsj_step with one setting of the loaded scheme changed: its status */
static int step_with(vsj_loaded *L, vsj_scheme scheme, double dt) {
    double s[64], u[16] = {0};
    vsj_work *w = vsj_work_new(&L->model);
    int status;
    memcpy(s, L->initial_state, (size_t)vsj_step_state_size(&L->model) * sizeof(double));
    status = vsj_step(&L->model, w, &scheme, s, u, dt, NULL);
    vsj_work_free(w);
    return status;
}

int main(int argc, char **argv) {
    char message[256];
    vsj_loaded *adaptive = vsj_load_model(argv[1], message, sizeof message);
    vsj_loaded *stepper = vsj_load_model(argv[2], message, sizeof message);
    vsj_scheme a, t;
    (void)argc;
    if (!adaptive || !stepper)
        return 2;
    a = adaptive->scheme;
    t = stepper->scheme;
    a.rtol = 1e6;
    printf("%d ", step_with(adaptive, a, 1e-3));  /* rtol out of range */
    a = adaptive->scheme;
    a.atol = 0.0;
    printf("%d ", step_with(adaptive, a, 1e-3));  /* atol out of range */
    printf("%d ", step_with(adaptive, adaptive->scheme, INFINITY));  /* no end */
    t.max_steps = 0;
    printf("%d ", step_with(stepper, t, 1e-3));  /* no step allowed */
    t.max_steps = 100;
    printf("%d ", step_with(stepper, t, 1.0));   /* 1000 steps of 1 ms */
    printf("%d\n", step_with(stepper, t, 0.1));  /* 100: allowed */
    vsj_free_loaded(adaptive);
    vsj_free_loaded(stepper);
    return 0;
}
"""


def test_the_step_function_refuses_settings_the_loader_refuses(engine_objects, params,
                                                                tmp_path):
    """vsj_step checks the scheme a C caller hands it as the model file's loader checks
    it: tolerances in vsj's ranges, a finite period, and the time-stepper's max_steps
    (it ran 1000 steps with max_steps = 100, and a period with max_steps = 0)."""
    adaptive = export_wrist(tmp_path, params, method="dopri")[0]
    adaptive = adaptive.rename(tmp_path / "adaptive.vsjm")
    stepper = export_wrist(tmp_path, params, method="timestep",
                           options=SimulationOptions(friction="stiction"))[0]
    source, exe = tmp_path / "checks.c", tmp_path / "checks"
    source.write_text(CHECKS_C)
    cc("-o", str(exe), str(source), *engine_objects, "-lm")
    done = subprocess.run([str(exe), str(adaptive), str(stepper)], capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr
    bad = 6  # VSJ_BAD_ARGUMENT (vsj.h); the others are vsj.engine.core's
    assert [int(v) for v in done.stdout.split()] == [bad, bad, bad, bad, TOO_MANY_STEPS, OK]

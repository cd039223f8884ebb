"""Cost per call of the step function, from Python and from C, against baselines timed
in this run.

Workload: the default wrist (velocity-driven motors and pivot, geometric elastic
elements), q = -0.4 cm, a control period of 1 ms, motor speeds and a load torque
that change every period (a 2000-period loop). Methods:

* ``dopri``: adaptive, at the simulator's default tolerances (`vsj.engine.plan.RTOL`),
  arctan friction;
* ``rk4``: 4 fixed substeps, arctan friction;
* ``timestep``: the time-stepper, one 1 ms step per period, with arctan friction
  and with true stiction.

Each is timed from Python (`Stepper.step` in a Python loop) and from C
(``step_loop.c``: the model exported with `vsj.export`, loaded by
``vsj_load_model`` and stepped by the C library in a C loop, as an estimator on
the robot would). Baselines: one `vsj.simulate.simulate` call of one period
(what a user without the step function would call), and one `simulate` call over
all 2000 periods (per period; no per-period inputs, only to show what the
integration itself costs). Times are the minimum of repetitions, taken in
interleaved rounds (this VM's speed drifts over seconds).

Run: ``.venv/bin/python benchmarks/step_cost.py`` (part of ``make bench``).
"""

from __future__ import annotations

import math
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

import numpy as np

from vsj import export
from vsj import params as params_module
from vsj.engine.plan import RTOL
from vsj.inputs import Constant
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import Stepper
from vsj.wrist import build_wrist

PERIOD = 1e-3
PERIODS = 2000
Q = -0.004
ROUNDS = 3
#: Issue 32's target for the step function called from C [s per 1 ms period].
TARGET_C = 0.5e-6
ENGINE = Path(__file__).resolve().parents[1] / "src" / "vsj" / "engine" / "c"

#: name -> (method, friction law)
METHODS = {"dopri": ("dopri", "arctan"), "rk4": ("rk4", "arctan"),
           "timestep, arctan": ("timestep", "arctan"),
           "timestep, stiction": ("timestep", "stiction")}


def best(fun, repeat=5):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fun()
        times.append(time.perf_counter() - start)
    return min(times)


def inputs_for(stepper):
    t = np.arange(PERIODS) * PERIOD
    U = np.zeros((PERIODS, stepper.n_inputs))
    names = list(stepper.input_names)
    U[:, names.index("motor_1")] = 0.5 * np.sin(2 * np.pi * 1.0 * t)
    U[:, names.index("motor_2")] = 0.3 * np.cos(2 * np.pi * 0.7 * t)
    U[:, names.index("tau_x")] = 0.02 * np.sin(2 * np.pi * 3.0 * t)
    return U


def build_loop(scratch: Path) -> Path:
    """step_loop.c with the engine's sources, at the flags of Python's extensions and
    setup.py's for the engine."""
    exe = scratch / "step_loop"
    flags = (sysconfig.get_config_var("CFLAGS") or "-O3").split()
    cc = (sysconfig.get_config_var("CC") or "cc").split()[0]
    subprocess.run([cc, *flags, "-std=c99", "-fno-math-errno", "-I", str(ENGINE), "-o", str(exe),
                    str(Path(__file__).with_name("step_loop.c")),
                    *map(str, sorted(ENGINE.glob("*.c"))), "-lm"], check=True)
    return exe


def main() -> int:
    p = params_module.default()
    initial = InitialState(q=Q)
    scratch = Path(tempfile.mkdtemp(prefix="vsj-step-"))
    loop = build_loop(scratch)
    cases = {}
    for name, (method, law) in METHODS.items():
        stepper = Stepper.wrist(p, period=PERIOD, method=method, substeps=4,
                                options=SimulationOptions(friction=law, step=PERIOD))
        U = inputs_for(stepper)
        model = scratch / f"{method}-{law}.vsjm"
        export.write_model(model, export.model_document(stepper, params=p, initial=initial,
                                                        inputs=U[0]), stepper)
        inputs = scratch / "inputs.csv"
        np.savetxt(inputs, U, delimiter=",", fmt="%.17g")
        start = stepper.initial_state(initial, U[0])

        def python_loop(stepper=stepper, U=U, start=start):
            if stepper.method == "timestep":
                stepper.use_model(stepper.model)  # a fresh stick/slip history, as in C
            y = start.copy()
            for u in U:
                stepper.step(y, u, out=y)
            return y

        def c_loop(model=model, inputs=inputs):
            done = subprocess.run([str(loop), str(model), str(inputs), "20"],
                                  capture_output=True, text=True, check=True)
            values = [float(v) for v in done.stdout.split()]
            return values[0] * 1e-9, np.array(values[1:])

        cases[name] = (python_loop, c_loop, stepper)

    t_py = dict.fromkeys(cases, math.inf)
    t_c = dict.fromkeys(cases, math.inf)
    final = {}
    for _ in range(ROUNDS):
        for name, (python_loop, c_loop, _) in cases.items():
            t_py[name] = min(t_py[name], best(python_loop, 3) / PERIODS)
            per_period, state = c_loop()
            t_c[name] = min(t_c[name], per_period)
            final[name] = (python_loop(), state)

    structure = build_wrist(p).assemble()
    names = Stepper.wrist(p, period=PERIOD).input_names
    held = {ch: Constant(0.1 * k) for k, ch in enumerate(names) if ch != "motor_s"}

    def one_period(ports):
        return lambda: simulate(structure, held, PERIOD, initial=initial,
                                ports=ports)

    one_period(True)()
    t_sim = best(one_period(True), repeat=20)
    t_sim_bare = best(one_period(False), repeat=20)
    t_long = best(lambda: simulate(structure, held, PERIODS * PERIOD, initial=initial, ports=False,
                                   options=SimulationOptions(output_step=PERIOD)),
                  repeat=3) / PERIODS

    print(f"vsj step function, default wrist, q = {Q * 100:g} cm, period {PERIOD * 1e3:g} ms, "
          f"{PERIODS} periods with changing inputs (minimum of repeated runs)")
    print(f"{'method':<20} {'from Python':>12} {'from C':>10} {'C vs simulate(1 period)':>24}"
          f" {'C = Python':>11}")
    for name in cases:
        python_state, c_state = final[name]
        same = np.array_equal(python_state, c_state)
        print(f"{name:<20} {t_py[name] * 1e6:>9.2f} us {t_c[name] * 1e6:>7.2f} us "
              f"{t_sim / t_c[name]:>21.0f}x {'yes' if same else 'NO':>11}")
    print(f"baseline: simulate() of one period: {t_sim * 1e6:.0f} us with port signals, "
          f"{t_sim_bare * 1e6:.0f} us without")
    print(f"context: simulate() of {PERIODS} periods in one call (constant inputs, dopri): "
          f"{t_long * 1e6:.2f} us per period")
    n = structure.n
    diff = float(np.max(np.abs(final["rk4"][0][:n] - final["dopri"][0][:n])))
    print(f"rk4 (4 substeps) vs dopri (rtol {RTOL:g}) after {PERIODS} periods: {diff:.2g} rad in "
          f"the ring angles")
    fastest = min(t_c, key=t_c.get)
    met = t_c["timestep, stiction"] <= TARGET_C
    print(f"target (issue 32): the step function from C within {TARGET_C * 1e6:g} us per "
          f"period: timestep with stiction {t_c['timestep, stiction'] * 1e6:.2f} us "
          f"({'met' if met else 'NOT met'}); fastest {fastest}")
    ok = all(np.array_equal(*final[name]) for name in cases)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

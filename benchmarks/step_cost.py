"""Cost per call of the step function (vsj.stepper), against baselines timed in this run.

Workload: the default wrist (velocity-driven motors and pivot, geometric elastic
elements, arctan friction on every element), q = -0.4 cm, a control period of
1 ms, motor speeds and a load torque that change every period (a 2000-period
loop). For each method (adaptive ``dopri`` at the simulator's default
tolerances, fixed-step ``rk4`` with 4 substeps):

* Python: `Stepper.step` called in a Python loop (the estimator use case);
* compiled: the numba kernel called from a numba loop (no Python in between);

Baselines: one `vsj.simulate.simulate` call of one period (what a user without
the stepper would call each period), with and without the port signals, and
one `simulate` call over all 2000 periods (per period; no per-period
inputs, only to show what the integration itself costs). Times are the
minimum of several repetitions (a shared VM scatters by tens of percent).

Run: ``/tmp/venv/bin/python benchmarks/step_cost.py`` (or the project venv).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from vsj import params as params_module
from vsj.inputs import Constant
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import OK, Stepper, step_dopri, step_rk4
from vsj.wrist import build_wrist, pivot_range

PERIOD = 1e-3
PERIODS = 2000
Q = -0.004


def best(fun, repeat=5):
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fun()
        times.append(time.perf_counter() - start)
    return min(times)


@njit
def loop_dopri(model, work, state, inputs, dt, rtol, atol, max_steps):
    for k in range(inputs.shape[0]):
        if step_dopri(model, work, state, inputs[k], dt, rtol, atol, max_steps) != OK:
            return k
    return inputs.shape[0]


@njit
def loop_rk4(model, work, state, inputs, dt, substeps):
    for k in range(inputs.shape[0]):
        if step_rk4(model, work, state, inputs[k], dt, substeps) != OK:
            return k
    return inputs.shape[0]


def inputs_for(stepper):
    t = np.arange(PERIODS) * PERIOD
    U = np.zeros((PERIODS, stepper.n_inputs))
    names = list(stepper.input_names)
    U[:, names.index("motor_1")] = 0.5 * np.sin(2 * np.pi * 1.0 * t)
    U[:, names.index("motor_2")] = 0.3 * np.cos(2 * np.pi * 0.7 * t)
    U[:, names.index("tau_x")] = 0.02 * np.sin(2 * np.pi * 3.0 * t)
    return U


def main() -> int:
    p = params_module.default()
    initial = InitialState(q=Q)
    rows = []
    results = {}
    for method in ("dopri", "rk4"):
        stepper = Stepper.wrist(p, period=PERIOD, method=method, substeps=4)
        U = inputs_for(stepper)
        start = stepper.initial_state(initial, U[0])

        def python_loop():
            y = start.copy()
            for u in U:
                stepper.step(y, u, out=y)
            return y

        def compiled_loop():
            y = start.copy()
            if method == "dopri":
                loop_dopri(stepper.model, stepper.work, y, U, PERIOD, stepper.rtol,
                           stepper.atol, stepper.max_steps)
            else:
                loop_rk4(stepper.model, stepper.work, y, U, PERIOD, stepper.substeps)
            return y

        python_loop()
        compiled_loop()  # compile (or load from the cache) before timing
        t_py = best(python_loop) / PERIODS
        t_c = best(compiled_loop) / PERIODS
        results[method] = python_loop()
        rows.append((method, t_py, t_c))

    structure = build_wrist(p).assemble()
    rng = pivot_range(p)
    names = Stepper.wrist(p, period=PERIOD).input_names
    held = {ch: Constant(0.1 * k) for k, ch in enumerate(names) if ch != "motor_s"}

    def one_period(ports):
        return lambda: simulate(structure, held, PERIOD, initial=initial, pivot_range=rng,
                                ports=ports)

    one_period(True)()
    t_sim = best(one_period(True), repeat=20)
    t_sim_bare = best(one_period(False), repeat=20)
    t_long = best(lambda: simulate(structure, held, PERIODS * PERIOD, initial=initial,
                                   pivot_range=rng, ports=False,
                                   options=SimulationOptions(output_step=PERIOD)),
                  repeat=3) / PERIODS

    # accuracy of rk4 (4 substeps) against dopri at the default tolerances, same loop
    n = Stepper.wrist(p, period=PERIOD).structure.n
    diff = float(np.max(np.abs(results["rk4"][:n] - results["dopri"][:n])))

    print(f"vsj step function, default wrist, q = {Q * 100:g} cm, period {PERIOD * 1e3:g} ms, "
          f"{PERIODS} periods with changing inputs (minimum of repeated runs)")
    print(f"{'method':<8} {'Python call':>14} {'compiled loop':>15} {'dispatch':>10} "
          f"{'vs simulate(1 period)':>22}")
    for method, t_py, t_c in rows:
        print(f"{method:<8} {t_py * 1e6:>11.2f} us {t_c * 1e6:>12.2f} us "
              f"{(t_py - t_c) * 1e6:>7.2f} us {t_sim / t_py:>17.0f}x faster")
    print(f"baseline: simulate() of one period: {t_sim * 1e6:.0f} us with port signals, "
          f"{t_sim_bare * 1e6:.0f} us without")
    print(f"context: simulate() of {PERIODS} periods in one call (constant inputs): "
          f"{t_long * 1e6:.2f} us per period")
    print(f"rk4 (4 substeps) vs dopri (rtol 1e-8) after {PERIODS} periods: "
          f"{diff:.2g} rad in the ring angles")
    return 0 if all(math.isfinite(t) for _, t, _ in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())

"""Why vsj's true stiction is a time-stepper with joint Coulomb impulses: measured.

Two tasks on the wrist:

* hold: motors held, 0.05 N m on the end-effector from t = 0.5 s; how far the
  end-effector drifts between 2 s and 12 s, once it has come to rest;
* run: the fig 4.15 circular motion at q = -1.5 cm, 10 s; wall time, steps,
  and for the time-stepper the stick/slip transitions at two step sizes.

For each friction law of the report (arctan, sign, slope with two widths) and
vsj's stiction law. Run with `.venv/bin/python benchmarks/friction_laws.py`
(also part of `make bench`).
"""

from __future__ import annotations

import sys
import time


from vsj import params as params_module
from vsj import scenario as scenarios
from vsj.inputs import Table
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import build_wrist

LAWS = [("arctan", {}), ("sign", {}), ("slope", {"slope_width": 1e-2}),
        ("slope", {"slope_width": 1e-4}), ("stiction", {})]


def hold(structure, law, extra):
    load = Table((0.0, 0.5, 12.0), (0.0, 0.05, 0.05))
    options = SimulationOptions(friction=law, max_steps=5_000_000, **extra)
    start = time.perf_counter()
    r = simulate(structure, {"tau_x": load}, 12.0, initial=InitialState(q=0.005), options=options,
                 ports=False)
    wall = time.perf_counter() - start
    if not r.success:
        return f"failed: {r.message[:50]}", wall
    after = r.time >= 2.0
    return abs(r["theta_x"][-1] - r["theta_x"][after][0]), wall


def run(structure, inputs, case, law, extra, step=1e-3):
    options = SimulationOptions(friction=law, step=step, max_steps=5_000_000, **extra)
    simulate(structure, inputs, 1.0, options=options, initial=case.initial,
             ports=False)
    start = time.perf_counter()
    r = simulate(structure, inputs, case.duration, options=options, initial=case.initial, ports=False)
    return r, time.perf_counter() - start


def main() -> int:
    p = params_module.default()
    structure = build_wrist(p).assemble()
    scen = scenarios.load("fig-4.15")
    case = scen.cases[0]
    prep = scenarios.prepare_case(scen, case, p)
    wrist, inputs = prep.structure, prep.inputs
    print(f"{'law':<22} {'hold: drift 2-12 s [rad]':>26} {'fig 4.15: wall [s]':>19} "
          f"{'steps':>9} {'transitions (1 ms / 0.25 ms)':>30}")
    for law, extra in LAWS:
        label = law + (f" w={extra['slope_width']:g}" if extra else "")
        drift, _ = hold(structure, law, extra)
        r, wall = run(wrist, inputs, case, law, extra)
        steps = r.solver["steps"] if r.success else "-"
        flips = ""
        if law == "stiction":
            fine, _ = run(wrist, inputs, case, law, extra, step=2.5e-4)
            flips = f"{sum(r.transitions.values())} / {sum(fine.transitions.values())}"
        drift_text = f"{drift:.2e}" if isinstance(drift, float) else drift
        wall_text = f"{wall:.3f}" if r.success else "failed"
        print(f"{label:<22} {drift_text:>26} {wall_text:>19} {steps!s:>9} {flips:>30}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

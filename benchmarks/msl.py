"""The MSL drive trains (`vsj.msl`): what the time-stepper costs against the event
count a Modelica tool must locate, and against vsj's own smooth alternative.

For ``Rotational.Examples.Friction`` (3 s) and ``CoupledClutches`` (1.5 s):

* ``stiction``: vsj's time-stepper with true stiction at 1 ms and at 0.1 ms steps,
  each with its largest use of the MSL tube (`vsj.msl.check`);
* baseline ``arctan``: the same network with the smooth arctan law (friction
  coefficient times normal force times 2/pi atan(w / 1e-3 rad/s)) on vsj's
  adaptive Dormand-Prince at the default tolerances: what a user without true
  stiction would run instead. Its tube usage is printed too;
* the number of events in the reference: the instants at which some friction
  element changes mode (stuck, forward or backward sliding), each of which a
  Modelica tool must locate by root finding and restart from; the time-stepper
  locates none of them and steps across.

Times are the best of interleaved rounds (this VM's speed drifts over seconds).
Run: ``.venv/bin/python benchmarks/msl.py`` (part of ``make bench``).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from vsj import compare, msl
from vsj.simulate import SimulationOptions, simulate

ROUNDS = 7


def reference_events(example, reference) -> int:
    """Mode changes of the reference's friction elements."""
    count = 0
    for name in example.modes:
        count += len(compare.changes(reference["time"], reference[f"{name}.mode"]))
    return count


def smooth(example):
    options = SimulationOptions(friction="arctan", output_step=1e-3, max_steps=10_000_000)

    def run():
        return simulate(example.structure, example.inputs, example.duration, options=options,
                        initial=example.initial, ports=False)

    return run


def usage(example, result, reference) -> float:
    if not result.success:
        return float("nan")
    tubes = msl.check(example, result, reference).tubes
    return max(t.usage for t in tubes)


def main() -> int:
    print("MSL drive trains: vsj's time-stepper against the reference's event count and "
          "against the smooth arctan law (best of interleaved rounds)\n")
    header = (f"{'example':<18} {'method':<22} {'time':>10} {'per s simulated':>16} "
              f"{'tube used':>10}")
    print(header)
    print("-" * len(header))
    for name, build in msl.EXAMPLES.items():
        example = build()
        reference = msl.reference(example)
        runs = {"stiction, 1 ms": lambda e=example: e.simulate(1e-3),
                "stiction, 0.1 ms": lambda e=example: e.simulate(1e-4),
                "arctan, dopri": smooth(example)}
        best = dict.fromkeys(runs, np.inf)
        results = {}
        for _ in range(ROUNDS):
            for label, run in runs.items():
                start = time.perf_counter()
                results[label] = run()
                best[label] = min(best[label], time.perf_counter() - start)
        for label in runs:
            r = results[label]
            note = "" if r.success else f"  FAILED: {r.message[:40]}"
            print(f"{name:<18} {label:<22} {best[label] * 1e3:8.2f} ms "
                  f"{best[label] / example.duration * 1e3:13.2f} ms "
                  f"{usage(example, r, reference):10.3g}{note}")
        events = reference_events(example, reference)
        print(f"{name:<18} reference events: {events} friction mode changes, each found by "
              f"root finding in a Modelica tool; the time-stepper needs no event search")
        print(f"{name:<18} ratio arctan-dopri / stiction-1ms: "
              f"{best['arctan, dopri'] / best['stiction, 1 ms']:.1f}x, "
              f"stiction 0.1 ms / 1 ms: {best['stiction, 0.1 ms'] / best['stiction, 1 ms']:.1f}x\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())

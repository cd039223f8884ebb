"""Coverage study of the whole-wrist identification (issue 23 acceptance).

Eight parameters free (the ring bearing's, the transmission's and the
differential's stiction levels, the parasitic compliance of transmission 1,
the end-effector inertia about theta_x, the ring and carrier inertias and the
transmission's viscous friction), identified from synthetic logs of
`examples/identification/experiment.toml` (cut to ``--duration``) with the
parameter set `examples/identification/wrist_params.toml` as the truth and
the default sensor artefacts of `vsj synth wrist` (encoder quantisation, noise,
the end-effector channels 0.2 ms behind the motor channels, sample-time
jitter; the truth simulated at ``--truth-step``, by default 0.5 ms as `vsj
synth wrist` simulates it, the fit at ``--fit-step``, by default its own
0.5 ms). A finer truth (``--truth-step 2.5e-4``) lets the time-stepper's
discretisation error show as it would on a real wrist: with 10 s logs the
standard errors are a tenth of a percent, and that error biases some
estimates by about one of them. Each trial has its own
noise seed and starts from its own point, every parameter 30 % off the truth
(up or down at random).

Acceptance, per parameter over the trials:

* of the trials in which it is reported as determined, at least 90 % within
  three reported standard errors of the truth;
* the spread of the estimates over the trials (sd) and the reported standard
  errors (rms over trials) agree within a factor of 1.5.

Run from the repository: ``.venv/bin/python benchmarks/identify_wrist_coverage.py
[--seeds 20] [--duration 10] [--jobs 2] [--json FILE]``. Trials run in
``--jobs`` processes, one engine thread each; every finished trial is printed.
The exit status is 0 when every criterion holds, 1 otherwise.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
FREE = ("planetary.ring_bearing_stiction", "transmission.stiction", "differential.stiction",
        "transmission.series_compliance_1", "differential.inertia_x", "planetary.ring_inertia",
        "transmission.viscous", "planetary.carrier_inertia")
#: Acceptance (issue 23).
Z_LIMIT, COVERAGE, SPREAD_FACTOR = 3.0, 0.9, 1.5
#: Each trial starts this far off the truth on every free parameter, up or down.
START_OFF = 0.3
#: First noise seed (trial k uses FIRST_SEED + k).
FIRST_SEED = 100


def trial(seed: int, duration: float, truth_step: float, fit_step: float) -> dict:
    from vsj import params as params_module
    from vsj import synth
    from vsj.identification import wrist_experiment as WE
    from vsj.identification.wrist import fit_wrist
    from vsj.identification.wrist_model import Setup
    from vsj.measurements import Measurement

    truth = params_module.load(ROOT / "examples/identification/wrist_params.toml")
    e = replace(WE.load(ROOT / "examples/identification/experiment.toml"), duration=duration,
                step=truth_step)
    data = synth.wrist(e, truth, seed=seed)
    log = Measurement(f"synthetic-seed{seed}.csv", {k: v[0] for k, v in data.columns.items()},
                      {k: v[1] for k, v in data.columns.items()}, data.comments)
    signs = np.random.default_rng(seed).choice([-1.0, 1.0], len(FREE))
    start = {n: truth[n] * (1.0 + START_OFF * s) for n, s in zip(FREE, signs)}
    began = time.perf_counter()
    fit = fit_wrist([log], truth, Setup(free=FREE, threads=1, step=fit_step), starts=1,
                    start=start)
    return {"seed": seed, "wall_time": time.perf_counter() - began,
            "simulations": fit.simulations,
            "values": {e.name: e.value for e in fit.estimates},
            "stderr": {e.name: e.stderr for e in fit.estimates},
            "status": {e.name: e.status for e in fit.estimates},
            "delays": {d.name: d.value for d in fit.delays},
            "truth": {n: truth[n] for n in FREE}}


def summary(trials: list[dict]) -> tuple[list[dict], bool]:
    rows, ok = [], True
    for name in FREE:
        det = [t for t in trials if t["status"][name] == "determined"]
        truth = trials[0]["truth"][name]
        values = np.array([t["values"][name] for t in det])
        se = np.array([t["stderr"][name] for t in det])
        z = (values - truth) / se if det else np.zeros(0)
        within = float(np.mean(np.abs(z) <= Z_LIMIT)) if det else math.nan
        spread = float(np.std(values, ddof=1)) if len(det) > 1 else math.nan
        rms_se = float(np.sqrt(np.mean(se ** 2))) if det else math.nan
        ratio = spread / rms_se if det else math.nan
        passed = (bool(det) and within >= COVERAGE
                  and 1 / SPREAD_FACTOR <= ratio <= SPREAD_FACTOR)
        ok &= passed
        rows.append({"name": name, "truth": truth, "determined": len(det),
                     "within_3se": within, "mean_z": float(np.mean(z)) if det else math.nan,
                     "spread": spread, "rms_stderr": rms_se, "spread_over_stderr": ratio,
                     "passed": passed})
    return rows, ok


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--duration", type=float, default=10.0, help="log length [s]")
    parser.add_argument("--jobs", type=int, default=2, help="worker processes")
    parser.add_argument("--truth-step", type=float, default=5e-4,
                        help="time step of the simulation that makes the logs [s]")
    parser.add_argument("--fit-step", type=float, default=5e-4,
                        help="time step of the fit's simulations with true stiction [s]")
    parser.add_argument("--json", help="write every trial and the summary here")
    args = parser.parse_args(argv)
    began = time.perf_counter()
    trials = []
    print(f"coverage: {len(FREE)} parameters, {args.seeds} seeds, {args.duration:g} s logs "
          f"(truth step {args.truth_step * 1e3:g} ms, fit step {args.fit_step * 1e3:g} ms), "
          f"{args.jobs} processes", flush=True)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(trial, FIRST_SEED + k, args.duration, args.truth_step,
                               args.fit_step) for k in range(args.seeds)]
        for future in as_completed(futures):
            t = future.result()
            trials.append(t)
            z = [(t["values"][n] - t["truth"][n]) / t["stderr"][n] for n in FREE]
            print(f"  [{len(trials):2d}/{args.seeds}] seed {t['seed']}: {t['wall_time']:.1f} s, "
                  f"{t['simulations']} window runs, z = "
                  + " ".join(f"{v:+.1f}" for v in z), flush=True)
    trials.sort(key=lambda t: t["seed"])
    rows, ok = summary(trials)
    print(f"\n{'parameter':36s} {'determined':>10s} {'within 3 SE':>11s} {'mean z':>7s} "
          f"{'spread/SE':>9s}  verdict")
    for r in rows:
        print(f"{r['name']:36s} {r['determined']:10d} {100 * r['within_3se']:10.0f}% "
              f"{r['mean_z']:+7.2f} {r['spread_over_stderr']:9.2f}  "
              f"{'pass' if r['passed'] else 'FAIL'}")
    print(f"\n{'every criterion holds' if ok else 'some criterion fails'} "
          f"(>= {100 * COVERAGE:.0f} % within {Z_LIMIT:g} SE, spread/SE within "
          f"{1 / SPREAD_FACTOR:.2f}..{SPREAD_FACTOR:g}); {time.perf_counter() - began:.0f} s")
    if args.json:
        Path(args.json).write_text(json.dumps({"trials": trials, "summary": rows, "passed": ok},
                                              indent=1) + "\n")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())

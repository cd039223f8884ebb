"""Throughput of `vsj design` (issue 37): 10 000 evaluations of a K-range objective on two
cores, and where the time goes.

The problem: the stiffness range K_max / K_min over the pivot range (9 positions, the
datasheet's grid) of the geometric elastic element, over the spring stiffness and the
springs' anchor and rest length; NSGA-II, 100 designs per generation for 100
generations, evaluated in chunks of 25 by two worker processes
(`vsj.sweep.schedulers.Pool`), checkpointed after each generation. Timed from the
design file to the checkpoint of the last generation (the page and figures are not).

Printed: the wall time, the evaluations per second, and the share of the two cores'
time spent outside the engine (the spring laws and what wraps them in Python:
`vsj.datasheet.Statics`), split into the rest of each evaluation (building the design's
parameter set, the Statics) and everything else (pymoo, the scheduling, the
checkpoints, the workers' start). The split inside an evaluation is measured on 500
designs in this process.

    python benchmarks/design.py [--workers N] [--generations G]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

SPEC = """
[design]
seed = 1
population = 100
generations = {generations}
batch = 25
[parameters]
"elastic_element.spring_stiffness" = {{ min = "100 N/m", max = "400 N/m" }}
"elastic_element.rest_length" = {{ min = "1 cm", max = "2 cm" }}
"elastic_element.anchor_x" = {{ min = "0.6 cm", max = "1.4 cm" }}
"elastic_element.anchor_y" = {{ min = "2.2 cm", max = "3.2 cm" }}
[objectives]
stiffness_ratio = {{}}
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--generations", type=int, default=100)
    args = parser.parse_args()
    from vsj.design import loads, optimise
    from vsj.design.evaluate import _Clock, evaluate

    spec = loads(SPEC.format(generations=args.generations), "benchmarks/design.py")
    with tempfile.TemporaryDirectory() as tmp:
        began = time.perf_counter()
        outcome = optimise.run(spec, Path(tmp) / "out", workers=args.workers)
        wall = time.perf_counter() - began
    evaluations = len(outcome.archive.x)
    # the split inside an evaluation, on designs of the run, in this process
    problem = outcome.problem
    designs = np.array(outcome.archive.x)[:: max(1, evaluations // 500)][:500]
    clock = _Clock()
    began = time.perf_counter()  # the clock's, so that the two times compare
    for x in designs:
        evaluate(problem, x, clock)
    inside = time.perf_counter() - began
    engine_part = clock.seconds / inside
    budget = wall * args.workers
    engine = outcome.engine_seconds
    evaluating = engine / engine_part
    print(f"vsj design: {evaluations} evaluations of stiffness_ratio on {args.workers} "
          f"workers in {wall:.1f} s ({evaluations / wall:.0f} per second; "
          f"{len(outcome.front)} designs on the front)")
    print(f"  of the {budget:.1f} core-seconds: engine (spring laws) {engine:.1f} s "
          f"({100 * engine / budget:.0f} %), rest of the evaluations about "
          f"{evaluating - engine:.1f} s ({100 * (evaluating - engine) / budget:.0f} %), "
          f"optimiser, scheduling, checkpoints and idle cores "
          f"{budget - evaluating:.1f} s ({100 * (budget - evaluating) / budget:.0f} %)")
    print(f"  time outside the engine: {100 * (1 - engine / budget):.0f} % of the cores' time")


if __name__ == "__main__":
    main()

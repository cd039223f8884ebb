"""What pint would cost a warm process, and what the defined unit names save (`vsj.units`).

Each round starts fresh Python processes (bytecode compiled, page cache warm) that
read vsj's own files the way ``vsj simulate fig-4.15`` does before it simulates: the
bundled parameter set, the scenario and its five cases prepared. One process does only
that (vsj's path: every unit there is in `vsj.units.definitions`); the other also
imports pint and builds its registry, which is what converting a single unit outside
the definitions costs, and what every process paid before factors were kept at all.
A third times the whole warm command. CPU time is the figure to compare (this VM is
shared: wall-clock time moves with the load); best and median of the rounds.

    python benchmarks/units_startup.py [--rounds N]     (default 5)
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

READ = """
import json, resource, sys, time
from vsj import params, scenario
p = params.default()
s = scenario.load("fig-4.15")
cases = [scenario.prepare_case(s, case, p) for case in s.cases]
if sys.argv[1] == "pint":
    from vsj import units
    units.registry()
usage = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"cpu": usage.ru_utime + usage.ru_stime, "pint": "pint" in sys.modules,
                  "dask": "dask" in sys.modules}))
"""


def read(variant: str) -> dict:
    done = subprocess.run([sys.executable, "-c", READ, variant], check=True,
                          capture_output=True, text=True)
    return json.loads(done.stdout)


def command(out: str) -> tuple[float, float]:
    """CPU and wall time of ``vsj simulate fig-4.15`` in a fresh process."""
    started, before = time.perf_counter(), os.times()
    subprocess.run([sys.executable, "-m", "vsj", "simulate", "fig-4.15", "--out", out],
                   check=True, stdout=subprocess.DEVNULL)
    after = os.times()
    cpu = (after.children_user - before.children_user
           + after.children_system - before.children_system)
    return cpu, time.perf_counter() - started


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    times: dict[str, list[float]] = {"files": [], "files + pint": [], "command cpu": [],
                                     "command wall": []}
    with tempfile.TemporaryDirectory(prefix="vsj-units-bench-") as root:
        command(os.path.join(root, "warm"))  # bytecode and page cache
        for k in range(args.rounds):
            plain, with_pint = read("plain"), read("pint")
            assert not plain["pint"] and with_pint["pint"]
            times["files"].append(plain["cpu"])
            times["files + pint"].append(with_pint["cpu"])
            cpu, wall = command(os.path.join(root, str(k)))
            times["command cpu"].append(cpu)
            times["command wall"].append(wall)
    print(f"{args.rounds} rounds, load average {os.getloadavg()[0]:.1f}; seconds")
    print(f"{'':<46}{'best':>8}{'median':>8}")
    rows = [("read vsj's files (CPU)", "files"),
            ("  the same, pint imported and its registry built", "files + pint"),
            ("warm vsj simulate fig-4.15 (CPU)", "command cpu"),
            ("  (wall clock)", "command wall")]
    for text, key in rows:
        print(f"{text:<46}{min(times[key]):>8.2f}{statistics.median(times[key]):>8.2f}")
    cost = statistics.median(times["files + pint"]) - statistics.median(times["files"])
    print(f"pint costs a process {cost:.2f} s of CPU (median difference)"
          f"{'; it imports Dask' if with_pint['dask'] else ''}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

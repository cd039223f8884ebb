"""A long run streamed to disk: peak memory of `vsj simulate` for one simulated hour.

Issue 31: one hour of fig 4.15's motion at the default 1 ms output used to peak at
9.4-9.6 GB of resident memory. `vsj simulate` now writes each block of samples as it
comes; this measures the peak resident set size of the whole command with
``/usr/bin/time -v`` (Debian package ``time``) and prints it against the 500 MB target,
with the file's size and the wall time. A shorter run (``--duration``) checks the same
in less time; memory should not grow with the duration.

    python benchmarks/long_run.py [--duration "1 h"] [--keep DIR]
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGET_MB = 500.0


def scenario_text(duration: str) -> str:
    """fig 4.15's first case (q = -1.5 cm) for ``duration``, sampled every 1 ms."""
    from vsj import scenario

    text = (Path(scenario.__file__).parent / "data" / "scenarios" / "fig-4.15.toml").read_text()
    text = re.sub(r'duration = "[^"]*"', f'duration = "{duration}"', text, count=1)
    return text.split("[[cases]]")[0] + '[[cases]]\nlabel = "q=-1.5cm"\ninitial = { q = "-1.5 cm" }\n'


def peak_rss_mb(argv: list[str]) -> tuple[float, float, str]:
    timer = shutil.which("time", path="/usr/bin") or "/usr/bin/time"
    started = time.perf_counter()
    done = subprocess.run([timer, "-v", *argv], capture_output=True, text=True)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed:\n{done.stdout}\n{done.stderr}")
    kb = float(re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr).group(1))
    return kb / 1024.0, wall, done.stdout


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", default="1 h")
    parser.add_argument("--keep", help="directory to keep the output in")
    args = parser.parse_args()
    work = Path(tempfile.mkdtemp(prefix="vsj-long-"))
    try:
        spec = work / "long.toml"
        spec.write_text(scenario_text(args.duration))
        out = Path(args.keep) if args.keep else work / "out"
        vsj = str(Path(sys.executable).parent / "vsj")
        peak, wall, _ = peak_rss_mb([vsj, "simulate", str(spec), "--out", str(out),
                                     "--no-plot"])
        size = (out / "trajectory.nc").stat().st_size / 2 ** 20
        print(f"long run ({args.duration} of fig 4.15 at 1 ms output, one case): peak RSS "
              f"{peak:.0f} MB (target {TARGET_MB:.0f} MB: {peak / TARGET_MB:.2f} of it), "
              f"trajectory.nc {size:.0f} MB, {wall:.1f} s wall")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

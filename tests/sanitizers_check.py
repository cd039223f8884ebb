"""The engine under AddressSanitizer and UndefinedBehaviorSanitizer (see tests/sanitize.py).

Run by ``make sanitize`` (and so by ``.ci/run``), not by ``make test``: the instrumented
build and its workload are the longest single job of the suite. The job runs every
regression scenario, batches on two threads, the step function with each method, the C
example on good and bad model files, the FMU's C layer through FMPy, and the binding's
refusal of bad arrays, all through an instrumented build of the engine. Under AddressSanitizer the work's arrays are separated by poisoned
gaps (engine/c/model.c), so an overrun from one array into the next is reported too.
"""

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).with_name("sanitize.py")


def test_engine_runs_clean_under_the_sanitizers(tmp_path):
    done = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)], capture_output=True,
                          text=True, timeout=600)
    output = done.stdout + done.stderr
    assert done.returncode == 0, output[-4000:]
    assert "AddressSanitizer:" not in output and "runtime error:" not in output
    # every part of the workload ran
    for part in ("scenario fig-4.15-stiction", "end stops", "batch stiction", "step timestep",
                 "example timestep", "refusals"):
        assert part in output

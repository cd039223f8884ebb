"""Progress bars (`vsj.progress`): where standard error is not a terminal there is no bar,
and tqdm is not even imported (a short command's start would pay for it); what is wrapped
is iterated and counted all the same."""

import subprocess
import sys

CODE = """
import sys
from vsj.progress import progress
seen = list(progress(range(3), desc="cases", unit="case"))
bar = progress(None, desc="runs", unit="run", total=5)
bar.update(2)
bar.update()
bar.close()
print(seen == [0, 1, 2], "tqdm" in sys.modules)
"""


def test_no_bar_and_no_tqdm_off_a_terminal():
    done = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True,
                          check=True)  # standard error is a pipe here
    assert done.stdout.split() == ["True", "False"]
    assert done.stderr == ""

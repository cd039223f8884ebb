"""
The C example, built and run
============================

``examples/c/step_wrist.c`` is a controller's loop around the engine in plain C: it
loads a wrist that ``vsj export-model`` wrote and steps it one control period at a
time. This page exports a model, compiles the program with the system's C compiler from
the engine's sources alone, runs it for one second at 1 kHz with both primary motors
turning, and plots what it printed.
"""

import io
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import vsj
from vsj.cli import main

root = Path(vsj.__file__).resolve().parents[2]  # the repository (an editable install)
engine = root / "src" / "vsj" / "engine" / "c"
work = Path(tempfile.mkdtemp())

# %%
# Export the wrist: velocity-source motors, true stiction, pivot at q = -1 cm.
assert main(["export-model", "--out", str(work / "wrist.vsjm"), "--q=-1cm",
             "--friction", "stiction"]) == 0

# %%
# Build: the example and the engine's C files, nothing else.
cc = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
command = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-I", str(engine),
           "-o", str(work / "step_wrist"), str(root / "examples" / "c" / "step_wrist.c"),
           *sorted(str(p) for p in engine.glob("[a-z]*.c")), "-lm"]
print(" ".join(os.path.relpath(c, root) if c.startswith(str(root)) else c for c in command))
subprocess.run(command, check=True)

# %%
# Run 1000 periods. Each line of ``inputs.csv`` sets the input channels in the order the
# export listed them above (motor_1, motor_2, motor_s [rad/s], tau_x, tau_y [N m]);
# after its last line the last inputs are held, so the primary motors turn at +3 and
# -3 rad/s throughout.
(work / "inputs.csv").write_text("3, -3, 0, 0, 0\n")
done = subprocess.run([str(work / "step_wrist"), str(work / "wrist.vsjm"), "1000",
                       str(work / "inputs.csv")], check=True, capture_output=True, text=True)
names = done.stdout.splitlines()[0].split(",")
data = np.loadtxt(io.StringIO(done.stdout), delimiter=",", skiprows=1)
print(data.shape[0], "rows of", ", ".join(names))

fig, ax = plt.subplots(figsize=(6, 3.5))
for name in ("theta_x [rad]", "theta_y [rad]"):
    ax.plot(data[:, 0], data[:, names.index(name)], label=name)
ax.set_xlabel(names[0])
ax.legend()
fig.tight_layout()
plt.show()

"""
The MSL's Friction example against its reference
================================================

``vsj msl friction`` rebuilds ``Modelica.Mechanics.Rotational.Examples.Friction`` (a
torque source, three inertias, a clutch, a spring-damper and a brake) from vsj's
components, runs it with true stiction at 1 ms steps and compares every signal with the
Modelica Association's published reference result inside the MSL's regression tube.
The command prints each signal's tube and the stick/slip agreement, and exits 1 if any
signal leaves its tube.
"""

import tempfile
from pathlib import Path

import matplotlib.image
import matplotlib.pyplot as plt

from vsj.cli import main

out = Path(tempfile.mkdtemp()) / "msl"
code = main(["msl", "friction", "--out", str(out)])
assert code == 0, f"vsj msl friction exited with {code}"

image = matplotlib.image.imread(out / "msl-friction.png")
fig = plt.figure(figsize=(image.shape[1] / 100, image.shape[0] / 100), dpi=100)
fig.figimage(image)
plt.show()

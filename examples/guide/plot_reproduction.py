"""
The report's figures, reproduced
================================

``vsj reproduce`` regenerates every figure of the report beside the report's numbers
(the user guide's page on the reproduction says how to read it). Here two of them,
from cheaper runs (``--reduced``): fig 4.13, the VSM's stiffness against the pivot
position, and fig 4.15, the end-effector's tracking at five stiffness settings.
"""

import json
import tempfile
from pathlib import Path

import matplotlib.image
import matplotlib.pyplot as plt

from vsj.cli import main

out = Path(tempfile.mkdtemp()) / "reproduction"
code = main(["reproduce", "--reduced", "--only", "fig-4.13", "fig-4.15", "--out", str(out)])
assert code == 0, f"vsj reproduce exited with {code}"

# %%
# Each figure is a PNG (and an SVG) in the output directory, drawn by vsj; shown here
# as written.
for name in ("fig-4.13", "fig-4.15"):
    image = matplotlib.image.imread(out / f"{name}.png")
    fig = plt.figure(figsize=(image.shape[1] / 100, image.shape[0] / 100), dpi=100)
    fig.figimage(image)
plt.show()

# %%
# Every number the figures state is a row of ``results.json``, with the report's value
# where the report gives one, and a category that says what kind of agreement it is:
# for fig 4.13, the report's own eq 4.5 checked against its measured stiffness (report
# consistency), the geometric model at the three points its geometry was calibrated to
# (calibration targets), and the exponential law refitted to synthetic loops (by
# construction). None of them is a prediction: the headline does not count them.
results = json.loads((out / "results.json").read_text())
for row in results["rows"]:
    if row["figure"] == "fig-4.13":
        report = "not stated" if row["report"] is None else row["report"]
        print(f"[{row['category']}] {row['quantity']}: vsj {row['vsj']}, report {report} "
              f"({row['verdict']})")

"""
First fit
=========

Identification on data with a known truth: a synthetic fixed-sun bench measurement of
the planetary gear module (report section 4.1), made from the constants the report
fitted to its fig 4.4, is written to a CSV file as a bench would write it, read back
and fitted with report eq 4.2, ``T = c1 w + c2 atan(c3 w)``. The file says it is
synthetic, and so does every result made from it.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from vsj import measurements, synth
from vsj.identification.friction import fit_curve

truth = synth.REPORT_CONSTANTS[("second", "sun")]  # c1 [N m s/rad], c2 [N m], c3 [s/rad]
data = synth.friction(fixed="sun", constants=truth, seed=1)

path = Path(tempfile.mkdtemp()) / "sun.csv"
measurements.write(path, data.columns, data.comments)
print(path.read_text().splitlines()[0])
print("columns:", next(line for line in path.read_text().splitlines()
                        if not line.startswith("#")))

# %%
# The fit
# -------
# The file's constant-speed segments are found, their transients dropped and each
# averaged; the angle ripple is fitted beside the curve. Each constant comes with its
# standard error and 95 % interval.
fit = fit_curve(measurements.read(path, required=("velocity", "torque")))
for estimate, true in zip((fit.c1, fit.c2, fit.c3), truth):
    low, high = estimate.ci95
    print(f"{estimate.name} = {estimate.value:.4g} {estimate.unit} "
          f"(95 % interval {low:.4g} to {high:.4g}; truth {true:g})")

# %%
# Measured points against the fitted curve.
w = np.linspace(fit.velocity.min(), fit.velocity.max(), 400)
fig, ax = plt.subplots(figsize=(6, 4))
ax.plot(fit.velocity, fit.torque * 1e3, "o", label="segment means (synthetic)")
ax.plot(w, fit.predict(w) * 1e3, label="c1 w + c2 atan(c3 w)")
ax.set_xlabel("carrier speed [rad/s]")
ax.set_ylabel("torque [mN m]")
ax.legend()
fig.tight_layout()
plt.show()

# %%
# ``vsj synth friction`` and ``vsj fit friction`` do the same from the command line;
# the user guide's characterisation page shows the whole chain to a parameter file.

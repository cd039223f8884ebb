"""
First simulation
================

The whole wrist, simulated for five seconds with one primary motor turning back and
forth. The run reports whether it succeeded, what the solver did, and its energy
ledger, which must close for the run to count as a success.
"""

# %%
# The parameter set and the wrist
# -------------------------------
# `vsj.params.default` is the bundled set (report table 4.1 and eq 4.5 plus estimates,
# each with its source). `vsj.build_wrist` connects the sub-models as in report fig 3.1;
# `assemble` eliminates the rigid constraints once.
import vsj
from vsj.inputs import Sine

params = vsj.params.default()
print("transmission stiction:", params["transmission.stiction"], "N m")
wrist = vsj.build_wrist(params).assemble()

# %%
# A run
# -----
# Motor 1's speed follows a 0.5 Hz sine of 3 rad/s amplitude (``Sine(amplitude, frequency)``,
# faded in over the first second); the pivot starts at q = -0.4 cm.
result = vsj.simulate(wrist, {"motor_1": Sine(3.0, 0.5, fade_in=1.0)}, 5.0,
                      initial=vsj.InitialState(q=-0.004))
print(result.summary())

# %%
# Every signal is an array over ``result.time``, with its SI unit.
print(len(result.columns()), "signals, for example:", ", ".join(result.columns()[:6]))
print("theta_x ends at", f"{result['theta_x'][-1]:.4f}", result.units["theta_x"])

# %%
# The same from the command line
# ------------------------------
# The ``vsj`` command is a thin layer over the same library; here it is called in
# process to list the built-in scenarios that ``vsj simulate NAME`` runs.
from vsj.cli import main

main(["scenarios"])

"""
First plot
==========

The end-effector angle and a VSM spring's deflection at the stiffest and the most
compliant setting of fig 4.15 (q = -1.5 and +0.5 cm): the same motor motion, a stiff and
a soft setting of the variable stiffness mechanism. Every signal is a NumPy array over
``result.time``, so any plotting library draws it.
"""

import matplotlib.pyplot as plt

import vsj
from vsj.inputs import Sine

params = vsj.params.default()
wrist = vsj.build_wrist(params).assemble()
motion = {"motor_1": Sine(3.0, 0.5, fade_in=1.0), "motor_2": Sine(3.0, 0.5, fade_in=1.0)}

fig, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 5))
for q in (-0.015, 0.005):  # pivot position [m]: fig 4.15's stiffest and softest setting
    result = vsj.simulate(wrist, motion, 6.0, initial=vsj.InitialState(q=q))
    assert result.success, result.message
    label = f"q = {q * 100:+.1f} cm"
    top.plot(result.time, result["theta_x"], label=label)
    bottom.plot(result.time, result["phi_1"] * 1e3, label=label)
top.set_ylabel("theta_x [rad]")
bottom.set_ylabel("phi_1 [mrad]")
bottom.set_xlabel("time [s]")
top.legend()
fig.tight_layout()
plt.show()

# %%
# At the soft setting the springs deflect more under the same motion, and the
# end-effector lags its motors further: the trade-off of report fig 4.15.

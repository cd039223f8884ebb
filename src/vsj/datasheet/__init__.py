"""A datasheet of the wrist as a variable stiffness actuator, from the model.

In the spirit of Grioli et al. 2015, "Variable stiffness actuators: the
user's point of view" (Int. J. Robotics Research 34(6)): the quantities a user
needs to choose and control a VSA, computed from a parameter set rather than
measured. Everything is given at the end-effector about ``theta_x`` (the
motion that deflects both elastic elements equally, motors held) and, where
useful, at one elastic element (the ring deflection ``phi``):

* stiffness range and its dependence on the pivot position ``q``;
* torque-deflection curves and tangent stiffness at several ``q``;
* maximum deflection at each setting, with the limit that decides it (a ring's
  end stop, or the peak of the restoring torque, past which no load is held),
  and the torque there;
* elastic energy stored at that deflection;
* stiffness-change time and electric energy, from the softest to the
  stiffest setting and back, through the pivot mechanism driven by its DC
  motor at the supply voltage (`vsj.components.pivot`, `vsj.components.motor`);
* output inertia with the motors held;
* natural frequencies and damping against ``q``, Bode plots of the
  end-effector compliance and of the motor-to-output transfer, and the
  position bandwidth, from `vsj.linear`.

`compute` returns plain data (the JSON file); `write` adds the figures and
writes a self-contained HTML page (images embedded as base64 PNG) and the
JSON next to it. The numbers are the model's: where parameters are estimates
(the DC motors, the pivot drive, the spring geometry calibrated to the
report's three measured stiffnesses) the datasheet says so in its notes.

The package is split by job: `compute` (the numbers, without matplotlib),
`drawing` (the figures) and `page` (the HTML page and the JSON file).
"""

from .compute import CURVE_POINTS, DEFAULT_FRICTION, MAX_Q_POINTS, Statics, check_q_points, compute
from .drawing import figures
from .page import OUTPUT_BYTES, html_page, write

__all__ = ["compute", "check_q_points", "Statics", "figures", "html_page", "write",
           "CURVE_POINTS", "DEFAULT_FRICTION", "MAX_Q_POINTS", "OUTPUT_BYTES"]

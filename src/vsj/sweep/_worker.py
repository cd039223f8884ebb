"""What the fork server of a sweep's worker processes imports once (`vsj.sweep.schedulers`).

Each worker is forked from that server, so it starts with the modules a chunk needs
already imported and the unit registry already built (together more than a second
per process otherwise). Importing this module has that effect and no other.
"""

import scipy.linalg  # noqa: F401  (input splines: vsj.inputs.spline_pieces)
import scipy.stats  # noqa: F401  (probe values of sampled parameters)

from .. import scenario, units  # noqa: F401
from . import runner, sampling  # noqa: F401

units.registry()

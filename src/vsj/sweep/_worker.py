"""What the fork server of a sweep's worker processes imports once (`vsj.sweep.schedulers`).

Each worker is forked from that server, so it starts with the modules a chunk needs
already imported (a noticeable part of a second per process otherwise). Importing this
module has that effect and no other. A chunk converts no units through pint (the
scenario's units are among those `vsj.units` defines, and the parameter set arrives
resolved), so pint's registry is not built here; a rare unit that needs it is converted
on demand. Nor does a chunk need SciPy: the input splines are solved without it
(`vsj.inputs.spline_pieces`), and the job arrives with its pass-through parameters
found (`vsj.sweep.runner.probed`), so a worker draws no probe values (scipy.stats).
"""

from .. import scenario  # noqa: F401
from . import runner, sampling  # noqa: F401

"""What the fork server of a sweep's worker processes imports once (`vsj.sweep.schedulers`).

Each worker is forked from that server, so it starts with the modules a chunk needs
already imported (a noticeable part of a second per process otherwise). Importing this
module has that effect; in the server it also ties the server to the sweep
(`follow_fork_server`). A chunk converts no units through pint (the scenario's units
are among those `vsj.units` defines, and the parameter set arrives resolved), so pint's
registry is not built here; a rare unit that needs it is converted on demand. Nor does
a chunk need SciPy: the input splines are solved without it
(`vsj.inputs.spline_pieces`), and the job arrives with its pass-through parameters
found (`vsj.sweep.runner.probed`), so a worker draws no probe values (scipy.stats).
"""

import os
import sys

from .. import scenario  # noqa: F401
from ..engine.core import die_with_parent
from . import runner, sampling  # noqa: F401


def _in_fork_server() -> bool:
    """Whether this import runs in a fork server's start (multiprocessing.forkserver's
    `main` importing its preload modules) rather than in a process that imports vsj."""
    frame = sys._getframe(1)
    while frame is not None:
        code = frame.f_code
        if code.co_name == "main" and \
                code.co_filename.endswith(os.path.join("multiprocessing", "forkserver.py")):
            return True
        frame = frame.f_back
    return False


def follow_fork_server() -> None:
    """A worker's start (the pool's initializer): the worker ends with the fork server
    that forked it. Python's workers wait for work on a queue whose writing end they hold
    themselves, so a sweep killed outright (SIGKILL) left them, and the server they keep
    alive, running."""
    die_with_parent()


if _in_fork_server():  # the server ends with the sweep that started it
    die_with_parent()

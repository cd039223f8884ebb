"""vsj: model, simulate and characterise the 2-DOF variable stiffness joint.

The wrist of J.D. Zult's report (University of Twente, 2016) as a modular,
port-based model: sub-models in `vsj.components`, assembled by
`vsj.network`, simulated by `vsj.simulate`. Start with::

    import vsj
    params = vsj.params.default()
    wrist = vsj.build_wrist(params).assemble()
    result = vsj.simulate(wrist, {"motor_1": vsj.inputs.Sine(3.0, 0.5)}, 5.0)
"""

#: The package's version (pyproject.toml reads it from here).
__version__ = "0.2.1"

import os as _os  # noqa: E402
import sys as _sys  # noqa: E402


def _the_command() -> bool:
    """Whether this process is the ``vsj`` command: its script, or ``python -m vsj``
    (whose ``sys.argv[0]`` is ``-m`` while the package is found)."""
    first = (getattr(_sys, "argv", None) or [""])[0]
    if first == "-m":
        argv = list(getattr(_sys, "orig_argv", ()))
        return "-m" in argv and argv[argv.index("-m") + 1:][:1] == ["vsj"]
    return _os.path.basename(first) == "vsj"


if _the_command():
    # Before NumPy loads: OpenBLAS, NumPy's BLAS, then starts a thread on every other
    # core, and by default each spins for a while before it sleeps, after it starts and
    # after every product it shares. vsj runs its work side by side by runs (cases,
    # batches, sweeps), so in the command that spinning only takes cores from its own
    # threads. The shortest wait sends them to sleep at once; they still share the
    # products they shared, the same way, so every result keeps its bits. A value set
    # already wins.
    _os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", "4")

from . import inputs, params  # noqa: E402
from .network import Network  # noqa: E402
from .simulate import InitialState, Result, SimulationOptions, simulate  # noqa: E402
from .wrist import WristOptions, build_wrist  # noqa: E402

__all__ = ["InitialState", "Network", "Result", "SimulationOptions", "WristOptions",
           "build_wrist", "inputs", "params", "simulate", "__version__"]

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
__version__ = "0.2.0"

from . import inputs, params  # noqa: E402
from .network import Network  # noqa: E402
from .simulate import InitialState, Result, SimulationOptions, simulate  # noqa: E402
from .wrist import WristOptions, build_wrist  # noqa: E402

__all__ = ["InitialState", "Network", "Result", "SimulationOptions", "WristOptions",
           "build_wrist", "inputs", "params", "simulate", "__version__"]

"""Controllers in the loop: sampled controllers that the C engine runs beside the plant.

`Controller` declares one (its period, `Sensor` s, blocks `PID` and `Linear`, and
`Actuator` s); `vsj.simulate.simulate` and every driver of a `vsj.engine.Plan` run it.
See `vsj.control.controller` for the semantics.
"""

from .controller import (
    PID,
    Actuator,
    CompiledController,
    Controller,
    Linear,
    Sensor,
    compile_controller,
)

__all__ = ["Actuator", "CompiledController", "Controller", "Linear", "PID", "Sensor",
           "compile_controller"]

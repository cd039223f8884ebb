"""Controllers in the loop: sampled controllers that the C engine runs beside the plant.

`Controller` declares one (its period, `Sensor` s, blocks `PID` and `Linear`, and
`Actuator` s); `vsj.simulate.simulate` and every driver of a `vsj.engine.Plan` run it.
See `vsj.control.controller` for the semantics.

`vsj.control.design` designs observer-based state feedback (`lqr`, `pole_placement`,
with a `Kalman` or `Luenberger` estimator) on vsj's linear models with python-control,
schedules it over the stiffness setting (`GainSchedule`) and gives it as a
`Controller`; `pid_statespace` is a `PID` as a python-control system. Those names load
python-control (slow to import) on first use.

`vsj.control.wrist` builds controllers in the wrist's own coordinates (end-effector
angles and pivot position): `wrist_controller` (position control through the motors'
encoders), `impedance_controller` (a virtual spring-damper at the end-effector, in
series with the VSM's springs), and the discrete `virtual_spring_damper` with its
`passivity_bound`.

`vsj.control.callback.run_callback` closes the loop with a Python function, through the
step function, for prototyping.
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
from .wrist import (
    MotorPID,
    MotorPlant,
    WristKinematics,
    closed_loop_stiffness,
    impedance_controller,
    mechanical_stiffness,
    motor_plants,
    passivity_bound,
    virtual_spring_damper,
    virtual_stiffness_for,
    wrist_controller,
    wrist_kinematics,
)

#: names of vsj.control.design, imported on first use (it imports python-control)
_DESIGN = ("GainSchedule", "Kalman", "Luenberger", "StateFeedback", "discretize", "lqr",
           "pid_statespace", "pole_placement")


def __getattr__(name):
    if name in _DESIGN:
        from . import design  # lazy: python-control takes ~1 s to import

        return getattr(design, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["Actuator", "CompiledController", "Controller", "GainSchedule", "Kalman",
           "Linear", "Luenberger", "MotorPID", "MotorPlant", "PID", "Sensor", "StateFeedback",
           "WristKinematics", "closed_loop_stiffness", "compile_controller", "discretize",
           "impedance_controller", "lqr", "mechanical_stiffness", "motor_plants",
           "passivity_bound", "pid_statespace", "pole_placement", "virtual_spring_damper",
           "virtual_stiffness_for", "wrist_controller", "wrist_kinematics"]

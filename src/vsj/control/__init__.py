"""Controllers in the loop: sampled controllers that the C engine runs beside the plant.

`Controller` declares one (its period, `Sensor` s, blocks `PID` and `Linear`, and
`Actuator` s); `vsj.simulate.simulate` and every driver of a `vsj.engine.Plan` run it.
See `vsj.control.controller` for the semantics.

`vsj.control.wrist` builds controllers in the wrist's own coordinates (end-effector
angles and pivot position): `wrist_controller` (position control through the motors'
encoders), `impedance_controller` (a virtual spring-damper at the end-effector, in
series with the VSM's springs), and the discrete `virtual_spring_damper` with its
`passivity_bound`.
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

__all__ = ["Actuator", "CompiledController", "Controller", "Linear", "MotorPID", "MotorPlant",
           "PID", "Sensor", "WristKinematics", "closed_loop_stiffness", "compile_controller",
           "impedance_controller", "mechanical_stiffness", "motor_plants", "passivity_bound",
           "virtual_spring_damper", "virtual_stiffness_for", "wrist_controller",
           "wrist_kinematics"]

"""DC motor: armature circuit, rotor and gearhead, at a motor port.

``L di/dt = V - R i - k omega_rotor`` with torque ``k i`` on the rotor (one
constant ``k`` in SI for torque and back-EMF, as power balance requires). The
rotor has inertia and viscous friction; a gearhead of ``gear_ratio`` (rotor
turns per output turn) connects it to the output ``flange``. Interchangeable
with `vsj.components.basic.VelocitySource` at any of the three motor ports;
its input channel carries the armature voltage [V].
"""

from __future__ import annotations

import math

from ..network import Component, Constraint, Friction, Motor, Parts
from .basic import _positive


class DCMotor(Component):
    """Brushed DC motor with gearhead; ``voltage_limit`` [V] is its rating."""

    ports = ("flange",)

    def __init__(self, name: str, *, resistance: float, inductance: float,
                 torque_constant: float, rotor_inertia: float, gear_ratio: float = 1.0,
                 viscous: float = 0.0, channel: str | None = None,
                 voltage_limit: float = math.inf):
        super().__init__(name)
        self.resistance = _positive(f"{name}: resistance", resistance, allow_zero=False)
        self.inductance = _positive(f"{name}: inductance", inductance, allow_zero=False)
        self.torque_constant = _positive(f"{name}: torque_constant", torque_constant,
                                         allow_zero=False)
        self.rotor_inertia = _positive(f"{name}: rotor_inertia", rotor_inertia, allow_zero=False)
        if not (math.isfinite(gear_ratio) and gear_ratio != 0.0):
            raise ValueError(f"{name}: gear_ratio must be finite and nonzero")
        self.gear_ratio = float(gear_ratio)
        self.viscous = _positive(f"{name}: viscous", viscous)
        self.voltage_limit = _positive(f"{name}: voltage_limit", voltage_limit, allow_zero=False)
        self.channel = channel or name

    def parts(self) -> Parts:
        out = self.port("flange")
        rotor = self.node("rotor")
        return Parts(
            flanges=[out, rotor],
            inertia={rotor: self.rotor_inertia},
            constraints=[Constraint(f"{self.name} gearhead", {rotor: 1.0, out: -self.gear_ratio})],
            frictions=[Friction(f"{self.name}.rotor", {rotor: 1.0}, self.viscous, 0.0, 1.0,
                                law="viscous")],
            motors=[Motor(self.name, rotor, self.channel, self.resistance, self.inductance,
                          self.torque_constant, self.voltage_limit)],
            priority={rotor: 3},
        )

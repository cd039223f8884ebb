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
from ._values import _section


class DCMotor(Component):
    """Brushed DC motor with gearhead; ``voltage_limit`` [V] is its rating."""

    ports = ("flange",)

    def __init__(self, name: str, *, resistance: float, inductance: float,
                 torque_constant: float, rotor_inertia: float, gear_ratio: float = 1.0,
                 viscous: float = 0.0, channel: str | None = None,
                 voltage_limit: float = math.inf):
        super().__init__(name)
        values = _section(name, "motor", resistance=resistance, inductance=inductance,
                          torque_constant=torque_constant, rotor_inertia=rotor_inertia,
                          gear_ratio=gear_ratio, viscous=viscous)
        if voltage_limit != math.inf:  # no rating: any voltage
            values.update(_section(name, "motor", voltage_limit=voltage_limit))
        self.voltage_limit = float(voltage_limit)
        for key, value in values.items():
            setattr(self, key, value)
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

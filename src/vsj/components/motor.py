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

from ..network import Constraint, Friction, Motor, Parts
from ._fields import SchemaComponent, section


class DCMotor(SchemaComponent):
    """Brushed DC motor with gearhead, the ``[motor]`` section of a parameter file;
    ``channel`` (default: the motor's name) carries its voltage [V]. Left out,
    ``voltage_limit`` is ``inf``: no rating, any voltage."""

    ports = ("flange",)
    fields = section("motor", defaults={"gear_ratio": 1.0, "viscous": 0.0,
                                        "voltage_limit": math.inf})

    def __init__(self, name: str, *, channel: str | None = None, **values: float):
        super().__init__(name, **values)
        self.channel = channel or name

    def parts(self) -> Parts:
        """The rotor (an internal flange with the rotor inertia, viscous loss and the
        electrical model driven by the voltage channel) geared to the output flange by
        ``gear_ratio``."""
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

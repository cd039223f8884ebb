"""VSM pivot mechanism: the stiffness motor sets the pivot position q.

Report section 3.4, fig 3.12: a planetary set with its ring fixed turns the
motor's rotation into the straight motion of the pivot. The belt and the
planetary are one transformer of ``ratio`` (motor turns per carrier turn); the
carrier angle ``phi_C`` gives ``q = amplitude * sin(phi_C)`` where
``amplitude`` is the gain times the ring radius of the report. The gears'
inertia and friction load the motor; the springs do not push back on ``q``
(non-backdrivable, section 3.1), so the mechanism is a chain of its own.
``q_min`` and ``q_max`` bound the range a run may use (default: the whole
reach ``+-amplitude``); the engine fails a run that leaves it.
"""

from __future__ import annotations

import math

from ..network import Component, Constraint, Friction, Parts, Pivot
from ._fields import FRICTION, SchemaComponent, section


class PivotMechanism(SchemaComponent):
    """Motor flange ``input`` to pivot carrier; publishes the pivot position. Its
    parameters are the ``[pivot]`` section of a parameter file and the ``[friction]``
    law's sharpness and peak; ``q_min`` and ``q_max`` left out are the whole reach."""

    ports = ("input",)
    fields = section("pivot", defaults={"inertia": 0.0, "viscous": 0.0, "stiction": 0.0,
                                        "q_min": None, "q_max": None}) + FRICTION

    def __init__(self, name: str, **values: float):
        super().__init__(name, **values)
        if self.q_min is None:
            self.q_min = -self.amplitude
        if self.q_max is None:
            self.q_max = self.amplitude
        self.check_relations()  # the range and the reach, as a parameter file's

    def carrier_angle(self, q: float) -> float:
        """Carrier angle [rad] that places the pivot at ``q`` [m] (principal branch)."""
        if not abs(q) <= self.amplitude:
            raise ValueError(f"{self.name}: q = {q} m is beyond the mechanism's reach "
                             f"{self.amplitude} m")
        return math.asin(q / self.amplitude)

    def parts(self) -> Parts:
        """The motor flange geared (``ratio``) to the carrier, which carries the inertia,
        the gear friction and the pivot ``q = amplitude sin(phi_C)`` [m] within ``[q_min,
        q_max]``."""
        motor = self.port("input")
        carrier = self.node("carrier")
        return Parts(
            flanges=[motor, carrier],
            inertia={carrier: self.inertia},
            constraints=[Constraint(f"{self.name} transmission",
                                    {motor: 1.0, carrier: -self.ratio})],
            frictions=[Friction(f"{self.name}.gears", {carrier: 1.0}, self.viscous,
                                self.stiction, self.sharpness, peak=self.peak)],
            pivots=[Pivot(carrier, self.amplitude, q_min=self.q_min, q_max=self.q_max)],
            priority={carrier: 2},
        )


class FixedPivot(Component):
    """A pivot pinned at ``q`` [m] (the elastic-element bench of section 4.2.1)."""

    ports = ()

    def __init__(self, name: str, q: float):
        super().__init__(name)
        if not math.isfinite(q):
            raise ValueError(f"{name}: q must be finite, got {q!r}")
        self.q = float(q)

    def parts(self) -> Parts:
        """No flanges: only a pivot pinned at ``q`` [m]."""
        return Parts(pivots=[Pivot(None, fixed=self.q)])

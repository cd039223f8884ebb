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

from ..friction import DEFAULT_SHARPNESS
from ..network import Component, Constraint, Friction, Parts, Pivot
from ..params import SHARPNESS
from ._values import _check, _peak, _section


class PivotMechanism(Component):
    """Motor flange ``input`` to pivot carrier; publishes the pivot position."""

    ports = ("input",)

    def __init__(self, name: str, *, ratio: float, amplitude: float, inertia: float = 0.0,
                 viscous: float = 0.0, stiction: float = 0.0, sharpness: float = DEFAULT_SHARPNESS,
                 peak: float = 1.0, q_min: float | None = None, q_max: float | None = None):
        super().__init__(name)
        self.peak = _peak(name, peak)
        for key, value in _section(name, "pivot", ratio=ratio, amplitude=amplitude,
                                   inertia=inertia, viscous=viscous, stiction=stiction).items():
            setattr(self, key, value)
        self.sharpness = _check(f"{name}: sharpness", SHARPNESS, sharpness)
        self.q_min = -self.amplitude if q_min is None else float(q_min)
        self.q_max = self.amplitude if q_max is None else float(q_max)
        if not -self.amplitude <= self.q_min < self.q_max <= self.amplitude:
            raise ValueError(f"{name}: the pivot range [{self.q_min}, {self.q_max}] m must be "
                             f"increasing and within the reach +-{self.amplitude} m")

    def carrier_angle(self, q: float) -> float:
        """Carrier angle [rad] that places the pivot at ``q`` [m] (principal branch)."""
        if not abs(q) <= self.amplitude:
            raise ValueError(f"{self.name}: q = {q} m is beyond the mechanism's reach "
                             f"{self.amplitude} m")
        return math.asin(q / self.amplitude)

    def parts(self) -> Parts:
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
        return Parts(pivots=[Pivot(None, fixed=self.q)])

"""A unilateral compliant contact: the environment the end-effector touches.

`Contact` pushes its flanges apart along one direction when their positions overlap:
its penetration ``d = sum_p arm_p angle_p - gap`` [m] (each port's angle times its lever
arm [m/rad], so that a link of length L at an end-effector angle gives its tip's arc
L theta) is resisted by Hunt and Crossley's law

    F = k d^n + lambda d^n d'    (d > 0; never pulling: 0 where that is negative)

(K. H. Hunt and F. R. E. Crossley, "Coefficient of restitution interpreted as damping
in vibroimpact", J. Appl. Mech. 42, 1975), each port feeling ``-arm_p F``. ``n = 1``,
``lambda = 0`` is a linear contact spring, ``n = 3/2`` Hertz's law for a sphere on a
plane; the damping term vanishes with the penetration, so the force is continuous at
first touch and the coefficient of restitution depends on the impact speed (with
alpha = lambda / k, for small alpha v: e = 1 - (2/3) alpha v, Hunt and Crossley's own
relation). The engine
integrates it as an element of the network (law ``contact``, engine/c/vsj.h): its force
is a run's signal ``contact.<name>.force``, its energy enters the ledger (stored while
it is compressed, the rest dissipated).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from ..network import Component, Friction, Parts


def _finite(name: str, what: str, value, *, low: float, strict: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"contact {name!r}: {what} must be a number, got {value!r}") from None
    if not math.isfinite(v) or (v <= low if strict else v < low):
        raise ValueError(f"contact {name!r}: {what} must be finite and "
                         f"{'>' if strict else '>='} {low:g}, got {value!r}")
    return v


class Contact(Component):
    """A Hunt-Crossley contact on the weighted sum of its ports' angles.

    ``arms`` maps each port to its lever arm [m/rad] (the penetration grows as the sum of
    arm times angle grows; negative arms push the other way, as a body pushed back);
    ``stiffness`` k [N/m^n], ``exponent`` n >= 1, ``damping`` lambda [N s/m^(n+1)] (the
    damping force lambda d^n d'; Hunt and Crossley write it alpha k with alpha in s/m),
    ``gap`` [m] (the weighted sum at first touch).
    """

    def __init__(self, name: str, arms: Mapping[str, float], *, stiffness: float,
                 exponent: float = 1.0, damping: float = 0.0, gap: float = 0.0):
        super().__init__(name)
        if not arms:
            raise ValueError(f"contact {name!r}: give at least one port's lever arm")
        self.ports = tuple(arms)
        self.arms = {port: _finite(name, f"arm of {port!r}", a, low=-math.inf)
                     for port, a in arms.items()}
        if all(a == 0.0 for a in self.arms.values()):
            raise ValueError(f"contact {name!r}: every lever arm is zero")
        self.stiffness = _finite(name, "stiffness", stiffness, low=0.0, strict=True)
        self.exponent = _finite(name, "exponent", exponent, low=1.0)
        self.damping = _finite(name, "damping", damping, low=0.0)
        self.gap = _finite(name, "gap", gap, low=-math.inf)

    def parts(self) -> Parts:
        """One element of law ``contact`` on the ports' weighted angles."""
        speed = {self.port(p): a for p, a in self.arms.items()}
        return Parts(flanges=list(speed), frictions=[Friction(
            self.name, speed, law="contact",
            contact=(self.stiffness, self.exponent, self.damping, self.gap))])

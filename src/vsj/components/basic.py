"""Basic one- and two-flange elements: inertia, ground, sources, ideal gear,
bearing, spring-damper.

Port convention: `vsj.ports`. Each element here is ideal; losses and inertia
are added by composing elements (as in Modelica's Rotational library).
"""

from __future__ import annotations

import math

from ..friction import DEFAULT_SHARPNESS
from ..network import (
    PRESCRIBED,
    Component,
    Constraint,
    Friction,
    Load,
    Parts,
    Source,
    Spring,
)
from ..params import INERTIA, SHARPNESS, STIFFNESS, VISCOUS
from ..springs import LINEAR, N_PARAMETERS
from ._values import _check, _peak, _stiction


class Inertia(Component):
    """A rotational inertia ``J`` [kg m^2] on its flange."""

    ports = ("flange",)

    def __init__(self, name: str, inertia: float):
        super().__init__(name)
        self.inertia = _check(f"inertia of {name}", INERTIA, inertia)

    def parts(self) -> Parts:
        """One flange carrying ``inertia`` [kg m^2]."""
        f = self.port("flange")
        return Parts(flanges=[f], inertia={f: self.inertia}, priority={f: 1})


class Fixed(Component):
    """The ground: its flange does not move."""

    ports = ("flange",)

    def parts(self) -> Parts:
        """One flange held at rest by a constraint (it has the highest priority, so
        elimination keeps it prescribed)."""
        f = self.port("flange")
        return Parts(flanges=[f], constraints=[Constraint(f"{self.name} fixed", {f: 1.0})],
                     priority={f: PRESCRIBED})


class _Driven(Component):
    """A one-flange element driven by an input channel (named after it by default)."""

    ports = ("flange",)

    def __init__(self, name: str, channel: str | None = None):
        super().__init__(name)
        self.channel = channel or name


class VelocitySource(_Driven):
    """Ideal velocity source: the flange speed follows input ``channel`` [rad/s].

    Interchangeable with `vsj.components.motor.DCMotor` at a motor port (the
    report's final simulations use velocity sources, section 4.3).
    """

    def parts(self) -> Parts:
        """One flange whose speed [rad/s] the input channel prescribes."""
        f = self.port("flange")
        return Parts(flanges=[f], sources=[Source(self.name, f, self.channel)])


class TorqueSource(_Driven):
    """An applied torque from input ``channel`` [N m] (an external load)."""

    def parts(self) -> Parts:
        """One flange loaded by the input channel's torque [N m]."""
        f = self.port("flange")
        return Parts(flanges=[f], loads=[Load(self.name, f, self.channel)])


class IdealGear(Component):
    """Ideal gear pair: ``omega_a = ratio * omega_b`` (Modelica's IdealGear).

    Kinematic map ``omega_a = ratio omega_b``; by its transpose the torques
    satisfy ``tau_b = -ratio tau_a``, so no power is lost.
    """

    ports = ("a", "b")

    def __init__(self, name: str, ratio: float):
        super().__init__(name)
        if not (math.isfinite(ratio) and ratio != 0.0):
            raise ValueError(f"gear ratio of {name} must be finite and nonzero, got {ratio!r}")
        self.ratio = float(ratio)

    def speeds(self, omega_b: float) -> float:
        """Speed of flange a for a speed of flange b."""
        return self.ratio * omega_b

    def torques(self, tau_a: float) -> float:
        """Torque on flange b balancing a torque ``tau_a`` on flange a."""
        return -self.ratio * tau_a

    def parts(self) -> Parts:
        """Flanges a and b tied by the constraint ``omega_a - ratio omega_b = 0`` (the
        torques follow from its transpose)."""
        a, b = self.port("a"), self.port("b")
        return Parts(flanges=[a, b],
                     constraints=[Constraint(f"{self.name} gear", {a: 1.0, b: -self.ratio})])


class _FrictionElement(Component):
    """A friction element on a speed of its flanges (`_speed`): viscous [N m s/rad], the
    report's stiction parameter ``k`` [N m] given as ``stiction`` or as the Coulomb
    level ``coulomb`` (= k pi/2) [N m], arctan sharpness [s/rad] and breakaway peak."""

    def __init__(self, name: str, *, viscous: float = 0.0, stiction: float = 0.0,
                 sharpness: float = DEFAULT_SHARPNESS, peak: float = 1.0,
                 coulomb: float | None = None):
        super().__init__(name)
        self.viscous = _check(f"viscous friction of {name}", VISCOUS, viscous)
        self.stiction = _stiction(name, stiction, coulomb)
        self.sharpness = _check(f"arctan sharpness of {name}", SHARPNESS, sharpness)
        self.peak = _peak(name, peak)

    def _speed(self) -> dict[str, float]:
        raise NotImplementedError

    def parts(self) -> Parts:
        speed = self._speed()
        return Parts(flanges=list(speed), frictions=[Friction(
            self.name, speed, self.viscous, self.stiction, self.sharpness, peak=self.peak)])


class Bearing(_FrictionElement):
    """Friction between a flange and the ground, on the flange's absolute speed (the
    arguments of `_FrictionElement`)."""

    ports = ("flange",)

    def _speed(self) -> dict[str, float]:
        return {self.port("flange"): 1.0}


class SlipFriction(_FrictionElement):
    """Friction on the slip ``omega_a - omega_b`` between two flanges (a gear mesh, a
    sliding contact), with the arguments of `Bearing`."""

    ports = ("a", "b")

    def _speed(self) -> dict[str, float]:
        return {self.port("a"): 1.0, self.port("b"): -1.0}


class SpringDamper(Component):
    """A linear spring ``stiffness`` [N m/rad] and a damper ``damping`` [N m s/rad]
    in parallel between flanges ``a`` and ``b``, on the relative angle ``b - a``
    (Modelica's ``SpringDamper``; the spring is at rest where the angles agree)."""

    ports = ("a", "b")

    def __init__(self, name: str, *, stiffness: float, damping: float = 0.0):
        super().__init__(name)
        self.stiffness = _check(f"stiffness of {name}", STIFFNESS, stiffness)
        self.damping = _check(f"damping of {name}", VISCOUS, damping)

    def parts(self) -> Parts:
        """A linear spring of ``stiffness`` [N m/rad] from a to b, with a viscous damper of
        ``damping`` [N m s/rad] beside it if that is > 0."""
        a, b = self.port("a"), self.port("b")
        parts = Parts(flanges=[a, b], springs=[
            Spring(self.name, {b: 1.0, a: -1.0}, LINEAR,
                   (self.stiffness,) + (0.0,) * (N_PARAMETERS - 1))])
        if self.damping > 0.0:
            parts.frictions.append(Friction(f"{self.name}.damper", {b: 1.0, a: -1.0},
                                            self.damping, 0.0, 1.0, law="viscous",
                                            damper=True))
        return parts

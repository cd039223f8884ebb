"""What the wrist touches: walls and free bodies at the tip of its end-effector link.

An `Environment` is a link of length ``link`` [m] on the end-effector (its tip, of mass
``tip_mass`` [kg], at ``link * theta`` along the arc of each output angle), and the
contacts it may make: `Wall` s (a compliant surface on a rigid backing) and `Body` s (a
mass on a spring and damper to the ground: a surrogate of a hand or a lower arm,
ISO/TS 15066's two-body model). Each contact is a Hunt-Crossley element of the network
(`vsj.components.Contact`), so every driver runs it: its force is the signal
``contact.<name>.force`` [N], its energy enters the ledger, and true stiction holds a
joint pressed against a wall (the time-stepper solves the contact with the friction
impulses' step).

Geometry. The tip moves, for small angles, as ``link * (theta_x, theta_y)``; a contact
faces a ``direction`` in that plane (0: along theta_x, pi/2: along theta_y) and is
touched where the tip's angle along that direction reaches ``angle``:
``d = link * (cos(direction) theta_x + sin(direction) theta_y - angle)`` is the
penetration (for a body, minus its own displacement). The arc stands for the
straight-line motion of the tip: exact along one axis, and within (1 - cos) of the
angle's size elsewhere.

`add_environment` adds one to a network; `vsj.wrist` networks take it on their
``diff.theta_x`` and ``diff.theta_y`` flanges.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .components import Bearing, Contact, Fixed, Inertia, SpringDamper
from .errors import InputError, finite_number
from .network import Network, Signal
from .safety.iso_ts_15066 import Tip


_number = finite_number  # (where, value, low=, strict=)


@dataclass(frozen=True)
class Wall:
    """A compliant wall on a rigid backing, touched where the tip's angle along
    ``direction`` [rad] reaches ``angle`` [rad]: Hunt-Crossley ``stiffness`` k [N/m^n],
    ``exponent`` n >= 1 and ``damping`` lambda [N s/m^(n+1)] (`vsj.components.Contact`)."""

    name: str
    angle: float
    stiffness: float
    direction: float = 0.0
    exponent: float = 1.0
    damping: float = 0.0


@dataclass(frozen=True)
class Body:
    """A free body at rest where the tip's angle along ``direction`` reaches ``angle``:
    ``mass`` [kg] on a support of ``support_stiffness`` [N/m] and ``support_damping``
    [N s/m] to the ground, touched through a Hunt-Crossley contact (``stiffness``
    [N/m^n], ``exponent``, ``damping`` [N s/m^(n+1)]: the skin and tissue). Its
    displacement along the direction over the link is the signal ``<name>`` [rad] (times
    ``link``: metres), its speed ``<name>.speed``."""

    name: str
    angle: float
    mass: float
    stiffness: float
    support_stiffness: float = 0.0
    support_damping: float = 0.0
    direction: float = 0.0
    exponent: float = 1.0
    damping: float = 0.0


@dataclass(frozen=True)
class Environment:
    """The end-effector's link (``link`` [m], ``tip_mass`` [kg]) and its ``contacts``
    (`Wall` and `Body`). ``tip`` (`vsj.safety.Tip`: a flat face of given area or a
    sphere of given radius) is the tip's contact geometry, which turns a contact's force
    into the pressure ISO/TS 15066 bounds; without it a run's safety figures check the
    force alone."""

    link: float
    contacts: tuple = ()
    tip_mass: float = 0.0
    tip: Tip | None = None

    def check(self) -> None:
        """`InputError` naming the key for a bad value: a link <= 0, a negative mass,
        a stiffness <= 0, an exponent < 1, a negative damping, a body without mass, two
        contacts of one name."""
        _number("environment.link", self.link, low=0.0, strict=True)
        _number("environment.tip_mass", self.tip_mass, low=0.0)
        if self.tip is not None and not isinstance(self.tip, Tip):
            raise InputError(f"environment.tip: a vsj.safety.Tip (Tip.flat(area) or "
                             f"Tip.sphere(radius)), got {type(self.tip).__name__}")
        names = [getattr(c, "name", None) for c in self.contacts]
        for i, c in enumerate(self.contacts):
            where = f"environment.contacts[{i}] ({getattr(c, 'name', '?')})"
            if not isinstance(c, (Wall, Body)):
                raise InputError(f"{where}: a contact is a vsj.environment.Wall or Body, got "
                                 f"{type(c).__name__}")
            if not c.name or "." in c.name or names.count(c.name) > 1:
                raise InputError(f"{where}: name must be unique, non-empty, without '.'")
            _number(f"{where}.angle", c.angle)
            _number(f"{where}.direction", c.direction)
            _number(f"{where}.stiffness", c.stiffness, low=0.0, strict=True)
            _number(f"{where}.exponent", c.exponent, low=1.0)
            _number(f"{where}.damping", c.damping, low=0.0)
            if isinstance(c, Body):
                _number(f"{where}.mass", c.mass, low=0.0, strict=True)
                _number(f"{where}.support_stiffness", c.support_stiffness, low=0.0)
                _number(f"{where}.support_damping", c.support_damping, low=0.0)


def add_environment(net: Network, env: Environment, *, theta_x: str = "diff.theta_x",
                    theta_y: str | None = "diff.theta_y") -> Network:
    """``net`` with ``env`` at the tip of the link on the flanges ``theta_x`` and
    ``theta_y`` (None: a single-axis network; its contacts must face direction 0)."""
    env.check()
    L = float(env.link)
    axes = {"x": theta_x} if theta_y is None else {"x": theta_x, "y": theta_y}
    if env.tip_mass > 0.0:  # the tip's inertia about each axis (small angles)
        for port, flange in axes.items():
            tip = Inertia(f"tip_{port}", env.tip_mass * L * L)
            net.add(tip)
            net.connect(tip.port("flange"), flange)
    for c in env.contacts:
        cos, sin = math.cos(c.direction), math.sin(c.direction)
        if theta_y is None and abs(sin) > 1e-12:
            raise InputError(f"environment contact {c.name!r}: a single-axis network has no "
                             "theta_y; give it direction 0")
        arms = {"x": L * cos} if theta_y is None else {"x": L * cos, "y": L * sin}
        # cos(pi/2), sin(pi) are 1e-17, not 0: an axis the direction does not move is none
        arms = {p: a for p, a in arms.items() if abs(a) > 1e-12 * L}
        if isinstance(c, Body):
            arms["body"] = -L  # the body's displacement L phi_b opens the gap
        contact = Contact(c.name, arms, stiffness=c.stiffness, exponent=c.exponent,
                          damping=c.damping, gap=L * c.angle)
        net.add(contact)
        for port in arms:
            if port != "body":
                net.connect(contact.port(port), axes[port])
        if isinstance(c, Body):
            mass = Inertia(f"{c.name}_mass", c.mass * L * L)
            net.add(mass)
            net.connect(contact.port("body"), mass.port("flange"))
            if c.support_stiffness == 0.0 and c.support_damping > 0.0:  # a damper alone
                drag = Bearing(f"{c.name}_support", viscous=c.support_damping * L * L)
                net.add(drag)
                net.connect(drag.port("flange"), mass.port("flange"))
            elif c.support_stiffness > 0.0:
                ground = Fixed(f"{c.name}_ground")
                support = SpringDamper(f"{c.name}_support",
                                       stiffness=c.support_stiffness * L * L,
                                       damping=c.support_damping * L * L)
                net.add(ground, support)
                net.connect(support.port("a"), ground.port("flange"))
                net.connect(support.port("b"), mass.port("flange"))
            net.signal(Signal(c.name, mass.port("flange"),
                              f"body {c.name}'s displacement over the link (x {L:g} m: metres)"))
    return net


__all__ = ["Body", "Environment", "Wall", "add_environment"]

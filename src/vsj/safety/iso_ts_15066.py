"""The ISO/TS 15066:2016 body model for the hand and the lower arm, and what follows from
it: permissible contact force and pressure, transfer energy and the largest impact speed.

ISO/TS 15066:2016 ("Robots and robotic devices -- Collaborative robots"), Annex A,
models a body region hit by a robot as a free effective mass ``m_H`` behind a linear
spring ``k`` (Table A.3), and bounds the contact force and pressure (Table A.2). The
limits are given for *quasi-static* contact (the body part clamped) and *transient*
contact (free to recoil); Table A.2 gives the transient limits as multiples of the
quasi-static ones (note c), a factor of 2 for both regions here.

Two colliding bodies, the robot of effective mass ``m_R`` and the body region, share the
energy of their relative motion through the spring. With the reduced mass (eq A.3)
``mu = (1/m_H + 1/m_R)^-1`` and the robot's effective mass by the standard's rule
``m_R = M/2 + m_L`` (eq A.4; ``M`` the robot's moving mass, ``m_L`` its payload), the
energy a contact may transfer is ``E = F^2/(2k) = A^2 p^2/(2k)`` (eq A.1, ``A`` the
contact area), the kinetic energy of the relative motion is ``E = mu v_rel^2 / 2``
(eq A.2), so the largest relative speed is ``v_rel,max = F_max/sqrt(mu k)`` or
``p_max A/sqrt(mu k)`` (eq A.5, A.6). `transient_speed_limit` gives it; a different
contact stiffness (a cover, a compliant joint in series: `series_stiffness`) and the
robot's effective mass at each stiffness setting are the caller's, so settings can be
compared at the same verdict.

Where the values are from. The standard's text (a copy is hosted at
studylib.net/doc/27627297) could not be read past its first pages with the tools at hand,
so every value below was read from public transcriptions of its tables, listed in
`TRANSCRIPTIONS` (S1-S4 are files found through a code search index, named here by their
index ids). Each value names the standard's table and row, and which transcriptions give
it; where they give it, they agree. Three hand areas (forefinger pad ND, forefinger end
joint ND, back of the hand ND) are given by S2 alone, and S2 is the only source of the
D/ND attribution of the hand's rows. S2 lists the radial bone under the upper arm, S1
and S4 under the lower arm (S4 as area 14): the lower arm is kept. The equation numbers
(A.1)-(A.6) follow S1's order of the equations and S6's numbers, which S6 gives for the
annex of ISO 10218-2:2025 that took over the TS's method.

Only the two regions the wrist can touch are here: ``"hand"`` (Table A.2/A.3 body region
"Hands and fingers") and ``"lower_arm"`` ("Lower arms and wrist joints"). Pressure
limits are per specific body area (Table A.2, the areas of the region's rows); a check
that names no area uses the region's lowest (`BodyRegion.most_sensitive_area`). The
limits are pain-onset and minor-injury values for adults (Table A.2, notes a and b), for
blunt contact.

All quantities are SI: forces in N, pressures in Pa (1 N/cm^2 = 1e4 Pa), spring
constants in N/m (1 N/mm = 1e3 N/m), masses in kg, speeds in m/s, energies in J.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from collections.abc import Mapping

import numpy as np

from ..errors import InputError
from ._checks import number

#: The public transcriptions of ISO/TS 15066:2016 Annex A that the values were read
#: from, by the key the values cite.
TRANSCRIPTIONS = MappingProxyType({
    "S1": "a public GitHub file (code index id 7789312282): a ROS 2 power-and-force-limiting "
          "controller for UR robots whose docstrings transcribe Table A.2 (quasi-static "
          "pressure and force by body area), Table A.3 and the equations of Annex A",
    "S2": "public GitHub research notes (code index id 71559044313), 'Serpens safety design: "
          "source research', section B1, read by their author from a licensed copy of the "
          "standard: Table A.2 with its notes a-d, Table A.3",
    "S3": "a public GitHub source file (code index id 70110050492) quoting Annex A as read "
          "from the standard's text: Table A.2 forces, transient contact 'at least twice' "
          "the quasi-static, Table A.3 spring constants",
    "S4": "a public GitHub script (code index id 70922347437) quoting Table A.2, row 'Lower "
          "arms and wrist joints', as read from the standard's page images: areas 14-16, "
          "160 N quasi-static, transient multiplier 2 for force and pressure",
    "S5": "Svarny et al., '3D Collision-Force-Map for Safe Human-Robot Collaboration', "
          "arXiv:2009.01036, abstract: for the back of the hand, 280 N transient and 140 N "
          "quasi-static",
    "S6": "safety.stimba.sk/en/pfl, a calculator for ISO 10218-2:2025 Annex A (which took "
          "over the TS's method): eq (A.3) reduced mass, (A.4) robot effective mass, "
          "(A.5)/(A.6) largest speed by force/pressure; Table A.2 note c, transient at "
          "least 2x quasi-static",
})

#: The two kinds of contact of ISO/TS 15066 (clause 5.5.5.4 and Annex A).
CONTACTS = ("transient", "quasi-static")

#: 1 N/cm^2 in Pa, and 1 N/mm in N/m: the units of Tables A.2 and A.3.
N_PER_CM2 = 1e4
N_PER_MM = 1e3


@dataclass(frozen=True)
class BodyArea:
    """A specific body area of a region (a row of Table A.2) and its quasi-static pressure
    limit.

    Attributes
    ----------
    name : str
        Key (``"back_of_hand_dominant"``).
    title : str
        The area as Table A.2 names it (D: the dominant side, ND: the other).
    quasi_static_pressure : float
        Maximum permissible pressure for quasi-static contact [Pa].
    source : str
        The table and row, and which `TRANSCRIPTIONS` give the value.
    """

    name: str
    title: str
    quasi_static_pressure: float
    source: str


@dataclass(frozen=True)
class BodyRegion:
    """A body region of the ISO/TS 15066 body model.

    Attributes
    ----------
    name : str
        Key (``"hand"``, ``"lower_arm"``).
    title : str
        The region as Tables A.2 and A.3 name it.
    effective_mass : float
        ``m_H`` [kg], Table A.3.
    spring_constant : float
        ``k`` [N/m], Table A.3.
    quasi_static_force : float
        Maximum permissible force for quasi-static contact [N], Table A.2.
    transient_force_factor, transient_pressure_factor : float
        Multipliers of the quasi-static force and pressure for transient contact,
        Table A.2 (note c).
    areas : mapping of str to BodyArea
        The region's specific body areas with their pressure limits, Table A.2.
    sources : mapping of str to str
        For each attribute above, the table and row, and which `TRANSCRIPTIONS` give it.
    """

    name: str
    title: str
    effective_mass: float
    spring_constant: float
    quasi_static_force: float
    transient_force_factor: float
    transient_pressure_factor: float
    areas: Mapping[str, BodyArea]
    sources: Mapping[str, str] = field(repr=False)

    def permissible_force(self, contact: str = "transient") -> float:
        """Maximum permissible contact force [N] for ``contact`` (``"transient"`` or
        ``"quasi-static"``), Table A.2."""
        factor = self.transient_force_factor if _contact(contact) == "transient" else 1.0
        return factor * self.quasi_static_force

    def permissible_pressure(self, area: str | None = None,
                             contact: str = "transient") -> float:
        """Maximum permissible pressure [Pa] on body ``area`` (default: the region's most
        sensitive) for ``contact``, Table A.2."""
        factor = self.transient_pressure_factor if _contact(contact) == "transient" else 1.0
        return factor * self.area(area).quasi_static_pressure

    def area(self, name: str | None = None) -> BodyArea:
        """The body area called ``name`` (default: `most_sensitive_area`)."""
        if name is None:
            return self.most_sensitive_area
        if name not in self.areas:
            raise InputError(f"body area {name!r} is not an area of region {self.name!r} "
                             f"({self.title}); its areas: {', '.join(self.areas)}")
        return self.areas[name]

    @property
    def most_sensitive_area(self) -> BodyArea:
        """The area with the lowest pressure limit (the first such, in table order)."""
        return min(self.areas.values(), key=lambda a: a.quasi_static_pressure)


def _contact(contact: str) -> str:
    if contact not in CONTACTS:
        raise InputError(f"contact must be one of {', '.join(map(repr, CONTACTS))}, "
                         f"got {contact!r}")
    return contact


def _areas(region: str, rows) -> Mapping[str, BodyArea]:
    return MappingProxyType({
        key: BodyArea(key, title, pressure * N_PER_CM2,
                      f"ISO/TS 15066:2016 Table A.2, region '{region}', area '{title}', "
                      f"maximum permissible pressure, quasi-static contact; {given}")
        for key, title, pressure, given in rows})


def _region(name, title, mass, k, force, factor, areas, given) -> BodyRegion:
    where = f"row '{title}'"
    return BodyRegion(
        name=name, title=title, effective_mass=mass, spring_constant=k * N_PER_MM,
        quasi_static_force=force, transient_force_factor=factor,
        transient_pressure_factor=factor, areas=_areas(title, areas),
        sources=MappingProxyType({
            "effective_mass": f"ISO/TS 15066:2016 Table A.3, {where}, effective mass m_H; "
                              f"{given['table_a3']}",
            "spring_constant": f"ISO/TS 15066:2016 Table A.3, {where}, effective spring "
                               f"constant K; {given['table_a3']}",
            "quasi_static_force": f"ISO/TS 15066:2016 Table A.2, {where}, maximum "
                                  f"permissible force, quasi-static contact; "
                                  f"{given['force']}",
            "transient_force_factor": f"ISO/TS 15066:2016 Table A.2, {where}, transient "
                                      f"contact, maximum permissible force multiplier "
                                      f"(note c); {given['factor']}",
            "transient_pressure_factor": f"ISO/TS 15066:2016 Table A.2, {where}, transient "
                                         f"contact, maximum permissible pressure multiplier "
                                         f"(note c); {given['factor']}",
        }))


#: The body regions the wrist can touch, by key. Pressures in N/cm^2 and spring constants
#: in N/mm as the tables give them, converted to SI on construction.
REGIONS: Mapping[str, BodyRegion] = MappingProxyType({
    "hand": _region(
        "hand", "Hands and fingers", mass=0.6, k=75.0, force=140.0, factor=2.0,
        areas=(
            ("forefinger_pad_dominant", "Forefinger pad D", 300.0, "given by S1, S2"),
            ("forefinger_pad_non_dominant", "Forefinger pad ND", 270.0, "given by S2"),
            ("forefinger_end_joint_dominant", "Forefinger end joint D", 280.0,
             "given by S1, S2"),
            ("forefinger_end_joint_non_dominant", "Forefinger end joint ND", 220.0,
             "given by S2"),
            ("thenar_eminence", "Thenar eminence", 200.0, "given by S1, S2"),
            ("palm", "Palm", 260.0, "given by S1, S2 (the same for D and ND)"),
            ("back_of_hand_dominant", "Back of the hand D", 200.0, "given by S1, S2"),
            ("back_of_hand_non_dominant", "Back of the hand ND", 190.0, "given by S2"),
        ),
        given={"table_a3": "given by S1, S2 (k also S3)", "force": "given by S1-S3, S5",
               "factor": "given by S2, S3, S5, S6"}),
    "lower_arm": _region(
        "lower_arm", "Lower arms and wrist joints", mass=2.0, k=40.0, force=160.0,
        factor=2.0,
        areas=(
            ("radial_bone", "Radial bone", 190.0, "given by S1, S2, S4"),
            ("forearm_muscle", "Forearm muscle", 180.0, "given by S1, S2, S4"),
            ("arm_nerve", "Arm nerve", 180.0, "given by S1, S2, S4"),
        ),
        given={"table_a3": "given by S1, S2 (k also S3)", "force": "given by S1-S4",
               "factor": "given by S2-S4, S6"}),
})


def region(name: str | BodyRegion) -> BodyRegion:
    """The body region called ``name`` (``"hand"`` or ``"lower_arm"``); a `BodyRegion`
    is returned as it is."""
    if isinstance(name, BodyRegion):
        return name
    if not isinstance(name, str) or name not in REGIONS:
        raise InputError(f"region {name!r} is not known; known regions: "
                         f"{', '.join(REGIONS)} (ISO/TS 15066:2016 Tables A.2, A.3)")
    return REGIONS[name]


def reduced_mass(body_mass: float, robot_mass: float) -> float:
    """Reduced mass ``mu = (1/m_H + 1/m_R)^-1`` [kg] of the two-body system (ISO/TS 15066
    eq A.3). ``robot_mass`` may be ``inf`` (a robot that the contact does not slow):
    ``mu = m_H``."""
    m_h = number("reduced_mass", "body_mass", body_mass, "kg")
    m_r = number("reduced_mass", "robot_mass", robot_mass, "kg", allow_inf=True)
    return m_h if math.isinf(m_r) else m_h * m_r / (m_h + m_r)


def robot_effective_mass(moving_mass: float, payload: float = 0.0) -> float:
    """The standard's estimate of the robot's effective mass ``m_R = M/2 + m_L`` [kg]
    (ISO/TS 15066 eq A.4): half the total mass ``M`` of the robot's moving parts plus the
    effective payload ``m_L`` (tool and workpiece). A model that gives the effective mass
    at the contact point (the inverse of its mobility there) should use that instead."""
    m = number("robot_effective_mass", "moving_mass", moving_mass, "kg")
    load = number("robot_effective_mass", "payload", payload, "kg", positive=False)
    return m / 2.0 + load


def series_stiffness(*stiffnesses: float) -> float:
    """Stiffness [N/m] of linear springs in series, ``(sum 1/k_i)^-1``: the body's
    spring behind a cover or a compliant transmission reflected to the contact point
    (an ``inf`` entry is a rigid link and drops out)."""
    if not stiffnesses:
        raise InputError("series_stiffness: give at least one stiffness [N/m]")
    ks = [number("series_stiffness", f"stiffness {i + 1}", k, "N/m", allow_inf=True)
          for i, k in enumerate(stiffnesses)]
    compliance = sum(0.0 if math.isinf(k) else 1.0 / k for k in ks)
    return math.inf if compliance == 0.0 else 1.0 / compliance


@dataclass(frozen=True)
class SpeedLimit:
    """The largest relative impact speed within a region's limits (`transient_speed_limit`).

    Attributes
    ----------
    speed : float
        The largest speed [m/s]: the smaller of the two below.
    by_force : float
        ``F_max / sqrt(mu k)`` [m/s] (eq A.5).
    by_pressure : float or None
        ``p_max A / sqrt(mu k)`` [m/s] (eq A.6); None without a contact area.
    reduced_mass : float
        ``mu`` [kg] (eq A.3).
    stiffness : float
        ``k`` [N/m] used.
    energy : float
        The transfer energy allowed, ``mu speed^2 / 2`` [J] (eq A.1, A.2).
    """

    speed: float
    by_force: float
    by_pressure: float | None
    reduced_mass: float
    stiffness: float
    energy: float

    @property
    def limited_by(self) -> str:
        """``"force"`` or ``"pressure"``: which limit sets `speed`."""
        pressure = self.by_pressure is not None and self.by_pressure < self.by_force
        return "pressure" if pressure else "force"


def transient_speed_limit(body: str | BodyRegion, robot_mass: float,
                          stiffness: float | None = None, contact_area: float | None = None,
                          area: str | None = None,
                          contact: str = "transient") -> SpeedLimit:
    """Largest relative speed [m/s] at which a robot of effective mass ``robot_mass`` [kg]
    may strike body region ``body`` and stay within its permissible force (and pressure,
    given ``contact_area``).

    The closed form of ISO/TS 15066 Annex A (eq A.1-A.6): the relative motion's kinetic
    energy ``mu v^2/2`` is all stored in a linear contact spring ``k`` at the instant of
    peak force, so ``F_peak = v sqrt(mu k)``. It is exact for two free masses meeting
    through one linear spring, and an estimate for anything else.

    Parameters
    ----------
    body : str or BodyRegion
        ``"hand"`` or ``"lower_arm"``.
    robot_mass : float
        The robot's effective mass at the contact point in the direction of the impact
        [kg] (`robot_effective_mass` gives the standard's estimate); ``inf`` for a robot
        the contact does not slow.
    stiffness : float, optional
        Contact stiffness [N/m]; default the region's spring constant (Table A.3). Give
        the series stiffness of the body and the robot's compliance at the contact
        (`series_stiffness`) to compare stiffness settings.
    contact_area : float, optional
        Contact area [m^2] (the smaller of the robot's and the body's surface in
        contact); with it the pressure limit of ``area`` applies as well.
    area : str, optional
        The body area whose pressure limit applies (default: the region's most
        sensitive).
    contact : str
        ``"transient"`` (default; the body part can recoil) or ``"quasi-static"``.
    """
    where = "transient_speed_limit"
    reg = region(body)
    mu = reduced_mass(reg.effective_mass, robot_mass)
    k = reg.spring_constant if stiffness is None else number(where, "stiffness", stiffness,
                                                             "N/m")
    root = math.sqrt(mu * k)
    by_force = reg.permissible_force(contact) / root
    by_pressure = None
    if contact_area is not None:
        a = number(where, "contact_area", contact_area, "m^2")
        by_pressure = reg.permissible_pressure(area, contact) * a / root
    elif area is not None:
        raise InputError(f"{where}: area {area!r} names a pressure limit, which needs "
                         f"contact_area [m^2]")
    speed = by_force if by_pressure is None else min(by_force, by_pressure)
    return SpeedLimit(speed, by_force, by_pressure, mu, k, 0.5 * mu * speed ** 2)


def transfer_energy_limit(body: str | BodyRegion, stiffness: float | None = None,
                          contact_area: float | None = None, area: str | None = None,
                          contact: str = "transient") -> float:
    """Largest energy [J] a contact may transfer to ``body``: ``F_max^2/(2k)``, and no
    more than ``A^2 p_max^2/(2k)`` given ``contact_area`` ``A`` [m^2] (ISO/TS 15066
    eq A.1). ``stiffness`` [N/m] defaults to the region's spring constant."""
    where = "transfer_energy_limit"
    reg = region(body)
    k = reg.spring_constant if stiffness is None else number(where, "stiffness", stiffness,
                                                             "N/m")
    force = reg.permissible_force(contact)
    if contact_area is not None:
        a = number(where, "contact_area", contact_area, "m^2")
        force = min(force, reg.permissible_pressure(area, contact) * a)
    elif area is not None:
        raise InputError(f"{where}: area {area!r} names a pressure limit, which needs "
                         f"contact_area [m^2]")
    return force ** 2 / (2.0 * k)


@dataclass(frozen=True)
class Tip:
    """The geometry of the robot's contact surface, which turns a contact force into a
    pressure.

    ``Tip.flat(area)`` touches over a fixed ``area`` [m^2] (a flat face smaller than the
    body part). ``Tip.sphere(radius)`` is a rounded tip of radius ``R`` [m] pressed
    ``d`` [m] into an elastic half-space: Hertz contact, whose contact circle has radius
    ``a = sqrt(R d)``, so the area is ``pi R d``, up to ``pi R^2`` (a hemisphere fully
    in). The pressure is the mean over that area, ``F / A``, the quantity Table A.2
    bounds.
    """

    kind: str
    size: float

    def __post_init__(self):
        if self.kind not in ("flat", "sphere"):
            raise InputError(f"Tip: kind must be 'flat' or 'sphere', got {self.kind!r}")
        unit = "m^2" if self.kind == "flat" else "m"
        number(f"Tip ({self.kind})", "area" if self.kind == "flat" else "radius", self.size,
               unit)

    @classmethod
    def flat(cls, area: float) -> "Tip":
        """A flat face in full contact over ``area`` [m^2]."""
        return cls("flat", number("Tip.flat", "area", area, "m^2"))

    @classmethod
    def sphere(cls, radius: float) -> "Tip":
        """A spherical tip of ``radius`` [m]."""
        return cls("sphere", number("Tip.sphere", "radius", radius, "m"))

    @property
    def needs_penetration(self) -> bool:
        """Whether the area depends on how deep the tip is in (a sphere's does)."""
        return self.kind == "sphere"

    def area(self, penetration=None) -> np.ndarray:
        """Contact area [m^2] at ``penetration`` [m] (ignored for a flat tip; none where
        the tip is not in, ``penetration <= 0``)."""
        if self.kind == "flat":
            return np.full(np.shape(penetration) if penetration is not None else (), self.size)
        if penetration is None:
            raise InputError("Tip.area: a spherical tip's area needs the penetration [m]")
        d = np.asarray(penetration, dtype=float)
        return math.pi * self.size * np.clip(d, 0.0, self.size)

    def pressure(self, force, penetration=None) -> np.ndarray:
        """Mean contact pressure ``F / A`` [Pa]; ``inf`` where a positive force acts on no
        area (a sphere touching at a point)."""
        f = np.asarray(force, dtype=float)
        a = self.area(penetration)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(f > 0, f / a, 0.0)


@dataclass(frozen=True)
class Verdict:
    """A contact checked against a region's limits (`verdict`).

    Attributes
    ----------
    region, contact : str
        The body region and the kind of contact checked.
    force, force_limit : float
        Peak contact force and its permissible value [N].
    pressure, pressure_limit : float or None
        Peak pressure and its permissible value on ``area`` [Pa]; None when no pressure
        was given.
    area : str or None
        The body area whose pressure limit applied.
    """

    region: str
    contact: str
    force: float
    force_limit: float
    pressure: float | None
    pressure_limit: float | None
    area: str | None

    @property
    def force_ratio(self) -> float:
        """``force / force_limit`` (1 is at the limit)."""
        return self.force / self.force_limit

    @property
    def pressure_ratio(self) -> float | None:
        """``pressure / pressure_limit``, or None."""
        return None if self.pressure is None else self.pressure / self.pressure_limit

    @property
    def passed(self) -> bool:
        """Whether force and pressure are within their limits (equal to a limit passes:
        the table gives maximum permissible values)."""
        pressure_ok = self.pressure is None or self.pressure_ratio <= 1.0
        return self.force_ratio <= 1.0 and pressure_ok

    def __str__(self) -> str:
        text = (f"{self.region} ({self.contact}): force {self.force:.4g} N of "
                f"{self.force_limit:.4g} N ({100 * self.force_ratio:.1f} %)")
        if self.pressure is not None:
            text += (f", pressure {self.pressure / N_PER_CM2:.4g} N/cm^2 of "
                     f"{self.pressure_limit / N_PER_CM2:.4g} N/cm^2 on {self.area} "
                     f"({100 * self.pressure_ratio:.1f} %)")
        return text + (": within the limits" if self.passed else ": OVER the limit")


def verdict(body: str | BodyRegion, peak_force: float, peak_pressure: float | None = None,
            contact: str = "transient", area: str | None = None) -> Verdict:
    """Check a contact's ``peak_force`` [N] (and ``peak_pressure`` [Pa]) against body
    region ``body``'s permissible values for ``contact`` (ISO/TS 15066 Table A.2).

    The pressure is checked against body ``area`` (default: the region's most sensitive);
    `ContactEvent.verdict` passes an event's peaks.
    """
    reg = region(body)
    force = number("verdict", "peak_force", peak_force, "N", positive=False)
    if peak_pressure is None:
        if area is not None:
            reg.area(area)
        return Verdict(reg.name, _contact(contact), force, reg.permissible_force(contact),
                       None, None, None)
    pressure = number("verdict", "peak_pressure", peak_pressure, "Pa", positive=False,
                      allow_inf=True)
    chosen = reg.area(area)
    return Verdict(reg.name, _contact(contact), force, reg.permissible_force(contact),
                   pressure, reg.permissible_pressure(chosen.name, contact), chosen.name)

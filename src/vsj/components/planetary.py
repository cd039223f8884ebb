"""Planetary gear module: sun, ring and carrier with mesh and bearing friction.

Report section 3.3. The ideal gear set is a three-port transformer (eq 3.9-3.11):

    omega_C = r_RC omega_R + r_SC omega_S,
    r_RC = N_R / (N_R + N_S),   r_SC = N_S / (N_R + N_S)

and its torques are the transpose of that map (`IdealPlanetary.torques`).
`PlanetaryGearModule` adds, by composition (fig 3.10):

* mesh friction on the sun-carrier slip ``omega_S - omega_C`` (stiction
  ``k_1``, arctan sharpness ``k_b1``) and on the ring-carrier slip
  ``omega_R - omega_C``, whose constants ``k_a2``, ``k_b2`` follow from
  ``k_1``, ``k_b1`` by one of two relations (`MESH_RELATIONS`, below);
* bearing friction (viscous and stiction) on each absolute speed, the
  stiction the report added after its measurements (section 4.1.3, table 4.1);
* the inertias of sun, ring and carrier "and what is attached to them".

Eq 3.27, the ring mesh's friction constants (``x = N_S/N_R``):

``"printed"`` (default)
    ``k_a2 = x k_1``, ``k_b2 = k_b1 / x``, as the report prints it. The report
    states equal tangential forces at both meshes as its assumption, but its
    eq 3.23-3.24 multiply by the pitch radii where they should divide, so under
    this relation the ring mesh's tangential force, and with the sun fixed the
    power it dissipates, is ``x^2`` times the sun mesh's (0.10 at x = 0.32);
    with equal forces the two meshes dissipate alike. It stays the default
    because table 4.1's ``k_1`` was derived from the measured curves with it:
    changing the relation without re-deriving ``k_1`` would no longer be table
    4.1's model.
``"equal-force"``
    ``k_a2 = k_1 / x``, ``k_b2 = k_b1 / x``: what the stated assumption gives
    with torque = force x pitch radius (eq 3.14). The physically consistent
    relation, offered as an option (docs/model-notes/planetary.md, eq 3.27 corrected).

With the sun fixed and the carrier driven at ``w``, the module's steady
friction torque is ``(b_C + b_R (1+x)^2) w + M_sun(w)`` plus the bearing
stiction terms, with the mesh term ``M_sun = k_1 (1+x^2) atan(k_b1 w)``
(printed) or ``2 k_1 atan(k_b1 w)`` (equal force) (eq 3.28 as restated in
docs/model-notes/planetary.md; the extracted report text loses the fractions). With the ring
fixed: ``(b_C + b_S (1+1/x)^2) w + M_ring(w)``, ``M_ring = k_1 (x+1/x)
atan(k_b1 w / x)`` or ``(2 k_1 / x) atan(k_b1 w / x)`` (eq 3.29).
`closed_form_torque` gives both test configurations, bearing stiction included.
"""

from __future__ import annotations

import numpy as np

from .. import friction
from ..friction import DEFAULT_SHARPNESS
from ..network import Component, Constraint, Parts
from ._fields import Field, SchemaComponent, section
from .basic import Bearing, Inertia, SlipFriction

#: Relations of eq 3.27 between the sun mesh's friction constants (k_1, k_b1) and the
#: ring mesh's (k_a2, k_b2), as functions of x = N_S/N_R: (k_a2 / k_1, k_b2 / k_b1).
MESH_RELATIONS = {
    "printed": lambda x: (x, 1.0 / x),
    "equal-force": lambda x: (1.0 / x, 1.0 / x),
}


class IdealPlanetary(Component):
    """The kinematics of eq 3.9 only: no inertia, no friction, no losses."""

    ports = ("sun", "ring", "carrier")

    def __init__(self, name: str, sun_teeth: float, ring_teeth: float):
        super().__init__(name)
        # the tooth counts' bounds are those of their [planetary] entries
        self.sun_teeth = Field("sun_teeth", "planetary.sun_teeth").take(name, sun_teeth)
        self.ring_teeth = Field("ring_teeth", "planetary.ring_teeth").take(name, ring_teeth)

    @property
    def r_RC(self) -> float:
        """Ring-to-carrier ratio N_R / (N_R + N_S) (eq 3.11)."""
        return self.ring_teeth / (self.ring_teeth + self.sun_teeth)

    @property
    def r_SC(self) -> float:
        """Sun-to-carrier ratio N_S / (N_R + N_S) (eq 3.11)."""
        return self.sun_teeth / (self.ring_teeth + self.sun_teeth)

    def speeds(self, ring_speed, sun_speed):
        """Carrier speed for given ring and sun speeds (eq 3.10)."""
        return self.r_RC * np.asarray(ring_speed) + self.r_SC * np.asarray(sun_speed)

    def torques(self, carrier_torque):
        """``(ring, sun)`` torques that the gear set holds against ``carrier_torque``.

        The transpose of `speeds`: a torque ``tau_C`` on the carrier is balanced
        by ``-r_RC tau_C`` on the ring and ``-r_SC tau_C`` on the sun.
        """
        tau = np.asarray(carrier_torque)
        return -self.r_RC * tau, -self.r_SC * tau

    def parts(self) -> Parts:
        """Sun, ring and carrier tied by the one kinematic constraint ``omega_C = r_RC
        omega_R + r_SC omega_S`` (report eq 3.9-3.10)."""
        s, r, c = (self.port(p) for p in self.ports)
        row = {c: 1.0, r: -self.r_RC, s: -self.r_SC}
        return Parts(flanges=[s, r, c], constraints=[Constraint(f"{self.name} gear set", row)],
                     priority={c: 1})


#: The flanges of the module, each with an inertia and a bearing.
PORTS = ("sun", "ring", "carrier")


class PlanetaryGearModule(SchemaComponent):
    """A planetary gear set with inertias, mesh friction and bearing friction, built
    by composition (fig 3.10): the `IdealPlanetary`, an `Inertia` and a `Bearing`
    on each of sun, ring and carrier, and the sun mesh's `SlipFriction`; the ring
    mesh follows from the sun mesh by eq 3.27 (``mesh_relation``, see the module
    docstring). Its parameters are the ``[planetary]`` section of a parameter file
    (only the tooth counts are required: a part left out is absent) and the
    ``[friction]`` law's sharpness for the bearings (``bearing_sharpness``; left
    out, the mesh's) and breakaway ``peak`` for every element.
    """

    ports = PORTS
    fields = section("planetary", defaults={
        "sun_inertia": 0.0, "ring_inertia": 0.0, "carrier_inertia": 0.0,
        "sun_bearing_viscous": 0.0, "sun_bearing_stiction": 0.0,
        "ring_bearing_viscous": 0.0, "ring_bearing_stiction": 0.0,
        "carrier_bearing_viscous": 0.0, "carrier_bearing_stiction": 0.0,
        "mesh_stiction": 0.0, "mesh_sharpness": DEFAULT_SHARPNESS,
    }) + section("friction", rename={"arctan_sharpness": "bearing_sharpness"},
                 defaults={"bearing_sharpness": None})

    def __init__(self, name: str, *, mesh_relation: str = "printed", **values: float):
        super().__init__(name, **values)
        self.gears = IdealPlanetary("gears", self.sun_teeth, self.ring_teeth)
        if mesh_relation not in MESH_RELATIONS:
            raise ValueError(f"{name}: mesh_relation must be one of "
                             f"{', '.join(MESH_RELATIONS)}, got {mesh_relation!r}")
        self.mesh_relation = mesh_relation
        inertia = {"sun": self.sun_inertia, "ring": self.ring_inertia,
                   "carrier": self.carrier_inertia}
        viscous = {"sun": self.sun_bearing_viscous, "ring": self.ring_bearing_viscous,
                   "carrier": self.carrier_bearing_viscous}
        stiction = {"sun": self.sun_bearing_stiction, "ring": self.ring_bearing_stiction,
                    "carrier": self.carrier_bearing_stiction}
        sharpness = (self.mesh_sharpness if self.bearing_sharpness is None
                     else self.bearing_sharpness)
        self.inertias = {port: Inertia(f"{port}_inertia", inertia[port]) for port in PORTS}
        self.bearings = {port: Bearing(f"bearing_{port}", viscous=viscous[port],
                                       stiction=stiction[port], sharpness=sharpness,
                                       peak=self.peak) for port in PORTS}
        self.mesh = SlipFriction("mesh_sun", stiction=self.mesh_stiction,
                                 sharpness=self.mesh_sharpness, peak=self.peak)

    @property
    def tooth_ratio(self) -> float:
        """``x = N_S / N_R``."""
        return self.gears.sun_teeth / self.gears.ring_teeth

    @property
    def ring_mesh(self) -> SlipFriction:
        """The ring mesh's friction: ``k_a2``, ``k_b2`` from the sun mesh's by eq 3.27
        (`mesh_relation`)."""
        scale_a, scale_b = MESH_RELATIONS[self.mesh_relation](self.tooth_ratio)
        return SlipFriction("mesh_ring", stiction=scale_a * self.mesh.stiction,
                            sharpness=scale_b * self.mesh.sharpness, peak=self.mesh.peak)

    def parts(self) -> Parts:
        """The ideal gear set, the two mesh frictions and, on each flange, its inertia and
        bearing, embedded under this module's name."""
        s, r, c = (self.port(p) for p in PORTS)
        flange = {"sun": s, "ring": r, "carrier": c}
        parts = self.embed(self.gears, sun=s, ring=r, carrier=c)
        parts.merge(self.embed(self.mesh, a=s, b=c))
        parts.merge(self.embed(self.ring_mesh, a=r, b=c))
        for port, bearing in self.bearings.items():
            parts.merge(self.embed(bearing, flange=flange[port]))
        for port, inertia in self.inertias.items():
            parts.merge(self.embed(inertia, flange=flange[port]))
        parts.priority = {c: 1}
        return parts

    def closed_form_torque(self, fixed: str, carrier_speed, law: str = "arctan"):
        """Steady torque needed to drive the carrier at ``carrier_speed`` [N m].

        ``fixed`` is ``"sun"`` (eq 3.28) or ``"ring"`` (eq 3.29). Every element
        is a function of the carrier speed through the kinematics, so the torque
        is the sum of each element's resistive torque times its speed ratio.
        Bearing stiction terms are included; with them zero this is exactly the
        report's ``c1 w + c2 atan(c3 w)`` form with
        ``c1 = b_C + b_R (1+x)^2``, ``c2 = k_1 (1+x^2)``, ``c3 = k_b1`` (fixed
        sun) and ``c1 = b_C + b_S (1+1/x)^2``, ``c2 = k_1 (x+1/x)``,
        ``c3 = k_b1/x`` (fixed ring) under the printed eq 3.27; under the
        equal-force relation ``c2 = 2 k_1`` (fixed sun) and ``2 k_1 / x`` (fixed
        ring).
        """
        w = np.atleast_1d(np.asarray(carrier_speed, dtype=float))
        x = self.tooth_ratio
        if fixed == "sun":
            ratios = {"mesh_sun": -1.0, "mesh_ring": x, "bearing_ring": 1.0 + x,
                      "bearing_carrier": 1.0, "bearing_sun": 0.0}
        elif fixed == "ring":
            ratios = {"mesh_sun": 1.0 / x, "mesh_ring": -1.0, "bearing_sun": 1.0 + 1.0 / x,
                      "bearing_carrier": 1.0, "bearing_ring": 0.0}
        else:
            raise ValueError(f"fixed must be 'sun' or 'ring', got {fixed!r}")
        total = np.zeros_like(w)
        # the friction elements of `parts`, taken from the parts that have them: a fit
        # evaluates this thousands of times, and embedding the whole module each time
        # (gears and inertias too) cost several times the torques
        elements = [e for part in (self.mesh, self.ring_mesh, *self.bearings.values())
                    for e in part.parts().frictions]
        for element in elements:
            ratio = ratios[element.name]
            if ratio == 0.0:
                continue
            total += ratio * friction.torque(law, ratio * w, viscous=element.viscous,
                                             stiction=element.k,
                                             sharpness=element.sharpness)
        return total if np.ndim(carrier_speed) else float(total[0])

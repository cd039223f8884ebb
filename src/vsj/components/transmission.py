"""Transmission module: the belts and gears between a carrier and the differential.

Report section 3.1 and table 4.1: one module per DOF lumps every transmission
between a planetary carrier and a differential input, with viscous friction
``b_T`` and stiction ``k_T`` (on the input, carrier side). Its ``ratio`` is
input speed over output speed (Modelica's convention). Fig 4.14 adds a
parasitic compliance in series in one DOF: with ``compliance > 0`` [rad/(N m)]
a linear spring (and an optional parallel damper) sits between the gear and
the output flange; with ``compliance = 0`` the module is rigid. The spring's
deflection is the twist ``phi_gear_side - phi_output`` and its reported torque
is the torque it applies to the output: the torque transmitted.
"""

from __future__ import annotations

from ..network import Constraint, Friction, Parts, Spring
from ..springs import LINEAR, N_PARAMETERS
from ._fields import FRICTION, SchemaComponent, section


class Transmission(SchemaComponent):
    """Carrier-side ``input`` to differential-side ``output``: the ``[transmission]``
    section of a parameter file, whose series compliance of DOF 1 it takes as
    ``compliance`` (the wrist reads DOF 2's for ``tr_2``), and the ``[friction]``
    law's sharpness and peak. By default a rigid, lossless 1:1 coupling."""

    ports = ("input", "output")
    fields = section("transmission", skip=("series_compliance_2",),
                     rename={"series_compliance_1": "compliance", "series_damping": "damping"},
                     defaults={"ratio": 1.0, "viscous": 0.0, "stiction": 0.0,
                               "compliance": 0.0, "damping": 0.0}) + FRICTION

    def parts(self) -> Parts:
        """Input and output geared by ``ratio`` with friction on the input; if
        ``compliance`` [rad/(N m)] is > 0, a linear spring of stiffness ``1 /
        compliance`` sits between the gear and the output flange."""
        a, b = self.port("input"), self.port("output")
        parts = Parts(flanges=[a, b], frictions=[
            Friction(f"{self.name}.friction", {a: 1.0}, self.viscous, self.stiction,
                     self.sharpness, peak=self.peak)])
        if self.compliance == 0.0:
            parts.constraints.append(Constraint(f"{self.name} gear", {a: 1.0, b: -self.ratio}))
            return parts
        end = self.node("spring_end")
        parts.flanges.append(end)
        parts.constraints.append(Constraint(f"{self.name} gear", {a: 1.0, end: -self.ratio}))
        stiffness = 1.0 / self.compliance
        # deflection output - gear side: the spring's torque acts on the output flange
        parts.springs.append(Spring(f"{self.name}.compliance", {b: 1.0, end: -1.0}, LINEAR,
                                    (stiffness,) + (0.0,) * (N_PARAMETERS - 1)))
        if self.damping > 0.0:
            parts.frictions.append(Friction(f"{self.name}.compliance_damping",
                                            {b: 1.0, end: -1.0}, self.damping, 0.0, 1.0,
                                            law="viscous"))
        parts.priority[b] = 5
        return parts

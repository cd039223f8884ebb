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

import math

from ..friction import DEFAULT_SHARPNESS
from ..network import Component, Constraint, Friction, Parts, Spring
from ..params import COMPLIANCE, SHARPNESS, STICTION, VISCOUS
from ..springs import LINEAR, N_PARAMETERS
from ._values import _check, _peak


class Transmission(Component):
    """Carrier-side ``input`` to differential-side ``output``."""

    ports = ("input", "output")

    def __init__(self, name: str, *, ratio: float = 1.0, viscous: float = 0.0,
                 stiction: float = 0.0, sharpness: float = DEFAULT_SHARPNESS,
                 compliance: float = 0.0, damping: float = 0.0, peak: float = 1.0):
        super().__init__(name)
        self.peak = _peak(name, peak)
        if not (math.isfinite(ratio) and ratio != 0.0):
            raise ValueError(f"{name}: ratio must be finite and nonzero, got {ratio!r}")
        self.ratio = float(ratio)
        self.viscous = _check(f"{name}: viscous", VISCOUS, viscous)
        self.stiction = _check(f"{name}: stiction", STICTION, stiction)
        self.sharpness = _check(f"{name}: sharpness", SHARPNESS, sharpness)
        self.compliance = _check(f"{name}: compliance", COMPLIANCE, compliance)
        self.damping = _check(f"{name}: damping", VISCOUS, damping)

    def parts(self) -> Parts:
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

"""Differential: two inputs to the end-effector angles theta_x and theta_y.

Report section 3.5, eq 3.30-3.31 with d1/d2 = 1:

    theta_x_dot = (psi_1_dot + psi_2_dot) / 2,   theta_y_dot = (psi_1_dot - psi_2_dot) / 2

(``psi`` are the differential inputs; the report calls them phi_1, phi_2, a
name vsj keeps for the elastic deflections). The end-effector inertias sit on
the two output speeds; the differential's own friction acts on the input speed
difference, which is proportional to theta_y_dot, so it sits there (fig 3.14).
"""

from __future__ import annotations

import numpy as np

from ..network import Constraint, Friction, Parts
from ._fields import FRICTION, SchemaComponent, section

#: The kinematic map of eq 3.31: (theta_x, theta_y) = MAP @ (psi_1, psi_2).
MAP = np.array([[0.5, 0.5], [0.5, -0.5]])


class Differential(SchemaComponent):
    """The differential with end-effector inertias and its own friction: the
    ``[differential]`` section of a parameter file and the ``[friction]`` law's
    sharpness and peak (everything zero by default: the ideal differential)."""

    ports = ("input_1", "input_2", "theta_x", "theta_y")
    fields = section("differential", defaults={"inertia_x": 0.0, "inertia_y": 0.0,
                                               "viscous": 0.0, "stiction": 0.0}) + FRICTION

    @staticmethod
    def speeds(input_speeds):
        """End-effector speeds (theta_x, theta_y) for input speeds (psi_1, psi_2)."""
        return MAP @ np.asarray(input_speeds)

    @staticmethod
    def torques(output_torques):
        """Input torques that transmit output torques (tau_x, tau_y): the transpose map."""
        return MAP.T @ np.asarray(output_torques)

    def parts(self) -> Parts:
        """The four flanges, the two constraints of the kinematic map `MAP` (report eq
        3.31), the output inertias and the gear friction on the y output."""
        p1, p2, tx, ty = (self.port(p) for p in self.ports)
        return Parts(
            flanges=[p1, p2, tx, ty],
            inertia={tx: self.inertia_x, ty: self.inertia_y},
            constraints=[
                Constraint(f"{self.name} x", {tx: 1.0, p1: -MAP[0, 0], p2: -MAP[0, 1]}),
                Constraint(f"{self.name} y", {ty: 1.0, p1: -MAP[1, 0], p2: -MAP[1, 1]}),
            ],
            frictions=[Friction(f"{self.name}.gears", {ty: 1.0}, self.viscous, self.stiction,
                                self.sharpness, peak=self.peak)],
        )

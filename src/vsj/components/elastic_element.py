"""The VSM elastic element as a component: a ring held by a lever with a movable
pivot and two springs (report section 3.2, fig 3.3).

Its torque comes from one of the spring laws of `vsj.springs`; this module
only wires the law, the lever friction and the ring flange into a network.
"""

from __future__ import annotations

import numpy as np

from ..friction import DEFAULT_SHARPNESS
from ..network import Friction, Parts, Spring
from ..springs import (
    EXPONENTIAL,
    EXPONENTIAL_FIELDS,
    GEOMETRIC,
    GEOMETRIC_REPORT,
    GEOMETRY_FIELDS,
    MODELS,
    N_PARAMETERS,
    ROW_FIELDS,
    coil_pretension,
    evaluate,
)
from ._fields import Row, SchemaComponent, section


class ElasticElement(SchemaComponent):
    """One elastic element of the VSM, acting on the ring flange of its planetary.

    ``model`` is ``"geometric"``, ``"geometric-report"`` (eq 3.8) or
    ``"exponential"`` (eq 4.5), or ``"linear"`` (a constant ``stiffness``
    [N m/rad] >= 0, for twin tests). ``geometry`` holds the geometric models'
    row (`GEOMETRY_FIELDS`), ``exponential`` the exponential model's
    (`EXPONENTIAL_FIELDS`); the model in use needs its row. The lever and pivot
    friction that gives the velocity-independent hysteresis of fig 4.10-4.12
    acts on the ring speed (``friction_stiction``, Coulomb level ``k pi/2``;
    ``friction_viscous``). The pivot position comes from the network's pivot
    mechanism; the element never pushes it back (section 3.1: non-backdrivable).
    All of these are the ``[elastic_element]`` section of a parameter file and the
    ``[friction]`` law's sharpness and peak.

    ``initial_tension`` [N] gives the springs a coil pretension (potential
    model only, static curves only: see the module docstring and
    `coil_pretension`); `parts` refuses it, because the engine cannot simulate it.
    """

    ports = ("ring",)
    fields = (Row("geometry", "elastic_element", default=None, row=GEOMETRY_FIELDS),
              Row("exponential", "elastic_element", default=None, row=EXPONENTIAL_FIELDS),
              *section("elastic_element", skip=GEOMETRY_FIELDS + EXPONENTIAL_FIELDS,
                       rename={"lever_viscous": "friction_viscous",
                               "lever_stiction": "friction_stiction"},
                       defaults={"friction_viscous": 0.0, "friction_stiction": 0.0}),
              *section("friction", rename={"arctan_sharpness": "friction_sharpness",
                                           "peak": "friction_peak"},
                       defaults={"friction_sharpness": DEFAULT_SHARPNESS}))

    def __init__(self, name: str, *, model: str, stiffness: float | None = None,
                 initial_tension: float = 0.0, **values):
        super().__init__(name, **values)
        if model not in MODELS:
            raise ValueError(f"{name}: unknown elastic model {model!r}; choose one of "
                             f"{', '.join(MODELS)}")
        self.model = model
        self.law = MODELS[model]
        if self.law in (GEOMETRIC, GEOMETRIC_REPORT):
            if self.geometry is None:
                raise ValueError(f"{name}: geometric model needs {', '.join(GEOMETRY_FIELDS)}")
            row = list(self.geometry)
        elif self.law == EXPONENTIAL:
            if self.exponential is None:
                raise ValueError(f"{name}: exponential model needs "
                                 f"{', '.join(EXPONENTIAL_FIELDS)}")
            row = list(self.exponential)
        else:
            if stiffness is None or not stiffness >= 0.0:
                raise ValueError(f"{name}: linear model needs a stiffness >= 0")
            row = [float(stiffness)]
        self.parameters = tuple(row + [0.0] * (N_PARAMETERS - len(row)))
        if not (np.isfinite(initial_tension) and initial_tension >= 0.0):
            raise ValueError(f"{name}: initial_tension must be finite and >= 0 N, got "
                             f"{initial_tension!r}")
        if initial_tension > 0.0 and self.law != GEOMETRIC:
            raise ValueError(f"{name}: initial_tension (coil pretension) is an option of the "
                             f"'geometric' model only, not of {model!r}")
        self.initial_tension = float(initial_tension)

    @property
    def reads(self) -> tuple[str, ...]:
        """The ``[elastic_element]`` rows' keys this element's model reads: the geometric
        models `GEOMETRY_FIELDS`, the exponential one `EXPONENTIAL_FIELDS`, the linear one
        none (its stiffness is an option of the model, not a parameter)."""
        return ROW_FIELDS[self.law]

    def torque(self, phi, q: float):
        """Torque [N m] this element applies to the ring at deflections ``phi``
        (coil pretension included)."""
        return (evaluate(self.law, self.parameters, phi, q)[0]
                + coil_pretension(phi, q, self.parameters, self.initial_tension)[0])

    def stiffness(self, phi, q: float):
        """Tangent stiffness ``-d torque / d phi`` [N m/rad]; with coil pretension the
        jumps where a spring goes slack are left out (the slope on either side)."""
        base = evaluate(self.law, self.parameters, phi, q)[1]
        if self.initial_tension == 0.0:
            return base
        phis = np.atleast_1d(np.asarray(phi, dtype=float)).ravel()
        h = 1e-4  # second difference of the added torque: dl/dphi is smooth where taut
        added = (coil_pretension(phis - h, q, self.parameters, self.initial_tension)[0]
                 - coil_pretension(phis + h, q, self.parameters, self.initial_tension)[0])
        return base + added / (2.0 * h)

    def parts(self) -> Parts:
        """The ring flange with the element's spring law and its lever friction.

        Raises ValueError if ``initial_tension`` > 0: the engine's spring laws have no coil
        pretension term."""
        if self.initial_tension > 0.0:
            raise ValueError(f"{self.name}: initial_tension = {self.initial_tension:g} N (coil "
                             "pretension) cannot be simulated: the engine's spring laws have "
                             "no such term; use it for static curves, or set it to 0")
        ring = self.port("ring")
        return Parts(
            flanges=[ring],
            springs=[Spring(self.name, {ring: 1.0}, self.law, self.parameters)],
            frictions=[Friction(f"{self.name}.lever", {ring: 1.0}, self.friction_viscous,
                                self.friction_stiction, self.friction_sharpness,
                                peak=self.friction_peak)],
            priority={ring: 10},
        )

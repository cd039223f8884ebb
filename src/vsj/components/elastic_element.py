"""VSM elastic element: a ring held by a lever with a movable pivot and two springs.

Geometry (report section 3.2.1, fig 3.3; restated in MODEL_NOTES.md): the
origin is the ring centre, y points up. The pivot sits at ``(0, q)``; the
lever is pinned to the ring at ``X_R = R (sin phi, -cos phi)`` (eq 3.2) and
slides through the pivot, so its direction is fixed by the angle ``alpha`` of
eq 3.1 (computed with ``atan2``, which stays right when ``q + R cos phi < 0``).
At the lever's far end, ``L`` along the lever and ``W`` to either side
(eq 3.3-3.4), two equal springs run to the fixed anchors ``(+x0, y0)`` and
``(-x0, y0)``. A spring only pulls: shorter than its rest length ``s0`` it
carries no force (the loss of pretension of fig 3.7 and 4.11).

Three models of the ring torque are offered, selected by law code:

``GEOMETRIC``
    The physical model. With a massless lever and a frictionless pivot the
    springs' potential energy ``V(phi, q) = sum k/2 max(l - s0, 0)^2`` fixes
    everything: the torque on the ring is ``-dV/dphi`` and the force on the
    pivot ``-dV/dq``. Only this form lets the energy ledger close while ``q``
    moves.
``GEOMETRIC_REPORT``
    Eq 3.5-3.8 as printed: the springs' moments about the pivot, ``T_a`` and
    ``T_b = -T_a(-phi)``, turned into a ring torque by ``R / r2`` (which is
    ``sin(alpha) / sin(phi)`` of eq 3.8, finite at ``phi = 0``). It treats the
    lever as turning about the pivot and ignores the force along the lever, so
    it differs from ``GEOMETRIC`` away from ``q = 0``; it is kept to compare
    with the report. It is not the gradient of ``V``.
``EXPONENTIAL``
    The simplified model of eq 4.5: a linear spring of stiffness
    ``K(q) = a1 exp(a2 q) + a3``.

The two VSM-derived models share the physical end stop at ``|phi| = phi_stop``
(1.40 rad, section 3.2.2), modelled as a stiff elastic stop. ``LINEAR`` is a
plain spring, used by the parasitic series compliance of fig 4.14.

Coil pretension (``initial_tension``, an option of the potential model): a
close-wound extension spring holds an initial tension ``F_i``; its force is
``F_i + k (l - s0)`` while it is longer than its free length ``s0`` and zero
below, so the force drops from ``F_i`` to zero at ``s0``. Where a spring goes
slack the ring torque then jumps by ``F_i |dl/dphi|`` instead of only changing
its slope. This fits the report's "very sudden deviation" and "non-continuous"
curves (fig 3.7, 4.11) better than a kink can. It is a static option: the
engine's spring laws (``engine/c/laws.c``) have no such term, so an element
with ``initial_tension > 0`` gives torque curves (`coil_pretension`,
`ElasticElement.torque`) but cannot be simulated.

Every law returns ``(torque, stiffness, energy, dV/dq)``: the torque applied
to the ring (restoring, in the ring's positive direction), ``-dtorque/dphi``,
the stored energy ``V`` and its derivative with respect to the pivot
position (the force the springs put on the pivot is ``-dV/dq``).
"""

from __future__ import annotations

import numpy as np

from ..network import Component, Friction, Parts, Spring
from ._values import _peak

LINEAR = 0
EXPONENTIAL = 1
GEOMETRIC = 2
GEOMETRIC_REPORT = 3

MODELS = {"linear": LINEAR, "exponential": EXPONENTIAL, "geometric": GEOMETRIC,
          "geometric-report": GEOMETRIC_REPORT}
MODEL_NAMES = {code: name for name, code in MODELS.items()}

#: Length of every law's parameter row (unused trailing entries are zero).
N_PARAMETERS = 9
#: Parameter rows. GEOMETRIC and GEOMETRIC_REPORT:
#: R, L, W, x0, y0, s0, k, phi_stop, k_stop (m, m, m, m, m, m, N/m, rad, N m/rad).
GEOMETRY_FIELDS = ("ring_radius", "lever_length", "lever_width", "anchor_x", "anchor_y",
                   "rest_length", "spring_stiffness", "end_stop", "end_stop_stiffness")
#: EXPONENTIAL: a1, a2, a3, phi_stop, k_stop (N m/rad, 1/m, N m/rad, rad, N m/rad).
EXPONENTIAL_FIELDS = ("a1", "a2", "a3", "end_stop", "end_stop_stiffness")

def end_stop(law: int, parameters) -> tuple[float, float] | None:
    """``(angle [rad], stiffness [N m/rad])`` of a law's end stop (stiffness infinite
    for a rigid stop), or None for a law without one."""
    fields = {EXPONENTIAL: EXPONENTIAL_FIELDS, GEOMETRIC: GEOMETRY_FIELDS,
              GEOMETRIC_REPORT: GEOMETRY_FIELDS}.get(law)
    if fields is None:
        return None
    return (float(parameters[fields.index("end_stop")]),
            float(parameters[fields.index("end_stop_stiffness")]))


# The laws themselves are the engine's (engine/c/laws.c); these are their
# Python entry points, evaluated by the same compiled code the simulator runs.


def _row(p) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(p, dtype=float).ravel()[:N_PARAMETERS])


def extensions(phi: float, q: float, p) -> tuple[float, float]:
    """Extensions ``l - s0`` [m] of springs a and b (negative: slack); ``p`` the
    geometric parameter row."""
    from ..engine import _core

    return _core.spring_extensions(_row(p), float(phi), float(q))


def shortest_extension(phis, q: float, par, r: int = 0) -> np.ndarray:
    """Smaller of the two springs' extensions at each deflection in ``phis``
    (parameter row ``r`` of ``par``)."""
    p = _row(np.atleast_2d(par)[r])
    return np.array([min(extensions(phi, q, p)) for phi in np.atleast_1d(phis)])


def geometry(phi: float, q: float, p) -> tuple[float, ...]:
    """Both geometric models at one point: ``(V, dV/dphi, d2V/dphi2, dV/dq, T_phi,
    dT_phi/dphi)`` where the first four belong to the potential model and
    ``T_phi`` is eq 3.8 (the report's reaction torque, applied to the ring as
    ``-T_phi``)."""
    from ..engine import _core

    return _core.spring_geometry(_row(p), float(phi), float(q))


def evaluate(law: int, par, phi, q: float):
    """A spring law at deflections ``phi`` [rad] and pivot position ``q`` [m]:
    arrays of the torque on the ring (restoring, in the ring's positive
    direction), the stiffness ``-dtorque/dphi``, the stored energy ``V`` and
    ``dV/dq`` (the force the springs put on the pivot is ``-dV/dq``). A
    non-finite result means the geometry broke down (``q + R <= 0``)."""
    from ..engine import _core

    phis = np.ascontiguousarray(np.atleast_1d(np.asarray(phi, dtype=float)).ravel())
    out = np.empty((phis.shape[0], 4))
    _core.spring_law(int(law), _row(par), phis, float(q), out)
    return out[:, 0], out[:, 1], out[:, 2], out[:, 3]


def spring_law(law: int, p, phi: float, q: float) -> tuple[float, float, float, float]:
    """`evaluate` at one point: ``(torque, stiffness, energy, dV/dq)``."""
    torque, stiffness, energy, dvdq = evaluate(law, p, phi, q)
    return float(torque[0]), float(stiffness[0]), float(energy[0]), float(dvdq[0])


#: Step [rad] of the central difference that gives the spring lengths' slope dl/dphi;
#: the lengths are smooth in phi (C-infinity away from q + R cos phi = 0), so the
#: error, about h^2 |d3l/dphi3| / 6, is below 1e-13 m/rad for the lengths of vsj's
#: geometries (a few cm).
LENGTH_STEP = 1e-6


def coil_pretension(phi, q: float, p, initial_tension: float):
    """What a coil pretension ``initial_tension`` [N] adds to the potential model.

    Returns arrays ``(torque [N m], energy [J])`` at deflections ``phi`` [rad]
    and pivot position ``q`` [m], for the geometric parameter row ``p``: the
    added energy is ``V_i = F_i sum(max(l - s0, 0))`` over both springs and the
    added torque on the ring ``-dV_i/dphi`` (restoring, as `evaluate`). Add
    them to `evaluate`'s ``GEOMETRIC`` torque and energy. Where a spring
    reaches its free length the torque jumps by ``F_i |dl/dphi|``.
    """
    if not initial_tension >= 0.0:
        raise ValueError(f"initial_tension must be >= 0 N, got {initial_tension!r}")
    phis = np.atleast_1d(np.asarray(phi, dtype=float)).ravel()
    row = _row(p)
    torque = np.zeros(phis.shape)
    energy = np.zeros(phis.shape)
    if initial_tension == 0.0:
        return torque, energy
    h = LENGTH_STEP
    for i, angle in enumerate(phis):
        now = np.array(extensions(angle, q, row))
        slope = (np.array(extensions(angle + h, q, row))
                 - np.array(extensions(angle - h, q, row))) / (2.0 * h)
        taut = now > 0.0
        energy[i] = initial_tension * float(np.sum(now[taut]))
        torque[i] = -initial_tension * float(np.sum(slope[taut]))
    return torque, energy


# -- the component -----------------------------------------------------------


class ElasticElement(Component):
    """One elastic element of the VSM, acting on the ring flange of its planetary.

    ``model`` is ``"geometric"``, ``"geometric-report"`` (eq 3.8) or
    ``"exponential"`` (eq 4.5), or ``"linear"`` (a constant ``stiffness``, for
    twin tests). ``geometry`` holds `GEOMETRY_FIELDS` (SI), ``exponential`` the
    `EXPONENTIAL_FIELDS`. The lever and pivot friction that gives the
    velocity-independent hysteresis of fig 4.10-4.12 acts on the ring speed
    (``friction_stiction``, Coulomb level ``k pi/2``; ``friction_viscous``).
    The pivot position comes from the network's pivot mechanism; the element
    never pushes it back (section 3.1: non-backdrivable).

    ``initial_tension`` [N] gives the springs a coil pretension (potential
    model only, static curves only: see the module docstring and
    `coil_pretension`); `parts` refuses it, because the engine cannot simulate it.
    """

    ports = ("ring",)

    def __init__(self, name: str, *, model: str, geometry=None, exponential=None,
                 stiffness: float | None = None, friction_viscous: float = 0.0,
                 friction_stiction: float = 0.0, friction_sharpness: float = 10.0,
                 friction_peak: float = 1.0, initial_tension: float = 0.0):
        super().__init__(name)
        self.friction_peak = _peak(name, friction_peak)
        if model not in MODELS:
            raise ValueError(f"{name}: unknown elastic model {model!r}; choose one of "
                             f"{', '.join(MODELS)}")
        self.model = model
        self.law = MODELS[model]
        if self.law in (GEOMETRIC, GEOMETRIC_REPORT):
            values = [float(v) for v in (geometry or ())]
            if len(values) != len(GEOMETRY_FIELDS):
                raise ValueError(f"{name}: geometric model needs {', '.join(GEOMETRY_FIELDS)}")
        elif self.law == EXPONENTIAL:
            values = [float(v) for v in (exponential or ())]
            if len(values) != len(EXPONENTIAL_FIELDS):
                raise ValueError(f"{name}: exponential model needs "
                                 f"{', '.join(EXPONENTIAL_FIELDS)}")
        else:
            if stiffness is None or not stiffness >= 0.0:
                raise ValueError(f"{name}: linear model needs a stiffness >= 0")
            values = [float(stiffness)]
        self.parameters = tuple(values + [0.0] * (N_PARAMETERS - len(values)))
        if not (np.isfinite(initial_tension) and initial_tension >= 0.0):
            raise ValueError(f"{name}: initial_tension must be finite and >= 0 N, got "
                             f"{initial_tension!r}")
        if initial_tension > 0.0 and self.law != GEOMETRIC:
            raise ValueError(f"{name}: initial_tension (coil pretension) is an option of the "
                             f"'geometric' model only, not of {model!r}")
        self.initial_tension = float(initial_tension)
        self.friction_viscous = float(friction_viscous)
        self.friction_stiction = float(friction_stiction)
        self.friction_sharpness = float(friction_sharpness)

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

"""Spring laws: the torque of every elastic element of the wrist, as a function of
its deflection and the pivot position.

The VSM elastic element (`vsj.components.ElasticElement`) is a ring held by a
lever with a movable pivot and two springs.

Geometry (report section 3.2.1, fig 3.3; restated in docs/model-notes/elastic-element.md): the
origin is the ring centre, y points up. The pivot sits at ``(0, q)``; the
lever is pinned to the ring at ``X_R = R (sin phi, -cos phi)`` (eq 3.2) and
slides through the pivot, so its direction is fixed by the angle ``alpha`` of
eq 3.1 (its sine and cosine taken from the pin-to-pivot vector over its length, which
stays right when ``q + R cos phi < 0``).
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

from . import _core

#: The spring laws (models) by name, with their engine codes (engine/c/vsj_layout.h's
#: table).
MODELS = {name: code for code, name in enumerate(_core.LAYOUT["spring_laws"])}
LINEAR, EXPONENTIAL, GEOMETRIC, GEOMETRIC_REPORT = (
    MODELS[n] for n in ("linear", "exponential", "geometric", "geometric-report"))
MODEL_NAMES = {code: name for name, code in MODELS.items()}

#: Length of every law's parameter row (unused trailing entries are zero).
N_PARAMETERS = 9
#: Parameter rows. GEOMETRIC and GEOMETRIC_REPORT:
#: R, L, W, x0, y0, s0, k, phi_stop, k_stop (m, m, m, m, m, m, N/m, rad, N m/rad).
GEOMETRY_FIELDS = ("ring_radius", "lever_length", "lever_width", "anchor_x", "anchor_y",
                   "rest_length", "spring_stiffness", "end_stop", "end_stop_stiffness")
#: EXPONENTIAL: a1, a2, a3, phi_stop, k_stop (N m/rad, 1/m, N m/rad, rad, N m/rad).
EXPONENTIAL_FIELDS = ("a1", "a2", "a3", "end_stop", "end_stop_stiffness")
#: The ``[elastic_element]`` keys each law's row is made of; the linear law's row (its
#: stiffness, an option of the model) reads none of them.
ROW_FIELDS = {LINEAR: (), EXPONENTIAL: EXPONENTIAL_FIELDS, GEOMETRIC: GEOMETRY_FIELDS,
              GEOMETRIC_REPORT: GEOMETRY_FIELDS}


def end_stop(law: int, parameters) -> tuple[float, float] | None:
    """``(angle [rad], stiffness [N m/rad])`` of a law's end stop (stiffness infinite
    for a rigid stop), or None for a law without one."""
    fields = ROW_FIELDS.get(law)
    if not fields:  # the linear law and laws without a row of these fields
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
    return _core.spring_geometry(_row(p), float(phi), float(q))


def evaluate(law: int, par, phi, q: float):
    """A spring law at deflections ``phi`` [rad] and pivot position ``q`` [m]:
    arrays of the torque on the ring (restoring, in the ring's positive
    direction), the stiffness ``-dtorque/dphi``, the stored energy ``V`` and
    ``dV/dq`` (the force the springs put on the pivot is ``-dV/dq``). A
    non-finite result means the geometry broke down (``q + R <= 0``)."""
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
#: error, about ``h^2 |d3l/dphi3| / 6``, is below 1e-13 m/rad for the lengths of vsj's
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

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

Every law returns ``(torque, stiffness, energy, dV/dq)``: the torque applied
to the ring (restoring, in the ring's positive direction), ``-dtorque/dphi``,
the stored energy ``V`` and its derivative with respect to the pivot
position (the force the springs put on the pivot is ``-dV/dq``).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import inline, kernel
from ..network import Component, Friction, Parts, Spring

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


@inline
def _lever(phi, q, R):
    """Lever angle alpha and its derivatives (eq 3.1) and the pin-pivot distance."""
    sp = math.sin(phi)
    cp = math.cos(phi)
    n = R * sp
    d = q + R * cp
    r2sq = n * n + d * d
    r2 = math.sqrt(r2sq)
    sa = n / r2
    ca = d / r2
    a_phi = R * (R + q * cp) / r2sq
    a_q = -R * sp / r2sq
    a_pp = R * q * sp * (R * R - q * q) / (r2sq * r2sq)
    return sp, cp, sa, ca, a_phi, a_q, a_pp, r2


@inline
def _lever_end(R, L, W, sa, ca, sp, cp, side):
    """Position of the lever end where spring ``side`` (+1: a, -1: b) attaches (eq 3.4)."""
    return R * sp - L * sa + side * W * ca, -R * cp + L * ca + side * W * sa


@inline
def row(par, r):
    """Parameter row ``r`` as a tuple of nine floats (values, not an array view)."""
    return (par[r, 0], par[r, 1], par[r, 2], par[r, 3], par[r, 4], par[r, 5], par[r, 6],
            par[r, 7], par[r, 8])


@kernel
def extensions(phi, q, p):
    """Extensions ``l - s0`` [m] of springs a and b (negative: slack); ``p`` as `row`."""
    R, L, W, x0, y0, s0 = p[0], p[1], p[2], p[3], p[4], p[5]
    sp, cp, sa, ca, _, _, _, _ = _lever(phi, q, R)
    Xa, Ya = _lever_end(R, L, W, sa, ca, sp, cp, 1.0)
    Xb, Yb = _lever_end(R, L, W, sa, ca, sp, cp, -1.0)
    return (math.sqrt((Xa - x0) ** 2 + (Ya - y0) ** 2) - s0,
            math.sqrt((Xb + x0) ** 2 + (Yb - y0) ** 2) - s0)


@kernel
def shortest_extension(phis, q, par, r):
    """Smaller of the two springs' extensions at each deflection in ``phis``."""
    out = np.empty(phis.shape[0])
    p = row(par, r)
    for i in range(phis.shape[0]):
        ea, eb = extensions(phis[i], q, p)
        out[i] = min(ea, eb)
    return out


@inline
def geometry(phi, q, p):
    """Both geometric models at one point (parameters ``p`` as `row`).

    Returns ``(V, dV/dphi, d2V/dphi2, dV/dq, T_phi, dT_phi/dphi)`` where the
    first four belong to the potential model and ``T_phi`` is eq 3.8 (the
    report's reaction torque, applied to the ring as ``-T_phi``).
    """
    R, L, W, x0, y0, s0, k = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    sp, cp, sa, ca, a_phi, a_q, a_pp, r2 = _lever(phi, q, R)
    V = 0.0
    dV = 0.0
    d2V = 0.0
    dVq = 0.0
    t_sum = 0.0
    dt_sum = 0.0
    for half in range(2):
        side = 1.0 - 2.0 * half  # spring a (+1), then spring b (-1)
        # lever end point X and its derivatives (eq 3.4), u_L = (-sa, ca), u_W = (ca, sa)
        lx = -L * ca + side * W * (-sa)   # (-L u_W + side W u_L), x
        ly = -L * sa + side * W * ca      # (-L u_W + side W u_L), y
        mx = L * sa - side * W * ca       # (-L u_L - side W u_W), x
        my = -L * ca - side * W * sa      # (-L u_L - side W u_W), y
        X, Y = _lever_end(R, L, W, sa, ca, sp, cp, side)
        Xp = R * cp + lx * a_phi
        Yp = R * sp + ly * a_phi
        Xpp = -R * sp + mx * a_phi * a_phi + lx * a_pp
        Ypp = R * cp + my * a_phi * a_phi + ly * a_pp
        Xq = lx * a_q
        Yq = ly * a_q
        ax = side * x0
        gx = X - ax
        gy = Y - y0
        ell = math.sqrt(gx * gx + gy * gy)
        e = ell - s0
        if e <= 0.0:
            continue  # slack: a spring only pulls
        gxp = gx * Xp + gy * Yp
        V += 0.5 * k * e * e
        dV += k * e * gxp / ell
        d2V += k * (gxp * gxp / (ell * ell)
                    + e * ((Xp * Xp + Yp * Yp + gx * Xpp + gy * Ypp) / ell
                           - gxp * gxp / (ell * ell * ell)))
        dVq += k * e * (gx * Xq + gy * Yq) / ell
        # eq 3.5-3.7: moment arm of the spring force about the pivot (0, q)
        c = gy * ax - gx * (y0 - q)
        dc = Yp * ax - Xp * (y0 - q)
        arm = c / ell
        darm = dc / ell - c * gxp / (ell * ell * ell)
        t_sum += k * e * arm
        dt_sum += k * (gxp / ell * arm + e * darm)
    scale = R / r2  # sin(alpha) / sin(phi) of eq 3.8
    T_phi = t_sum * scale
    dT_phi = dt_sum * scale + t_sum * R * q * R * sp / (r2 * r2 * r2)
    return V, dV, d2V, dVq, T_phi, dT_phi


@inline
def spring_law(law, p, phi, q):
    """``(torque, stiffness, energy, dV/dq)`` of a spring law at deflection ``phi``.

    ``p`` is the spring's parameter row as a tuple (`row`; a value, so this
    inlined code needs no array bookkeeping), ``q`` the pivot position [m]
    (ignored by ``LINEAR``). A non-finite result means the geometry broke down
    (the pin reached the pivot, ``q + R <= 0``).
    """
    if law == LINEAR:
        k = p[0]
        return -k * phi, k, 0.5 * k * phi * phi, 0.0
    if law == EXPONENTIAL:
        growth = p[0] * math.exp(p[1] * q)
        stiff = growth + p[2]
        tau = -stiff * phi
        energy = 0.5 * stiff * phi * phi
        dvq = 0.5 * growth * p[1] * phi * phi
        stop, k_stop = p[3], p[4]
    else:
        V, dV, d2V, dVq, T_phi, dT_phi = geometry(phi, q, p)
        if law == GEOMETRIC:
            tau = -dV
            stiff = d2V
        else:
            tau = -T_phi
            stiff = dT_phi
        energy = V
        dvq = dVq
        stop, k_stop = p[7], p[8]
    excess = abs(phi) - stop
    if excess > 0.0:
        sign = 1.0 if phi > 0.0 else -1.0
        tau -= k_stop * excess * sign
        stiff += k_stop
        energy += 0.5 * k_stop * excess * excess
    return tau, stiff, energy, dvq


@kernel
def _law_arrays(law, par, phis, q, out):
    for i in range(phis.shape[0]):
        res = spring_law(law, row(par, 0), phis[i], q)
        out[i, 0] = res[0]
        out[i, 1] = res[1]
        out[i, 2] = res[2]
        out[i, 3] = res[3]
    return out


def evaluate(law: int, par, phi, q: float):
    """Vectorised `spring_law`: arrays of torque, stiffness, energy and dV/dq."""
    phis = np.atleast_1d(np.asarray(phi, dtype=float))
    out = _law_arrays(int(law), np.asarray(par, dtype=float).reshape(1, -1), phis, float(q),
                      np.empty((phis.shape[0], 4)))
    return out[:, 0], out[:, 1], out[:, 2], out[:, 3]


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
    """

    ports = ("ring",)

    def __init__(self, name: str, *, model: str, geometry=None, exponential=None,
                 stiffness: float | None = None, friction_viscous: float = 0.0,
                 friction_stiction: float = 0.0, friction_sharpness: float = 10.0):
        super().__init__(name)
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
        self.friction_viscous = float(friction_viscous)
        self.friction_stiction = float(friction_stiction)
        self.friction_sharpness = float(friction_sharpness)

    def torque(self, phi, q: float):
        """Torque [N m] this element applies to the ring at deflections ``phi``."""
        return evaluate(self.law, self.parameters, phi, q)[0]

    def stiffness(self, phi, q: float):
        """Tangent stiffness ``-d torque / d phi`` [N m/rad]."""
        return evaluate(self.law, self.parameters, phi, q)[1]

    def parts(self) -> Parts:
        ring = self.port("ring")
        return Parts(
            flanges=[ring],
            springs=[Spring(self.name, {ring: 1.0}, self.law, self.parameters)],
            frictions=[Friction(f"{self.name}.lever", {ring: 1.0}, self.friction_viscous,
                                self.friction_stiction, self.friction_sharpness)],
            priority={ring: 10},
        )

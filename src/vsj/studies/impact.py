"""The reduced impact model: how hard the wrist hits a body at a given speed.

The standard reduced model of a collision with an elastic joint (Bicchi and Tonietti,
"Fast and soft-arm tactics", IEEE Robotics and Automation Magazine 11(2), 2004; the
two-body model of ISO/TS 15066 annex A for the body): the link's tip, ``link`` [m] from
the axis, strikes a free body of effective mass ``m_H`` [kg] through a linear contact of
stiffness ``k_c`` [N/m] (Hunt-Crossley with n = 1 and no damping: `vsj.components.Contact`
with those values). Behind the link sits the joint's spring ``K`` [N m/rad] (the
stiffness setting), behind that the motors' rotors. The impact is short against the
motors' electrical and mechanical time constants, so the rotors are taken as free
inertias (their torque over the impact neglected, as Bicchi and Tonietti do); friction
is neglected (it only takes energy out).

Coordinates ``z = (theta_m, theta, x_H)`` [rad, rad, m] with the `AxisModel`'s 2 x 2
mass matrix (plus a tip mass) and the body's mass; the potential is ``K (theta_m -
theta)^2 / 2`` plus, while the tip presses into the body (``d = link theta - x_H > 0``),
``k_c d^2 / 2``. Each phase (in contact, apart) is linear and undamped, so it is solved
exactly by its modes (``K_phase phi = w^2 M phi``): no step size, no tolerance. The
contact ends where ``d`` returns to zero; the tip may catch the body again (the rotors
push the link through the joint's spring), so phases follow each other until the body
moves away faster than the tip ever can (the free motion's largest tip speed is the
rigid motion's plus every mode's amplitude times its frequency): after that no contact
can come, and the peak over all contacts is final.

Two closed forms bound it: a rigid joint (``K`` infinite) is one mass ``m_R + m_L``
striking ``m_H``, ``F = v sqrt(k_c mu)`` with ``mu`` the reduced mass (the
mass-spring-mass impact); with ``K = 0`` the rotors never take part, ``F = v sqrt(k_c
mu_L)`` with the link's own effective mass. In between, with ``K link^-2`` far below
``k_c`` (the wrist's case: the joint is two orders softer than a hand at 10 cm), the
first peak is the link's alone and a slower second one follows as the rotors push the
link through the joint's spring in series with the contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import eigh
from scipy.optimize import brentq, minimize_scalar

from ..errors import InputError, SimulationError
from ..safety import region

#: Samples per period of the fastest mode when a phase's gap is searched for its zero
#: crossing and its peak: a crossing closer than 1/64 period to another could be missed,
#: but a sum of two sinusoids turns at most twice per period of the faster one.
SAMPLES_PER_PERIOD = 64
#: A phase is searched in windows of this many periods of its slowest mode.
WINDOW_PERIODS = 4
#: Largest number of contact phases followed before giving up (raised, never silent).
MAX_CONTACTS = 200


@dataclass(frozen=True)
class BodyModel:
    """The body struck: ``mass`` m_H [kg] (effective mass), ``stiffness`` k_c [N/m] (the
    contact's, n = 1), ``force_limit`` [N] (the transient force allowed) and ``name``
    and ``source`` (where the numbers come from)."""

    name: str
    mass: float
    stiffness: float
    force_limit: float
    source: str = ""

    def check(self) -> None:
        """`InputError` naming the field for a value that is not finite and > 0."""
        for key in ("mass", "stiffness", "force_limit"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or v <= 0:
                raise InputError(f"body {self.name!r}: {key} must be a finite number > 0, "
                                 f"got {v!r}")


    @classmethod
    def from_region(cls, name: str, contact: str = "transient") -> "BodyModel":
        """The ISO/TS 15066 body region ``name`` (``"hand"``, ``"lower_arm"``;
        `vsj.safety.region`) as a body: its effective mass and spring constant
        (Table A.3) and its permissible force for ``contact`` (Table A.2), with the
        sources those values cite."""
        reg = region(name)
        sources = "; ".join(reg.sources[key] for key in (
            "effective_mass", "spring_constant", "quasi_static_force",
            "transient_force_factor"))
        return cls(reg.name, reg.effective_mass, reg.spring_constant,
                   reg.permissible_force(contact), sources)


#: The hand of ISO/TS 15066 (`vsj.safety.region` ``"hand"``) under transient contact.
HAND = BodyModel.from_region("hand")


@dataclass(frozen=True)
class Impact:
    """The outcome of one impact: ``peak_force`` [N], the time it comes at
    ``peak_time`` [s] after first touch, ``contacts`` (how many separate contacts),
    the first contact's ``first_peak`` [N] and ``duration`` [s], and ``end`` [s], when
    the last contact ended (after it the body moves away faster than the tip can
    follow)."""

    peak_force: float
    peak_time: float
    contacts: int
    first_peak: float
    duration: float
    end: float


class _Phase:
    """One linear, undamped phase: ``z(t)`` from ``z0``, ``v0`` by the modes of
    ``(K, M)``; its ``rigid`` lowest modes (as many as ``K`` has null directions, known
    from which springs act) move rigidly."""

    def __init__(self, M, K, z0, v0, rigid: int):
        w2, phi = eigh(K, M)  # ascending
        self.rigid = np.arange(len(w2)) < rigid
        self.w = np.sqrt(np.where(self.rigid, 0.0, np.maximum(w2, 0.0)))
        self.phi = phi
        self.a = phi.T @ M @ z0      # modal positions (phi^T M phi = I)
        self.b = phi.T @ M @ v0      # modal speeds

    def modal(self, t, derivative=0):
        t = np.atleast_1d(np.asarray(t, dtype=float))[:, None]
        w = np.where(self.rigid, 1.0, self.w)
        c, s = np.cos(w * t), np.sin(w * t)
        if derivative == 0:
            osc = self.a * c + self.b / w * s
            rig = self.a + self.b * t
        else:
            osc = -self.a * w * s + self.b * c
            rig = np.broadcast_to(self.b, osc.shape)
        return np.where(self.rigid, rig, osc)

    def position(self, t):
        return self.modal(t) @ self.phi.T

    def speed(self, t):
        return self.modal(t, 1) @ self.phi.T

    def periods(self):
        w = self.w[~self.rigid]
        return 2 * math.pi / w.max(), 2 * math.pi / w.min()

    def never_above_zero_after(self, row) -> float:
        """A time after which ``row . z(t)`` stays below zero for good, or ``inf``: the
        rigid part of it must fall (``row . rigid speed < 0``), and then it is below
        zero once the rigid part is below minus every mode's amplitude."""
        gain = row @ self.phi
        r = self.rigid
        slope = float(gain[r] @ self.b[r]) if r.any() else 0.0
        offset = float(gain[r] @ self.a[r]) if r.any() else 0.0
        o = ~r
        amplitude = float(np.abs(gain[o]) @ np.sqrt(self.a[o] ** 2 + (self.b[o] / self.w[o]) ** 2))
        if slope >= 0.0:
            return math.inf if offset + amplitude >= 0.0 or slope > 0.0 else 0.0
        return max(0.0, (offset + amplitude) / -slope)


def _first_crossing(phase: _Phase, row, sign: float, start: float, give_up: float = math.inf):
    """The first time > ``start`` where ``sign * row . z`` falls through zero (for the
    contact's end, sign = +1) or rises through it (sign = -1: the next touch), searched
    window after window: ``(time, sampled times, sampled values)``, or None when the
    search passes ``give_up`` (no crossing can come after it)."""
    fast, slow = phase.periods()
    step = fast / SAMPLES_PER_PERIOD
    window = WINDOW_PERIODS * slow
    t0 = start
    for _ in range(10_000):
        t = t0 + np.arange(0, int(math.ceil(window / step)) + 1) * step
        g = sign * (phase.position(t) @ row)
        below = np.flatnonzero((g[1:] < 0) & (g[:-1] >= 0))
        below = below[t[below + 1] > start + step * 1e-6]
        if len(below):
            i = int(below[0])
            if g[i] == 0.0 and t[i] > start:
                return float(t[i]), t[:i + 1], g[:i + 1]
            f = lambda s: sign * float(phase.position(s)[0] @ row)  # noqa: E731
            root = brentq(f, t[i], t[i + 1], xtol=1e-15, rtol=4 * np.finfo(float).eps)
            return root, t[:i + 1], g[:i + 1]
        t0 = float(t[-1])
        if t0 > give_up:
            return None
    raise SimulationError("impact model: a contact phase did not end within 10 000 windows")


def _peak(phase: _Phase, row, times, gaps) -> tuple[float, float]:
    """The largest ``row . z`` over a contact phase sampled at ``times`` (``gaps``),
    refined between the samples around the best one."""
    i = int(np.argmax(gaps))
    lo = times[max(i - 1, 0)]
    hi = times[min(i + 1, len(times) - 1)]
    if hi <= lo:
        return float(times[i]), float(gaps[i])
    res = minimize_scalar(lambda s: -float(phase.position(s)[0] @ row), bounds=(lo, hi),
                          method="bounded", options={"xatol": 1e-14 * max(hi, 1e-9)})
    if -res.fun >= gaps[i]:
        return float(res.x), float(-res.fun)
    return float(times[i]), float(gaps[i])


def impact(mass, stiffness: float, link: float, body: BodyModel, *, speed_motor: float,
           speed_link: float, deflection: float = 0.0, tip_mass: float = 0.0) -> Impact:
    """The impact of the link's tip on ``body`` (a `BodyModel`) at first touch.

    ``mass`` [kg m^2]: the 2 x 2 mass matrix over ``(theta_m, theta)`` (`AxisModel.mass`);
    ``stiffness`` K [N m/rad] the joint's (``inf``: rigid, rotors and link one body);
    ``link`` [m] the tip's distance from the axis, ``tip_mass`` [kg] a mass there;
    ``speed_motor``, ``speed_link`` [rad/s] the motor side's and the link's speeds and
    ``deflection`` [rad] the joint's (``theta_m - theta``) at first touch. The link must
    approach the body (``speed_link > 0``). Returns an `Impact`."""
    body.check()
    M2 = np.array(mass, dtype=float)
    if M2.shape != (2, 2) or not np.all(np.isfinite(M2)):
        raise InputError(f"impact: mass must be a finite 2 x 2 matrix, got {M2.tolist()}")
    link = _positive("link", link)
    tip_mass = _positive("tip_mass", tip_mass, allow_zero=True)
    if not (isinstance(stiffness, (int, float)) and stiffness >= 0 and not math.isnan(stiffness)):
        raise InputError(f"impact: stiffness must be >= 0 N m/rad (inf: rigid), got "
                         f"{stiffness!r}")
    if not (math.isfinite(speed_link) and speed_link > 0):
        raise InputError(f"impact: speed_link must be > 0 rad/s (the link approaches the "
                         f"body), got {speed_link!r}")
    M2[1, 1] += tip_mass * link ** 2
    kc, mH = body.stiffness, body.mass
    if math.isinf(stiffness):
        # one body: the rotors and the link turn together
        m = float(M2.sum()) / link ** 2
        if not (math.isfinite(speed_motor) and math.isclose(speed_motor, speed_link)
                and deflection == 0.0):
            raise InputError("impact: a rigid joint has one speed and no deflection")
        M = np.diag([m, mH])
        Kc = kc * np.array([[1.0, -1.0], [-1.0, 1.0]])
        Kf = np.zeros((2, 2))
        z0, v0 = np.zeros(2), np.array([speed_link * link, 0.0])
        row = np.array([1.0, -1.0])
        rigid_touching, rigid_apart = 1, 2
    else:
        M = np.zeros((3, 3))
        M[:2, :2] = M2
        M[2, 2] = mH
        Kf = np.zeros((3, 3))
        Kf[:2, :2] = stiffness * np.array([[1.0, -1.0], [-1.0, 1.0]])
        row = np.array([0.0, link, -1.0])
        Kc = Kf + kc * np.outer(row, row)
        z0 = np.array([deflection, 0.0, 0.0])
        v0 = np.array([speed_motor, speed_link, 0.0])
        # null directions: the common motion, and with K = 0 the rotors' own
        rigid_touching, rigid_apart = (1, 2) if stiffness > 0 else (2, 3)
        if not math.isfinite(speed_motor):
            raise InputError(f"impact: speed_motor must be finite, got {speed_motor!r}")
    peak, peak_time, first, duration, t_abs = 0.0, 0.0, None, None, 0.0
    for contacts in range(1, MAX_CONTACTS + 1):
        phase = _Phase(M, Kc, z0, v0, rigid_touching)
        end, times, gaps = _first_crossing(phase, row, +1.0, 0.0)
        t_peak, g_peak = _peak(phase, row, times, gaps)
        if kc * g_peak > peak:
            peak, peak_time = kc * g_peak, t_abs + t_peak
        if first is None:
            first, duration = kc * g_peak, end
        z0, v0 = phase.position(end)[0], phase.speed(end)[0]
        t_abs += end
        free = _Phase(M, Kf, z0, v0, rigid_apart)
        if free.rigid.all():
            closing = float(row @ v0)
            if closing <= 0.0:
                return Impact(peak, peak_time, contacts, first, duration, t_abs)
            again = -float(row @ z0) / closing
        else:
            found = _first_crossing(free, row, -1.0, 0.0, free.never_above_zero_after(row))
            if found is None:  # the body moves away faster than the tip can follow
                return Impact(peak, peak_time, contacts, first, duration, t_abs)
            again = found[0]
        z0, v0 = free.position(again)[0], free.speed(again)[0]
        t_abs += again
    raise SimulationError(f"impact model: still touching after {MAX_CONTACTS} contacts")


def _positive(name: str, value, *, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"impact: {name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"impact: {name} must be a finite number {'>=' if allow_zero else '>'}"
                         f" 0, got {value!r}")
    return v


def reduced_mass(m1: float, m2: float) -> float:
    """``m1 m2 / (m1 + m2)`` [kg]."""
    return m1 * m2 / (m1 + m2)


def mass_spring_mass_peak(speed: float, stiffness: float, m1: float, m2: float) -> float:
    """The closed form: a mass ``m1`` [kg] at ``speed`` [m/s] strikes a free mass ``m2``
    through a linear spring ``stiffness`` [N/m]; the spring's peak force [N] is ``speed
    sqrt(stiffness mu)`` (all kinetic energy of the relative motion, ``mu v^2 / 2``,
    stored in the spring at the peak)."""
    return speed * math.sqrt(stiffness * reduced_mass(m1, m2))


def force_per_speed(mass, stiffness: float, link: float, body: BodyModel, *,
                    tip_mass: float = 0.0) -> float:
    """The peak force per unit tip speed [N/(m/s)] of an impact with the motor side and
    the link at one speed and the joint undeflected (the model is linear and every phase
    scales with the speed, so this is the force at 1 m/s)."""
    omega = 1.0 / float(link)
    return impact(mass, stiffness, link, body, speed_motor=omega, speed_link=omega,
                  tip_mass=tip_mass).peak_force


def safe_speed(mass, stiffness: float, link: float, body: BodyModel, *,
               tip_mass: float = 0.0) -> float:
    """The largest link speed [rad/s] whose impact on ``body`` (motor side at the same
    speed, joint undeflected) stays within ``body.force_limit``."""
    return body.force_limit / (force_per_speed(mass, stiffness, link, body,
                                               tip_mass=tip_mass) * link)


__all__ = ["BodyModel", "HAND", "Impact", "force_per_speed", "impact",
           "mass_spring_mass_peak", "reduced_mass", "safe_speed"]

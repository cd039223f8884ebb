"""Tracking against safety over the stiffness setting: what a softer joint costs in
tracking and what it buys in a collision.

For each pivot position q the wrist, with DC motors and closed in its own coordinates
(`vsj.control.wrist_controller`: collocated PIDs on the motors, at 1 kHz), follows the
circle of report fig 4.15 with its end-effector (radius ``radius`` at ``frequency``,
faded in). Two runs per setting:

* **tracking**: in free space; the lag [s] of theta_x behind its reference at the
  circle's frequency over its last two turns (the elastic elements deflect under the
  output side's inertia and friction, more where they are soft), and the RMS distance
  to the circle;
* **collision**: the same motion with a hand surrogate on its path (ISO/TS 15066's
  two-body model: the hand's effective mass and spring constant, Table A.3, held by an
  arm of ``arm_stiffness``) ``inset`` inside the circle where theta_x peaks; the peak
  contact force and its verdict against the hand's permissible transient force (Table
  A.2) and the quasi-static one (the hand stays clamped while the motors press on).

Nothing in the report is compared here: it characterises one prototype in free space.
The figure tests the published argument for variable stiffness (Bicchi and Tonietti,
"Fast and soft-arm tactics", IEEE Robotics & Automation Magazine 2004): softness lowers
the force of a collision at a cost in tracking. `run` gives the numbers, `figure` the
figure, `page` the page; ``vsj study tracking-safety`` writes all three.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..control import mechanical_stiffness, wrist_controller
from ..environment import Body, Environment, add_environment
from ..errors import InputError
from ..inputs import Sine
from ..simulate import InitialState, SimulationOptions, simulate
from ..sweep.metrics import phase_lag
from ..wrist import WristOptions, build_wrist
from .iso_ts_15066 import region


@dataclass(frozen=True)
class Setup:
    """The study's motion, collision and sampling (SI units; angles in rad)."""

    radius: float = 0.3
    frequency: float = 0.5
    fade_in: float = 2.0
    duration: float = 6.0
    link: float = 0.1
    tip_mass: float = 0.2
    inset: float = 0.22  # near the centre: even the softest, most lagging setting reaches it
    arm_stiffness: float = 2e4
    arm_damping: float = 50.0
    period: float = 1e-3
    friction: str = "arctan"
    #: the elastic elements' model (`vsj.wrist.WristOptions.elastic`): eq 4.5 by default,
    #: the geometric one where the springs' geometry is what is studied (`vsj.design`)
    elastic: str = "exponential"

    def check(self) -> None:
        """`InputError` naming the field for a value out of its range."""
        for name in ("radius", "frequency", "duration", "link", "period", "arm_stiffness"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise InputError(f"tracking-safety study: {name} must be > 0, got {v!r}")
        for name in ("fade_in", "tip_mass", "arm_damping"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise InputError(f"tracking-safety study: {name} must be >= 0, got {v!r}")
        if not 0 < self.inset < self.radius:
            raise InputError(f"tracking-safety study: inset must lie in (0, radius = "
                             f"{self.radius:g}) rad, got {self.inset!r}")
        if self.duration < self.fade_in + 2.0 / self.frequency:
            raise InputError("tracking-safety study: duration must cover the fade-in and two "
                             "turns of the circle")


@dataclass
class Tradeoff:
    """The study's numbers, one entry per pivot position ``q`` [m]: the end-effector's
    mechanical stiffness about x [N m/rad], the tracking lag [s] and RMS error [rad], and
    the collision's peak contact force [N] with the hand's permissible transient and
    quasi-static forces [N]."""

    setup: Setup
    q: list = field(default_factory=list)
    stiffness: list = field(default_factory=list)
    lag: list = field(default_factory=list)
    rms_error: list = field(default_factory=list)
    peak_force: list = field(default_factory=list)
    transient_limit: float = 0.0
    quasi_static_limit: float = 0.0

    def as_dict(self) -> dict:
        """JSON-ready, with the reproduction's category and verdict: a prediction the
        report states no value for (`vsj.reproduce.base`)."""
        from ..reproduce.base import PREDICTION  # lazy: vsj.reproduce imports SciPy

        out = asdict(self)
        out["setup"] = asdict(self.setup)
        out.update(category=PREDICTION, verdict="not compared",
                   tests="Bicchi and Tonietti 2004: softness lowers a collision's force "
                         "at a cost in tracking")
        return out

    def summary(self) -> str:
        """The finding in a few words: what softening from the stiffest to the softest
        setting does to the lag and to the collision's peak force."""
        i, j = int(np.argmax(self.stiffness)), int(np.argmin(self.stiffness))
        return (f"from the stiffest setting (q = {100 * self.q[i]:.2f} cm, "
                f"{self.stiffness[i]:.3g} N m/rad) to the softest (q = {100 * self.q[j]:.2f} "
                f"cm, {self.stiffness[j]:.3g} N m/rad) the tracking lag goes from "
                f"{1e3 * self.lag[i]:.1f} to {1e3 * self.lag[j]:.1f} ms and the collision's "
                f"peak force from {self.peak_force[i]:.1f} to {self.peak_force[j]:.1f} N "
                f"(hand: {self.transient_limit:g} N transient, {self.quasi_static_limit:g} N "
                "quasi-static, ISO/TS 15066 Table A.2)")


def _references(s: Setup, q: float) -> dict:
    circle = dict(amplitude=s.radius, frequency=s.frequency, fade_in=s.fade_in)
    return {"theta_x": Sine(phase=math.pi / 2, **circle), "theta_y": Sine(**circle), "q": q}


def run(params, qs, setup: Setup | None = None, progress=None) -> Tradeoff:
    """The study at the pivot positions ``qs`` [m] for a parameter set; ``progress``, if
    given, is called with each finished setting's index."""
    s = setup or Setup()
    s.check()
    qs = [float(q) for q in qs]
    if not qs:
        raise InputError("tracking-safety study: give at least one pivot position")
    hand = region("hand")
    options = WristOptions(motors="dc", pivot_drive="dc", elastic=s.elastic)
    free = build_wrist(params, options).assemble()
    for q in qs:
        if not free.pivot.q_min <= q <= free.pivot.q_max:
            raise InputError(f"tracking-safety study: q = {q:g} m is outside the pivot's "
                             f"range [{free.pivot.q_min:g}, {free.pivot.q_max:g}] m")
    env = Environment(link=s.link, tip_mass=s.tip_mass, contacts=(Body(
        "hand", angle=s.radius - s.inset, mass=hand.effective_mass,
        stiffness=hand.spring_constant, support_stiffness=s.arm_stiffness,
        support_damping=s.arm_damping),))
    touching = add_environment(build_wrist(params, options), env).assemble()
    sim = SimulationOptions(friction=s.friction, output_step=s.period)
    out = Tradeoff(setup=s, transient_limit=hand.permissible_force("transient"),
                   quasi_static_limit=hand.permissible_force("quasi-static"))
    for k, q in enumerate(qs):
        tracked = simulate(free, {}, s.duration, options=sim, initial=InitialState(q=q),
                           controller=wrist_controller(free, _references(s, q),
                                                       period=s.period), ports=False)
        hit = simulate(touching, {}, s.duration, options=sim, initial=InitialState(q=q),
                       controller=wrist_controller(touching, _references(s, q),
                                                   period=s.period), ports=False)
        for result, what in ((tracked, "tracking"), (hit, "collision")):
            if not result.success:
                raise InputError(f"tracking-safety study: the {what} run at q = {q:g} m "
                                 f"failed: {result.message}")
        last = tracked.time >= s.duration - 2.0 / s.frequency
        t, x, ref = tracked.time[last], tracked["theta_x"][last], tracked["control.theta_x"][last]
        y, ref_y = tracked["theta_y"][last], tracked["control.theta_y"][last]
        out.q.append(q)
        out.stiffness.append(float(mechanical_stiffness(free, q)[0, 0]))
        out.lag.append(phase_lag(t, x, ref, s.frequency))
        out.rms_error.append(float(np.sqrt(np.mean((x - ref) ** 2 + (y - ref_y) ** 2))))
        out.peak_force.append(float(np.max(hit["contact.hand.force"])))
        if progress is not None:
            progress(k)
    return out


def figure(result: Tradeoff, path) -> None:
    """The trade-off as a figure: tracking lag against the collision's peak force, one
    point per setting (labelled with q), with the hand's ISO limits."""
    from .. import plots  # lazy: matplotlib is heavy; imported when a figure is drawn

    fig = plots.figure(figsize=(7.5, 4.8))
    ax = fig.add_subplot()
    lag_ms = 1e3 * np.asarray(result.lag)
    force = np.asarray(result.peak_force)
    ax.plot(force, lag_ms, "o-", color="C0")
    for q, f, lag in zip(result.q, force, lag_ms):
        ax.annotate(f"q = {100 * q:.1f} cm", (f, lag), textcoords="offset points",
                    xytext=(6, 4), fontsize=8)
    for limit, text in ((result.transient_limit, "transient"),
                        (result.quasi_static_limit, "quasi-static")):
        ax.axvline(limit, color="C3", linestyle="--" if text == "transient" else ":")
        ax.text(limit, ax.get_ylim()[1], f" hand, {text} (ISO/TS 15066)", color="C3",
                fontsize=8, va="top", rotation=90)
    ax.set_xlabel("peak contact force of the collision with the hand surrogate [N]")
    ax.set_ylabel("tracking lag of theta_x [ms]")
    ax.set_title("Tracking against safety over the stiffness setting (model study)")
    ax.grid(True, alpha=0.3)
    plots.save(fig, path)


def page(result: Tradeoff, png: bytes) -> str:
    """The study's HTML page: what it is, the figure, the table, what is new."""
    from .. import pages  # lazy: the page writer is needed for pages only

    rows = "".join(
        f"<tr><td>{100 * q:.2f}</td><td>{k:.4g}</td><td>{1e3 * lag:.2f}</td>"
        f"<td>{1e3 * e:.2f}</td><td>{f:.1f}</td><td class=l>{_verdict(result, f)}</td></tr>"
        for q, k, lag, e, f in zip(result.q, result.stiffness, result.lag, result.rms_error,
                                    result.peak_force))
    s = result.setup
    hand = region("hand")
    body = [
        "<p class=headline>" + pages.esc(result.summary()) + "</p>",
        "<p>" + pages.esc(
            f"The wrist (DC motors, {s.elastic} elastic elements, {s.friction} friction) "
            f"follows a {s.radius:g} rad circle at {s.frequency:g} Hz (report fig 4.15's "
            f"motion) in closed loop at {1 / s.period:g} Hz, once in free space (the lag) "
            f"and once with a hand surrogate (ISO/TS 15066 Table A.3: "
            f"{hand.effective_mass:g} kg, {hand.spring_constant / 1e3:g} N/mm) "
            f"held by an arm of {s.arm_stiffness:g} N/m, {s.inset:g} rad inside the "
            f"circle, {s.link:g} m from the wrist's centre (tip mass {s.tip_mass:g} kg)."
        ) + " <span class='synthetic'>model study: no measurement</span></p>",
        pages.figure(png, "tracking lag against the collision's peak force, per q"),
        "<table><tr><th>q [cm]</th><th>stiffness about x [N m/rad]</th><th>lag [ms]</th>"
        "<th>RMS error [mrad]</th><th>peak force [N]</th><th class=l>ISO/TS 15066, hand"
        "</th></tr>" + rows + "</table>",
        "<p>" + pages.esc(
            "What is new: the report characterises the prototype in free space and gives "
            "no collision figure, so nothing here is compared with a report value. The "
            "figure tests the argument of Bicchi and Tonietti (2004) for variable "
            "stiffness: a softer setting lowers the force of a collision at a cost in "
            "tracking.") + "</p>"]
    return pages.document("vsj study: tracking against safety", body)


def _verdict(result: Tradeoff, force: float) -> str:
    if force <= result.quasi_static_limit:
        return "within the quasi-static and transient limits"
    if force <= result.transient_limit:
        return "within the transient limit only"
    return "above the transient limit"


__all__ = ["Setup", "Tradeoff", "figure", "page", "run"]

"""Contact events from a run's sampled signals, and the figures of each.

A *contact event* is a maximal run of samples with a positive contact force. Its figures
come from the samples alone, whatever computed them, so the same function serves a
simulated contact and a measured one:

peak force
    The largest sample [N]. The true peak may lie between samples: where the force has
    curvature ``F''`` it exceeds the sampled peak by at most ``|F''| h^2 / 8`` (``h``
    the sample spacing, `ContactEvent.resolution`).
impulse
    ``int F dt`` [N s] by the trapezoidal rule over the event's samples and the zero
    samples that bracket it.
duration
    The contact began after the last zero sample before the event and at or before its
    first positive sample, and likewise at its end: `ContactEvent.duration_bounds`
    holds the shortest and longest durations the samples allow, `ContactEvent.duration`
    their midpoint (within ``resolution`` of the truth). An event cut by the start or the
    end of the run has no bracketing zero on that side: its longest duration is ``inf``
    and its duration counts from (to) the run's first (last) sample.
energy
    Two readings, whichever the caller can give. ``body_velocity`` (the surrogate body's
    velocity at the contact along the direction the contact force pushes it) gives the
    *work of the contact force on the body*, ``int F v dt`` over the event
    (`ContactEvent.work`: the energy the body kept when the contact ended; for an event
    cut by the run's end, what it had received by then). ``body_energy``
    (the surrogate body's mechanical energy, kinetic plus that of its own spring) gives
    its *peak rise* during the event (`ContactEvent.body_energy_gain`).
    `ContactEvent.energy` is the work when it is known, else the energy rise;
    `ContactEvent.energy_kind` says which.
joint
    Peak magnitudes over the event of the elastic elements' deflections [rad] and spring
    torques [N m], one per element, and the margin to the end stop (the stop angle
    minus the peak deflection; negative when the element went past it, onto the stop).

Signals over the event are read over its samples and the bracketing zero samples (where
the run has them), so a deflection that peaks as the contact ends is still seen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ._checks import non_negative, number, series, time_axis
from .iso_ts_15066 import BodyRegion, Tip, Verdict, verdict


@dataclass(frozen=True)
class ContactEvent:
    """One contact event of a run (`contact_events`); SI units throughout.

    Attributes
    ----------
    first, last : int
        Indices of the event's first and last sample with a positive force.
    start, end : float
        Estimated start and end of the contact [s]: midway between the last zero sample
        and the first positive one (the first positive sample if the run starts in
        contact), and likewise at the end.
    duration_bounds : tuple of float
        Shortest and longest contact durations the samples allow [s] (the longest is
        ``inf`` for an event cut by the run's start or end).
    cut_at_start, cut_at_end : bool
        Whether the run starts or ends in this contact.
    resolution : float
        Largest sample spacing over the event [s]: the timing error of ``start``,
        ``end`` and ``peak_time``.
    peak_force : float
        Largest force sample [N].
    peak_time : float
        Time of that sample [s].
    impulse : float
        ``int F dt`` [N s].
    peak_pressure : float or None
        Largest mean contact pressure [Pa] given a `Tip`.
    peak_penetration : float or None
        Largest contact penetration [m].
    work : float or None
        Work of the contact force on the body over the event [J].
    body_energy_gain : float or None
        Peak rise of the body's mechanical energy during the event [J].
    peak_deflection, peak_spring_torque : tuple of float or None
        Peak ``|deflection|`` [rad] and ``|spring torque|`` [N m] per elastic element.
    end_stop_margin : tuple of float or None
        End-stop angle minus peak deflection [rad], per element.
    """

    first: int
    last: int
    start: float
    end: float
    duration_bounds: tuple[float, float]
    cut_at_start: bool
    cut_at_end: bool
    resolution: float
    peak_force: float
    peak_time: float
    impulse: float
    peak_pressure: float | None = None
    peak_penetration: float | None = None
    work: float | None = None
    body_energy_gain: float | None = None
    peak_deflection: tuple[float, ...] | None = None
    peak_spring_torque: tuple[float, ...] | None = None
    end_stop_margin: tuple[float, ...] | None = None

    @property
    def duration(self) -> float:
        """Estimated contact duration [s], ``end - start``."""
        return self.end - self.start

    @property
    def energy(self) -> float | None:
        """Energy transferred to the body [J]: `work` if known, else `body_energy_gain`
        (`energy_kind` says which; None when neither signal was given)."""
        return self.work if self.work is not None else self.body_energy_gain

    @property
    def energy_kind(self) -> str | None:
        """``"work"`` (work of the contact force on the body), ``"body energy"`` (peak
        rise of the body's mechanical energy) or None."""
        if self.work is not None:
            return "work"
        return None if self.body_energy_gain is None else "body energy"

    def verdict(self, body: str | BodyRegion, contact: str = "transient",
                area: str | None = None) -> Verdict:
        """The event's peak force (and peak pressure, if known) against body region
        ``body``'s ISO/TS 15066 limits (`vsj.safety.verdict`)."""
        return verdict(body, self.peak_force, self.peak_pressure, contact, area)


def _runs(positive: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of each maximal run of True."""
    edges = np.diff(positive.astype(np.int8))
    starts = list(np.flatnonzero(edges == 1) + 1)
    ends = list(np.flatnonzero(edges == -1))
    if positive[0]:
        starts.insert(0, 0)
    if positive[-1]:
        ends.append(positive.size - 1)
    return [(int(a), int(b)) for a, b in zip(starts, ends)]


def _trapezoid(y: np.ndarray, t: np.ndarray) -> float:
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t))) if y.size > 1 else 0.0


def _per_element(values: np.ndarray) -> tuple[float, ...]:
    peak = np.max(np.abs(values), axis=0)
    return tuple(float(p) for p in np.atleast_1d(peak))


def contact_events(time, force, *, penetration=None, body_velocity=None, body_energy=None,
                   deflection=None, spring_torque=None, end_stop=None,
                   tip: Tip | None = None) -> list[ContactEvent]:
    """The contact events of one contact's sampled signals, in time order (none if the
    force is never positive).

    Parameters
    ----------
    time : array_like, shape (n,)
        Sample times [s], strictly increasing, at least two.
    force : array_like, shape (n,)
        Contact force [N], >= 0 (a unilateral contact only pushes).
    penetration : array_like, shape (n,), optional
        Contact penetration [m] (needed for a spherical `Tip`'s pressure).
    body_velocity : array_like, shape (n,), optional
        The surrogate body's velocity at the contact [m/s], positive in the direction the
        contact force pushes it: gives `ContactEvent.work`.
    body_energy : array_like, shape (n,), optional
        The surrogate body's mechanical energy [J]: gives `ContactEvent.body_energy_gain`.
    deflection, spring_torque : array_like, shape (n,) or (n, m), optional
        Elastic deflection [rad] and spring torque [N m] of each of ``m`` elastic elements.
    end_stop : float or array_like of m floats, optional
        End-stop angle [rad] of the elements (needs ``deflection``).
    tip : Tip, optional
        The robot's contact geometry: gives `ContactEvent.peak_pressure`.
    """
    where = "contact_events"
    t = time_axis(where, time)
    n = t.size
    f = series(where, "force", force, n, "N")
    non_negative(where, "force", f, "N", "a contact force pushes, so it is >= 0")
    d = None if penetration is None else series(where, "penetration", penetration, n, "m")
    v = None if body_velocity is None else series(where, "body_velocity", body_velocity, n,
                                                  "m/s")
    e = None if body_energy is None else series(where, "body_energy", body_energy, n, "J")
    q = None if deflection is None else series(where, "deflection", deflection, n, "rad",
                                               columns=True)
    tau = None if spring_torque is None else series(where, "spring_torque", spring_torque, n,
                                                    "N m", columns=True)
    stop = _end_stop(where, end_stop, q)
    if tip is not None and not isinstance(tip, Tip):
        raise InputError(f"{where}: tip must be a vsj.safety.Tip (Tip.flat or Tip.sphere), "
                         f"got {tip!r}")
    if tip is not None and tip.needs_penetration and d is None:
        raise InputError(f"{where}: a spherical tip's pressure needs the penetration [m]")

    events = []
    for first, last in _runs(f > 0):
        cut_start, cut_end = first == 0, last == n - 1
        lo = first if cut_start else first - 1   # the bracketing zero samples, where
        hi = last if cut_end else last + 1       # the run has them
        span = slice(lo, hi + 1)
        inner = t[last] - t[first]
        outer = math.inf if cut_start or cut_end else t[hi] - t[lo]
        start = t[first] if cut_start else 0.5 * (t[lo] + t[first])
        end = t[last] if cut_end else 0.5 * (t[last] + t[hi])
        peak = first + int(np.argmax(f[first:last + 1]))
        in_contact = slice(first, last + 1)
        events.append(ContactEvent(
            first=first, last=last, start=float(start), end=float(end),
            duration_bounds=(float(inner), float(outer)), cut_at_start=cut_start,
            cut_at_end=cut_end,
            resolution=float(np.max(np.diff(t[span]))),
            peak_force=float(f[peak]), peak_time=float(t[peak]),
            impulse=_trapezoid(f[span], t[span]),
            peak_pressure=None if tip is None else float(np.max(tip.pressure(
                f[in_contact], None if d is None else d[in_contact]))),
            peak_penetration=None if d is None else float(np.max(d[span])),
            work=None if v is None else _trapezoid(f[span] * v[span], t[span]),
            body_energy_gain=None if e is None else float(np.max(e[span]) - e[lo]),
            peak_deflection=None if q is None else _per_element(q[span]),
            peak_spring_torque=None if tau is None else _per_element(tau[span]),
            end_stop_margin=None if stop is None else tuple(
                float(s - p) for s, p in zip(stop, _per_element(q[span])))))
    return events


def _end_stop(where: str, end_stop, deflection) -> tuple[float, ...] | None:
    """The end-stop angle of each element, or None."""
    if end_stop is None:
        return None
    if deflection is None:
        raise InputError(f"{where}: end_stop needs the deflection [rad] to measure a margin")
    elements = 1 if deflection.ndim == 1 else deflection.shape[1]
    values = np.atleast_1d(np.asarray(end_stop, dtype=object))
    if values.ndim != 1 or values.size not in (1, elements):
        raise InputError(f"{where}: end_stop must be one angle [rad] or one per elastic "
                         f"element ({elements}), got {end_stop!r}")
    stops = [number(where, "end_stop", s, "rad") for s in values]
    return tuple(stops * elements if len(stops) == 1 else stops)

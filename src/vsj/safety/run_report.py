"""The safety figures of a run: every contact event of every contact of its environment,
with the joint's deflections and spring torques, and its verdict against ISO/TS 15066.

`report` reads a run's `vsj.simulate.Result` (its ``contact.<name>.*`` signals, the
elastic elements' ``spring.*.deflection`` and ``.torque``) with the network it ran;
`vsj simulate` writes it into ``meta.json`` (each case's ``safety``) for a scenario with
an ``[environment]``.

A run's samples (its output step, 1 ms by default) can miss a short impact or its peak.
Given the run's plan, `report` samples the contacts again where they need it
(`vsj.simulate.refine`: the same trajectory, sampled finer), so that the figures do not
depend on the output step; each event says whether its samples resolve it.
"""

from __future__ import annotations

import numpy as np

from ..network import Structure
from ..simulate.refine import contact_samples, suspect_intervals
from ..simulate.result import Result
from ..springs import end_stop
from .events import contact_events
from .iso_ts_15066 import REGIONS, Tip, region


def _body(structure: Structure, e: int) -> tuple[int, float] | None:
    """The body contact ``e`` pushes (the flange on its ``body`` port, as
    `vsj.environment` and `vsj.components.Contact` name it): ``(i, c)``, its generalised
    coordinate and the rate c v_i [m/s] at which the body gives way per unit of it; None
    for a wall, or a body whose flange is not one coordinate."""
    element = structure.frictions[e]
    ports = [p for p in element.speed if p.rsplit(".", 1)[-1] == "body"]
    if len(ports) != 1:
        return None
    row, sources = structure.rows(ports[0])
    used = np.flatnonzero(row)
    if len(used) != 1 or np.any(sources):
        return None
    i = int(used[0])
    return i, -element.speed[ports[0]] * float(row[i])


def _body_velocity(structure: Structure, e: int, result) -> np.ndarray | None:
    """The speed [m/s] of the body contact ``e`` pushes, in the direction it pushes it,
    from its coordinate's speed signal (named as a run names it); None for a wall."""
    body = _body(structure, e)
    if body is None:
        return None
    i, rate = body
    names = {sig.flange: sig.name for sig in structure.signals}
    signal = f"{names.get(structure.free[i], structure.free[i])}.speed"
    return rate * result[signal] if signal in result.signals else None


def reads(structure: Structure, names) -> list[str]:
    """Those of the signal ``names`` the figures read: the contacts', the elastic elements'
    deflections and torques, the bodies' speeds."""
    flanges = {sig.flange: sig.name for sig in structure.signals}
    bodies = {f"{flanges.get(structure.free[b[0]], structure.free[b[0]])}.speed"
              for b in (_body(structure, e) for e, fr in enumerate(structure.frictions)
                        if fr.contact is not None) if b is not None}
    return [name for name in names if name.startswith("contact.") or name in bodies
            or (name.startswith("spring.") and name.endswith((".deflection", ".torque")))]


def report(result, structure: Structure, tip: Tip | None = None, *, plan=None) -> dict:
    """Per contact of ``structure``'s environment: its events (peak force, impulse,
    duration, energy transferred to a body, the joint's peak deflection, spring torque
    and margin to the end stop; the peak pressure with the tip's geometry ``tip``) and
    each event's verdict for the hand and the lower arm (ISO/TS 15066 Table A.2, and
    with ``tip`` the pressure on each region's most sensitive area). A body part struck
    by the tip can recoil: the limits of transient contact. One between the tip and a
    wall cannot, it is clamped: the limits of quasi-static contact, half of those
    (the event's ``contact`` says which). JSON-ready; empty without contacts.

    ``plan`` (the `vsj.engine.plan.Plan` the run ran; a run of `vsj.simulate.simulate`
    carries it as ``result.plan``) samples the contacts again where the run's samples
    could miss a contact or its peak (`vsj.simulate.refine.contact_samples`). Without
    it the figures come from the samples alone. Either way an event is ``resolved``
    when its samples bound its peak force within `vsj.simulate.refine.REL_TOL`; one
    that is not (a contact the time-stepper's step is too long for) says so."""
    plan = getattr(result, "plan", None) if plan is None else plan
    # the elastic elements: the springs with an end stop (the figures are against it)
    springs = [sp for sp in structure.springs if end_stop(sp.law, sp.parameters) is not None
               and f"spring.{sp.name}.deflection" in result.signals]
    contacts = [(e, element.name) for e, element in enumerate(structure.frictions)
                if element.contact is not None]
    if plan is not None and contacts and len(result.time) >= 2:
        wanted = reads(structure, result.signals)
        time, signals = contact_samples(plan, result.time,
                                        {name: result[name] for name in wanted})
        result = Result(time=time, signals=signals, units={}, ledger={}, success=True,
                        message="", solver={})
    deflection = np.column_stack([result[f"spring.{sp.name}.deflection"] for sp in springs]) \
        if springs else None
    torque = np.column_stack([result[f"spring.{sp.name}.torque"] for sp in springs]) \
        if springs else None
    stops = [end_stop(sp.law, sp.parameters)[0] for sp in springs]
    out = {}
    for e, name in contacts:
        force = np.maximum(result[f"contact.{name}.force"], 0.0)
        depth = result[f"contact.{name}.penetration"]
        events = contact_events(result.time, force, penetration=depth,
                                body_velocity=_body_velocity(structure, e, result),
                                deflection=deflection, spring_torque=torque,
                                end_stop=stops if springs else None, tip=tip)
        suspect = suspect_intervals(result.time, force, depth, result[f"contact.{name}.rate"],
                                    result.signals.get(f"work.{name}")) \
            if len(result.time) >= 2 else np.zeros(0, dtype=bool)
        kind = "quasi-static" if _body(structure, e) is None else "transient"
        out[name] = [_event(ev, [sp.name for sp in springs],
                            not suspect[max(ev.first - 1, 0):ev.last + 1].any(), kind)
                     for ev in events]
    return out


def _event(ev, springs: list[str], resolved: bool, contact: str) -> dict:
    entry = {
        "start": ev.start, "end": ev.end, "duration": ev.duration,
        "cut_at_end": ev.cut_at_end, "peak_force": ev.peak_force,
        "peak_time": ev.peak_time, "impulse": ev.impulse,
        "energy_to_body": ev.energy, "energy_kind": ev.energy_kind,
        "sample_resolution": ev.resolution, "samples": ev.last - ev.first + 1,
        "resolved": resolved,
    }
    if ev.peak_pressure is not None:
        entry["peak_pressure"] = ev.peak_pressure
    if springs and ev.peak_deflection is not None:
        entry["joint"] = {
            name: {"peak_deflection": float(ev.peak_deflection[j]),
                   "peak_spring_torque": float(ev.peak_spring_torque[j]),
                   "end_stop_margin": float(ev.end_stop_margin[j])}
            for j, name in enumerate(springs)}
    entry["contact"] = contact
    entry["iso_ts_15066"] = {body: str(ev.verdict(body, contact)) for body in REGIONS}
    entry["passed"] = {body: bool(ev.verdict(body, contact).passed) for body in REGIONS}
    return entry


def summary(figures: dict, until: float | None = None) -> list[str]:
    """One line per contact: its events and worst peak force with the verdicts; ``until``
    the time a failed run stopped at, which the figures go no further than."""
    lines = []
    cover = "" if until is None else f" up to t = {until:.6g} s, where the run stopped"
    for name, events in figures.items():
        if not events:
            lines.append(f"contact {name}: no contact{cover}")
            continue
        worst = max(events, key=lambda ev: ev["peak_force"])
        kind = worst.get("contact", "transient")
        verdicts = ", ".join(f"{region(b).title.lower()} "
                             f"{'within' if worst['passed'][b] else 'ABOVE'} the {kind} limits"
                             for b in REGIONS)
        if kind == "quasi-static":
            verdicts += ": clamped against a wall"
        unresolved = sum(not ev["resolved"] for ev in events)
        lines.append(f"contact {name}: {len(events)} event(s), peak {worst['peak_force']:.4g} N "
                     f"at {worst['peak_time']:.4g} s ({verdicts})"
                     + (f"; {unresolved} event(s) not resolved: the samples (the "
                        "time-stepper's steps) do not bound their force" if unresolved else "")
                     + cover)
    return lines


__all__ = ["reads", "report", "summary"]

"""A run's contacts sampled finely enough for their safety figures, whatever its output step.

A run is sampled on its output grid (1 ms by default). An impact on a stiff surface can
last a few microseconds: its peak force falls between two samples, or the whole contact
does, and figures read from the samples (`vsj.safety.events`) under-read it. The engine's
steps do not depend on where a run is sampled, so a plan run again gives the same
trajectory, and `contact_samples` samples it again where a contact can hide or peak,
pass after pass, each pass splitting a suspect interval between two samples into `SPLIT`
(`suspect_intervals`):

* no force at either end, but the work the contact's force did changed between them
  (the energy ledger's accumulator of the element, which stays exactly constant while
  the force is zero): a contact lies between the samples. Without the ledger (figures
  of samples alone), a penetration that could reach zero inside at the rate of either
  end (twice it, for the speed's change within the interval) stands in for it;
* a force at both ends, a penetration falling at the start and rising at the end that
  could reach zero inside the same way: the contact may part and close again;
* a force at either end and a penetration that stops rising inside (its rate changes
  sign), where its largest value can exceed both ends' by more than `REL_TOL` of itself:
  the force peaks between the samples;
* a sampled force peak whose second difference exceeds ``8 REL_TOL`` of it: a parabola
  through the three samples can rise more than `REL_TOL` above the middle one.

A run whose samples never come within reach of a contact (no force, and no penetration
that its rate could take to zero between two samples) is not run again. The passes end
when no interval is suspect, or at the scheme's resolution: the
time-stepper's step (its state exists at its steps only, so the samples are snapped to
them) or `FLOOR` for the adaptive schemes. What is still suspect there is a contact the
scheme resolves in too few steps for its force to be trusted (`vsj.safety.run_report`
marks such an event as not resolved).
"""

from __future__ import annotations

import numpy as np

from ..engine import core
from ..engine.plan import Plan
from .driver import block_samples
from .signals import catalogue, collect

#: Sub-intervals a pass splits a suspect interval into.
SPLIT = 32
#: Relative error of a contact's peak force and penetration the samples are refined to.
REL_TOL = 1e-3
#: Shortest sample spacing of the adaptive schemes' refinement [s] (a contact shorter than
#: this is not a mechanical one).
FLOOR = 1e-9
#: Passes at most (each refines by `SPLIT`: a 1 ms grid reaches about 1 ns in six).
PASSES = 6
#: New samples one pass may add; beyond, the refinement stops (what is left stays suspect).
MAX_NEW = 500_000


def suspect_intervals(t, force, depth, rate, work=None) -> np.ndarray:
    """Per interval between the samples ``t`` (n - 1 of them) of a contact's force,
    penetration and its rate (and the work its force has done, if known): whether the
    contact may hide in it or peak in it by more than `REL_TOL` (the module's tests)."""
    h = np.diff(t)
    f0, f1, d0, d1, r0, r1 = force[:-1], force[1:], depth[:-1], depth[1:], rate[:-1], rate[1:]
    apart = (f0 <= 0.0) & (f1 <= 0.0)
    if work is None:
        hidden = apart & ((d0 + 2.0 * np.maximum(r0, 0.0) * h > 0.0)
                          | (d1 + 2.0 * np.maximum(-r1, 0.0) * h > 0.0))
    else:
        hidden = apart & (np.diff(work) != 0.0)
    # inside a contact the penetration decelerates (concave): the tangents at the ends
    # bound its largest value from above, the larger end from below
    upper = np.minimum(d0 + r0 * h, d1 - r1 * h)
    lower = np.maximum(d0, d1)
    turning = ~apart & (r0 > 0.0) & (r1 <= 0.0) & (upper - lower > REL_TOL * np.abs(upper))
    # in contact at both ends, but the penetration could fall to zero inside (a parting)
    parting = (f0 > 0.0) & (f1 > 0.0) & (r0 < 0.0) & (r1 > 0.0) \
        & ((d0 + 2.0 * r0 * h <= 0.0) | (d1 - 2.0 * r1 * h <= 0.0))
    sharp = np.zeros_like(hidden)
    if len(force) >= 3:
        mid = force[1:-1]
        second = np.abs(force[:-2] - 2.0 * mid + force[2:])
        peak = (mid > 0.0) & (mid >= force[:-2]) & (mid >= force[2:]) \
            & (second > 8.0 * REL_TOL * mid)
        sharp[:-1] |= peak
        sharp[1:] |= peak
    return hidden | turning | parting | sharp


def _new_times(t, split, step) -> np.ndarray:
    """Times strictly inside each interval marked in ``split``: `SPLIT` - 1 evenly spaced,
    or with a fixed ``step`` the step grid's points there (up to `SPLIT` - 1 of them)."""
    a, b = t[:-1][split], t[1:][split]
    if not len(a):
        return np.zeros(0)
    inner = a[:, None] + (b - a)[:, None] * (np.arange(1, SPLIT) / SPLIT)[None, :]
    if step is not None:
        inner = np.round(inner / step) * step
        inner = np.where((inner > a[:, None]) & (inner < b[:, None]), inner, np.nan)
    new = np.unique(inner[np.isfinite(inner)])
    return new[~np.isin(new, t)]


def _sample(plan: Plan, times: np.ndarray, names: list[str], end: float | None = None):
    """The signals ``names`` of a fresh run of ``plan`` at ``times`` (increasing), block by
    block, and each contact's work so far (its ledger accumulator, ``work.<name>``):
    ``(times reached, signals)``. ``end``: where the run ends (its last steps depend on
    it: that of the run being sampled again; default the last of ``times``)."""
    structure, layout = plan.structure, plan.layout
    table = [s for s in catalogue(structure, ports=False, controller=plan.controller)
             if s.name in names]
    friction = layout.n_state + layout.acc_slices()["friction"].start
    columns = {f"work.{fr.name}": friction + e for e, fr in enumerate(structure.frictions)
               if fr.contact is not None}
    engine = plan.engine()
    run = plan.start(until=float(times[-1]) if end is None else end)
    extra = plan.controller.width if plan.controller is not None else 0
    per_block = block_samples(structure, layout, False, extra)
    parts: dict[str, list] = {name: [] for name in [*names, *columns]}
    reached = 0
    for start in range(0, len(times), per_block):
        chunk = times[start:start + per_block]
        out, coulomb, stuck = run.advance(chunk, finish=False)
        valid = len(chunk) if run.status == core.OK else \
            int(np.count_nonzero(~np.isnan(out[:, 0]))) if out.shape[1] else 0
        if table:
            signals, _ = collect(structure, engine, layout, chunk[:valid], out[:valid],
                                 coulomb[:valid], stuck[:valid], ports=False, table=table,
                                 controller=plan.controller)
            for name in names:
                parts[name].append(np.array(signals[name], dtype=float))
        for name, column in columns.items():
            parts[name].append(np.array(out[:valid, column], dtype=float))
        reached += valid
        if run.status != core.OK:
            break
    return times[:reached], {name: np.concatenate(values) if values else np.zeros(0)
                             for name, values in parts.items()}


def _merge(t, signals, t_new, new):
    """The two sample sets as one, in time order."""
    order = np.argsort(np.concatenate([t, t_new]), kind="stable")
    return (np.concatenate([t, t_new])[order],
            {name: np.concatenate([values, new[name]])[order]
             for name, values in signals.items()})


def contact_samples(plan: Plan, time, signals) -> tuple[np.ndarray, dict]:
    """``signals`` (a run of ``plan`` sampled at ``time``: name -> samples; every contact's
    ``contact.<name>.force``, ``.penetration`` and ``.rate`` among them) with samples
    added where `suspect_intervals` finds a contact hiding or peaking between two of them:
    ``(time, signals)``, each contact's work so far added as ``work.<name>``. Every signal
    is sampled at the added times; a sample of ``time`` keeps its value (the run again
    gives the same one). What the scheme's resolution leaves suspect,
    `suspect_intervals` still finds in the result."""
    t = np.asarray(time, dtype=float)
    signals = {name: np.asarray(values, dtype=float) for name, values in signals.items()}
    contacts = [fr.name for fr in plan.structure.frictions if fr.contact is not None]
    if len(t) < 2 or not contacts:
        return t, signals
    names = list(signals)
    step = plan.scheme.step if plan.scheme.name == "timestep" else None
    floor = FLOOR if step is None else step
    if not np.any(np.diff(t) > 1.5 * floor):  # sampled at every step already
        return t, signals
    near = False  # a contact, or a penetration that could reach zero between samples
    for name in contacts:
        force = signals[f"contact.{name}.force"]
        near |= bool(np.any(force > 0.0) or np.any(suspect_intervals(
            t, force, signals[f"contact.{name}.penetration"], signals[f"contact.{name}.rate"])))
    if not near:  # never within reach of a contact: nothing to sample again
        return t, signals
    # the run's end as the run had it (`run_plan`: its duration, or its last sample past
    # it by round-off), so that its steps are the same to the last
    end = max(plan.duration, float(t[-1]))
    # the contacts' work at the given samples: a second run, sampled as the first
    reached, work = _sample(plan, t, [], end)
    t = t[:len(reached)]
    signals = {name: values[:len(t)] for name, values in signals.items()} | work
    for _ in range(PASSES):
        suspect = np.zeros(len(t) - 1, dtype=bool)
        for name in contacts:
            suspect |= suspect_intervals(t, signals[f"contact.{name}.force"],
                                         signals[f"contact.{name}.penetration"],
                                         signals[f"contact.{name}.rate"],
                                         signals[f"work.{name}"])
        # an interval one step long (the time-stepper) or `FLOOR` is not split
        new = _new_times(t, suspect & (np.diff(t) > 1.5 * floor), step)
        if not len(new) or len(new) > MAX_NEW:
            break
        t_new, values = _sample(plan, new, names, end)
        t, signals = _merge(t, signals, t_new, values)
    return t, signals


__all__ = ["FLOOR", "MAX_NEW", "PASSES", "REL_TOL", "SPLIT", "contact_samples",
           "suspect_intervals"]

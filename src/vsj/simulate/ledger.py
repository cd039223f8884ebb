"""The energy ledger of a run: work in = stored change + dissipated + residual."""

from __future__ import annotations

import numpy as np

from ..engine import Engine, Layout
from ..network import Structure
from ..springs import GEOMETRIC_REPORT
from .signals import contact_energy, contact_rows


def contact_energies(structure: Structure, engine: Engine, y, t: float) -> dict[int, float]:
    """The elastic energy [J] of each contact of the environment (by friction element
    index) at state ``y`` and time ``t``."""
    out = {}
    n = structure.n
    sigma = None
    for e, fr in enumerate(structure.frictions):
        if fr.contact is None:
            continue
        if sigma is None:
            sigma = engine.source_signals(np.array([t]))[0][0]
        rx, ru = contact_rows(structure, e)
        k_c, n_c, _, gap = fr.contact
        out[e] = float(contact_energy(rx @ y[:n] + ru @ sigma - gap, k_c, n_c))
    return out


def ledger(structure: Structure, engine: Engine, layout: Layout, y0, y_end, duration):
    """Energy balance of a run: work in = stored change + dissipated (+ residual)."""
    n_state = 2 * layout.n + layout.n_motors
    acc = y_end[n_state:]
    slices = layout.acc_slices()
    (kin0, pot0, ind0), spring_v0 = engine.stored_energy(0.0, y0[:n_state])
    (kin1, pot1, ind1), spring_v1 = engine.stored_energy(duration, y_end[:n_state])
    work_in = {}
    for j, src in enumerate(structure.sources):
        work_in[f"source {src.name}"] = float(acc[slices["sources"]][j])
    for j, ld in enumerate(structure.loads):
        work_in[f"load {ld.name}"] = float(acc[slices["loads"]][j])
    for j, mo in enumerate(structure.motors):
        work_in[f"motor {mo.name} (electric)"] = float(acc[slices["electric"]][j])
    pivot_work = float(np.sum(acc[slices["pivot"]]))
    if structure.pivot.flange is not None:
        work_in["pivot (non-backdrivable) on springs"] = pivot_work
    dissipated = {f"friction {fr.name}": float(acc[slices["friction"]][e])
                  for e, fr in enumerate(structure.frictions) if fr.contact is None}
    # a contact's accumulator is the work its force took from the mechanism: what it
    # holds at the end (its elastic energy) and what it dissipated
    held0, held1 = (contact_energies(structure, engine, y[:n_state], t)
                    for y, t in ((y0, 0.0), (y_end, duration)))
    for e, fr in enumerate(structure.frictions):
        if fr.contact is not None:
            dissipated[f"contact {fr.name}"] = float(acc[slices["friction"]][e]
                                                     - (held1[e] - held0[e]))
    for j, mo in enumerate(structure.motors):
        dissipated[f"resistance {mo.name}"] = float(acc[slices["resistance"]][j])
    stops = acc[slices["stops"]]
    for k, sp in enumerate(structure.springs):
        if stops[k] != 0.0:
            dissipated[f"end stop {sp.name}"] = float(stops[k])
    stored = {"kinetic": float(kin1 - kin0), "springs": float(pot1 - pot0),
              "inductors": float(ind1 - ind0)}
    if held0:
        stored["contacts"] = float(sum(held1.values()) - sum(held0.values()))
    nonconservative = {}
    for k, sp in enumerate(structure.springs):
        if sp.law == GEOMETRIC_REPORT:
            dv = spring_v1[k] - spring_v0[k]
            w_spring = float(acc[slices["spring"]][k])
            w_pivot = float(acc[slices["pivot"]][k])
            nonconservative[f"spring {sp.name} (eq 3.8 is not a potential force)"] = float(
                w_pivot - w_spring - dv - stops[k])
    total_in = sum(work_in.values())
    total_stored = sum(stored.values())
    total_diss = sum(dissipated.values()) + sum(nonconservative.values())
    residual = total_in - total_stored - total_diss
    # the energy in play: what flowed in or out, or what the mechanism holds (a run
    # that rests under a load does almost no work, but its springs hold energy)
    held = max(abs(kin0) + abs(pot0) + abs(ind0) + sum(held0.values()),
               abs(kin1) + abs(pot1) + abs(ind1) + sum(held1.values()))
    scale = max(sum(abs(v) for v in work_in.values()), sum(abs(v) for v in dissipated.values()),
                abs(total_stored), held, 1e-300)
    return {"work_in": work_in, "stored_change": stored, "dissipated": dissipated,
            "nonconservative": nonconservative, "total_in": total_in,
            "total_stored": total_stored, "total_dissipated": total_diss,
            "residual": residual, "relative_residual": abs(residual) / scale}

"""Naming a run's samples: every flange, source, load, motor, friction element,
spring and connection as a signal with its unit."""

from __future__ import annotations

import numpy as np

from ..engine import Engine, Layout, observation_layout
from ..network import Signal, Structure


def state_names(structure: Structure) -> list[str]:
    names = [f"{f}.angle" for f in structure.free] + [f"{f}.speed" for f in structure.free]
    return names + [f"{m.name}.current" for m in structure.motors]


def collect(structure: Structure, engine: Engine, layout: Layout, t_out, out, coulomb, stuck,
            *, ports: bool) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Evaluate every signal at the samples (one compiled pass), then name them:
    ``(signals, units)`` keyed by signal name."""
    raw = engine.observe(t_out, out, coulomb)
    cols = observation_layout(layout)
    sig: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}

    def put(name, values, unit):
        sig[name] = np.ascontiguousarray(values)
        units[name] = unit

    x, v = raw[:, cols["x"]], raw[:, cols["v"]]
    sigma, u = raw[:, cols["sigma"]], raw[:, cols["u"]]
    named = {s.flange for s in structure.signals}
    probes = list(structure.signals) + [Signal(f, f) for f in structure.free if f not in named]
    for s in probes:
        rx, ru = structure.rows(s.flange)
        put(s.name, x @ rx + sigma @ ru, "rad")
        put(f"{s.name}.speed", v @ rx + u @ ru, "rad/s")
    if structure.pivot.flange is not None or structure.springs:
        put("q", raw[:, cols["q"]][:, 0], "m")
        put("q.rate", raw[:, cols["qdot"]][:, 0], "m/s")
    for j, src in enumerate(structure.sources):
        put(f"source.{src.name}.speed", u[:, j], "rad/s")
        put(f"source.{src.name}.torque", raw[:, cols["src_tau"]][:, j], "N m")
        put(f"source.{src.name}.power", u[:, j] * raw[:, cols["src_tau"]][:, j], "W")
    for j, ld in enumerate(structure.loads):
        tau, speed = raw[:, cols["ld_tau"]][:, j], raw[:, cols["ld_w"]][:, j]
        put(f"load.{ld.name}.torque", tau, "N m")
        put(f"load.{ld.name}.power", tau * speed, "W")
    for j, mo in enumerate(structure.motors):
        cur, volt = raw[:, cols["current"]][:, j], raw[:, cols["mo_V"]][:, j]
        put(f"motor.{mo.name}.current", cur, "A")
        put(f"motor.{mo.name}.voltage", volt, "V")
        put(f"motor.{mo.name}.speed", raw[:, cols["mo_w"]][:, j], "rad/s")
        put(f"motor.{mo.name}.power", volt * cur, "W")
    slip, torque = raw[:, cols["fr_s"]], raw[:, cols["fr_f"]]
    for e, fr in enumerate(structure.frictions):
        put(f"friction.{fr.name}.slip", slip[:, e], "rad/s")
        # the resistive torque: the one exception to the port convention (vsj.ports)
        put(f"friction.{fr.name}.torque", torque[:, e], "N m")
        put(f"friction.{fr.name}.power", -torque[:, e] * slip[:, e], "W")
        put(f"friction.{fr.name}.stuck", stuck[:, e].astype(float), "1")
    for k, sp in enumerate(structure.springs):
        put(f"spring.{sp.name}.deflection", raw[:, cols["sp_d"]][:, k], "rad")
        put(f"spring.{sp.name}.torque", raw[:, cols["sp_tau"]][:, k], "N m")
        put(f"spring.{sp.name}.stiffness", raw[:, cols["sp_k"]][:, k], "N m/rad")
        put(f"spring.{sp.name}.energy", raw[:, cols["sp_V"]][:, k], "J")
        put(f"spring.{sp.name}.power", raw[:, cols["sp_tau"]][:, k] * raw[:, cols["sp_dd"]][:, k],
            "W")
    if ports and len(t_out):
        for name, torque_c, power_c in port_flows(structure, raw, cols):
            put(f"port.{name}.torque", torque_c, "N m")
            put(f"port.{name}.power", power_c, "W")
    return sig, units


def port_flows(structure: Structure, raw, cols):
    """Torque and power through every connection, from Newton's law per flange.

    With all element torques known, the constraint forces follow from
    ``I domega/dt - Q = E^T nu`` (``E``: every kinematic constraint and source
    row). A connection ``a -- b`` transmits ``nu`` into flange ``a``; its
    power is ``nu * omega_a``.
    """
    A, B, I = structure.A, structure.B, structure.inertia
    accel = raw[:, cols["a"]] @ A.T + raw[:, cols["ud"]] @ B.T
    speed = raw[:, cols["v"]] @ A.T + raw[:, cols["u"]] @ B.T
    applied = -raw[:, cols["fr_f"]] @ structure.friction_rows
    applied += raw[:, cols["sp_tau"]] @ structure.spring_rows
    for j, ld in enumerate(structure.loads):
        applied[:, structure.index(ld.flange)] += raw[:, cols["ld_tau"]][:, j]
    for j, mo in enumerate(structure.motors):
        applied[:, structure.index(mo.flange)] += mo.torque_constant * raw[:, cols["current"]][:, j]
    residual = accel * I - applied
    E = structure.constraint_rows
    nu = residual @ np.linalg.pinv(E.T).T
    flows = []
    for r, name in enumerate(structure.constraint_names):
        if not name.startswith("connection "):
            continue
        a, b = name[len("connection "):].split(" -- ")
        torque = nu[:, r]
        flows.append((f"{a}--{b}", torque, torque * speed[:, structure.index(a)]))
    return flows

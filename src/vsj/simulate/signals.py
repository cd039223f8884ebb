"""Naming a run's samples: the signal table of a network.

`catalogue` lists, once, every signal a run of a network gives: its name, its unit,
what it is, and how it is computed from the engine's observation of a block of
samples (`vsj.engine.Engine.observe`). Results, the trajectory files (netCDF
attributes, CSV headers) and the streamed writer all read it, so a signal is
declared in one place. `collect` evaluates the table on one block.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Callable

import numpy as np

from ..engine import Engine, Layout, observation_layout
from ..network import Signal, Structure


#: A matrix with more nonzero entries than this per column, on average, is applied by
#: `numpy.einsum` in one pass; a sparser one (the network's incidence rows: a flange's
#: angle is one or two generalised angles) term by term, which costs a fraction.
SPARSE_TERMS = 4


def rows(samples: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """``samples @ matrix`` (a vector or a matrix; samples along the leading axes), each
    element of the result summed in the same order however many samples there are. A
    BLAS product may sum a row otherwise in a block of another height (OpenBLAS's
    kernels do), and a run sampled in blocks, or in a batch, must give the bits of one
    sampled at once.

    A sparse ``matrix`` (`SPARSE_TERMS`) is applied term by term: each element is the
    sum of its nonzero products in the order of the rows of ``matrix``, element-wise
    over the samples. A dense one goes through `numpy.einsum`, whose order depends on
    the shapes of ``matrix`` only."""
    matrix = np.asarray(matrix, dtype=float)
    table = matrix[:, None] if matrix.ndim == 1 else matrix
    if np.count_nonzero(table) > SPARSE_TERMS * table.shape[1]:
        spec = "...j,j->..." if matrix.ndim == 1 else "...j,jk->...k"
        return np.einsum(spec, samples, matrix, optimize=False)
    samples = np.asarray(samples, dtype=float)
    # the sums side by side in memory, each contiguous: a signal is one of them
    out = np.empty((table.shape[1],) + samples.shape[:-1])
    for c in range(table.shape[1]):
        used = np.flatnonzero(table[:, c])
        if not len(used):
            out[c] = 0.0
            continue
        total = np.multiply(samples[..., used[0]], table[used[0], c], out=out[c])
        for j in used[1:]:
            total += samples[..., j] * table[j, c]
    return out[0] if matrix.ndim == 1 else np.moveaxis(out, 0, -1)


def contact_rows(structure: Structure, e: int) -> tuple[np.ndarray, np.ndarray]:
    """``(row_x, row_sigma)``: friction element e's row over the generalised and the
    source angles (a contact's penetration, before its gap)."""
    row = structure.friction_rows[e]
    return row @ structure.A, row @ structure.B


def contact_energy(d, stiffness: float, exponent: float):
    """Elastic energy [J] of a Hunt-Crossley contact at penetration ``d`` [m]:
    k d^(n+1) / (n+1) where it is compressed, 0 apart."""
    d = np.maximum(np.asarray(d, dtype=float), 0.0)
    return stiffness * d ** (exponent + 1.0) / (exponent + 1.0)


def state_names(structure: Structure) -> list[str]:
    """Names of the engine's state components: each free flange's angle and speed, then
    each motor's armature current."""
    names = [f"{f}.angle" for f in structure.free] + [f"{f}.speed" for f in structure.free]
    return names + [f"{m.name}.current" for m in structure.motors]


@dataclass(frozen=True)
class Block:
    """One block of samples as the engine observed it: ``raw`` (rows of
    `vsj.engine.observation_layout` columns) and each friction element's stick state.
    ``parts``, if given, holds some groups of columns as arrays of their own instead
    (rows: samples; ``raw`` is then None): the light signals (`LIGHT_COLUMNS`) of runs
    that were not observed."""

    raw: np.ndarray | None
    stuck: np.ndarray
    columns: dict
    cache: dict
    #: a controller's columns of the samples (its bus, then its actuators), if any
    control: np.ndarray | None = None
    parts: dict | None = None

    def col(self, name: str) -> np.ndarray:
        """The samples of one group of observation columns (rows: samples)."""
        if self.parts is not None:
            return self.parts[name]
        return self.raw[:, self.columns[name]]


#: Columns of `Engine.observe` that are the sampled state or the sources' angles and
#: speeds (which `Engine.source_signals` gives without evaluating the model).
LIGHT_COLUMNS = frozenset({"x", "v", "current", "sigma", "u"})


@dataclass(frozen=True)
class SignalSpec:
    """A signal of a run: ``name``, SI ``unit``, ``description``, ``values`` (its
    samples in a `Block`) and ``reads``, the observation columns it is computed from
    (``stuck``: the friction elements' stick states)."""

    name: str
    unit: str
    description: str
    values: Callable[[Block], np.ndarray]
    reads: frozenset = frozenset()

    @property
    def light(self) -> bool:
        """Whether the signal needs only the state and the sources (`LIGHT_COLUMNS`)."""
        return self.reads <= LIGHT_COLUMNS

    @property
    def needs_impulses(self) -> bool:
        """Whether the signal needs the time-stepper's stiction impulses, which only
        single runs sample (batch runs do not)."""
        return bool(self.reads & {"fr_f", "stuck"})


def catalogue(structure: Structure, *, ports: bool, controller=None) -> list[SignalSpec]:
    """Every signal a run of ``structure`` gives, in the order results list them; with
    ``controller`` (a `vsj.control.CompiledController`) its bus and actuators too."""
    table: list[SignalSpec] = []

    def add(name, unit, description, values, *reads):
        table.append(SignalSpec(name, unit, description, values, frozenset(reads)))

    if controller is not None:
        for j, (name, unit) in enumerate(zip(controller.bus, controller.units)):
            add(f"control.{name}", unit, f"controller signal {name} (held from its last "
                f"sample, every {controller.period:g} s)", lambda b, j=j: b.control[:, j])
        n_bus = len(controller.bus)
        for j, (channel, unit) in enumerate(zip(controller.channels, controller.channel_units)):
            add(f"actuator.{channel}", unit, f"what the controller applies to input {channel} "
                "(after its limits)", lambda b, j=j: b.control[:, n_bus + j])

    named = {s.flange for s in structure.signals}
    probes = list(structure.signals) + [Signal(f, f) for f in structure.free if f not in named]
    for s in probes:
        rx, ru = structure.rows(s.flange)
        what = f"{s.description} (flange {s.flange})" if s.description else f"flange {s.flange}"
        add(s.name, "rad", f"angle: {what}",
            lambda b, rx=rx, ru=ru: rows(b.col("x"), rx) + rows(b.col("sigma"), ru), "sigma", "x")
        add(f"{s.name}.speed", "rad/s", f"speed: {what}",
            lambda b, rx=rx, ru=ru: rows(b.col("v"), rx) + rows(b.col("u"), ru), "u", "v")
    if structure.pivot.flange is not None or structure.springs:
        add("q", "m", "pivot position of the elastic elements", lambda b: b.col("q")[:, 0], "q")
        add("q.rate", "m/s", "rate of the pivot position", lambda b: b.col("qdot")[:, 0], "qdot")
    for j, src in enumerate(structure.sources):
        add(f"source.{src.name}.speed", "rad/s", f"prescribed speed of source {src.name}",
            lambda b, j=j: b.col("u")[:, j], "u")
        add(f"source.{src.name}.torque", "N m", f"torque source {src.name} supplies",
            lambda b, j=j: b.col("src_tau")[:, j], "src_tau")
        add(f"source.{src.name}.power", "W", f"power source {src.name} supplies",
            lambda b, j=j: b.col("u")[:, j] * b.col("src_tau")[:, j], "src_tau", "u")
    for j, ld in enumerate(structure.loads):
        add(f"load.{ld.name}.torque", "N m", f"external torque {ld.name}",
            lambda b, j=j: b.col("ld_tau")[:, j], "ld_tau")
        add(f"load.{ld.name}.power", "W", f"power of external torque {ld.name}",
            lambda b, j=j: b.col("ld_tau")[:, j] * b.col("ld_w")[:, j], "ld_tau", "ld_w")
    for j, mo in enumerate(structure.motors):
        add(f"motor.{mo.name}.current", "A", f"armature current of motor {mo.name}",
            lambda b, j=j: b.col("current")[:, j], "current")
        add(f"motor.{mo.name}.voltage", "V", f"armature voltage of motor {mo.name}",
            lambda b, j=j: b.col("mo_V")[:, j], "mo_V")
        add(f"motor.{mo.name}.speed", "rad/s", f"rotor speed of motor {mo.name}",
            lambda b, j=j: b.col("mo_w")[:, j], "mo_w")
        add(f"motor.{mo.name}.power", "W", f"electric power into motor {mo.name}",
            lambda b, j=j: b.col("mo_V")[:, j] * b.col("current")[:, j], "current", "mo_V")
    for e, fr in enumerate(structure.frictions):
        if fr.contact is not None:  # the environment's contacts: force, penetration
            rx, ru = contact_rows(structure, e)
            k_c, n_c, _, gap = fr.contact
            add(f"contact.{fr.name}.force", "N", f"force of contact {fr.name} (>= 0)",
                lambda b, e=e: b.col("fr_f")[:, e], "fr_f")
            add(f"contact.{fr.name}.penetration", "m", f"penetration of contact {fr.name} "
                "(negative: apart by that distance)",
                lambda b, rx=rx, ru=ru, gap=gap: rows(b.col("x"), rx) + rows(b.col("sigma"), ru)
                - gap, "x", "sigma")
            add(f"contact.{fr.name}.rate", "m/s", f"rate of penetration of contact {fr.name}",
                lambda b, e=e: b.col("fr_s")[:, e], "fr_s")
            add(f"contact.{fr.name}.power", "W", f"power into contact {fr.name}",
                lambda b, e=e: b.col("fr_f")[:, e] * b.col("fr_s")[:, e], "fr_f", "fr_s")
            add(f"contact.{fr.name}.energy", "J", f"elastic energy stored in contact {fr.name}",
                lambda b, rx=rx, ru=ru, gap=gap, k_c=k_c, n_c=n_c: contact_energy(
                    rows(b.col("x"), rx) + rows(b.col("sigma"), ru) - gap, k_c, n_c),
                "x", "sigma")
            continue
        add(f"friction.{fr.name}.slip", "rad/s", f"slip speed of friction element {fr.name}",
            lambda b, e=e: b.col("fr_s")[:, e], "fr_s")
        # the resistive torque: the one exception to the port convention (vsj.ports)
        add(f"friction.{fr.name}.torque", "N m",
            f"resistive torque of friction element {fr.name}",
            lambda b, e=e: b.col("fr_f")[:, e], "fr_f")
        add(f"friction.{fr.name}.power", "W", f"power friction element {fr.name} delivers "
            "(never positive)", lambda b, e=e: -b.col("fr_f")[:, e] * b.col("fr_s")[:, e],
            "fr_f", "fr_s")
        add(f"friction.{fr.name}.stuck", "1", f"1 while friction element {fr.name} holds",
            lambda b, e=e: b.stuck[:, e].astype(float), "stuck")
    for k, sp in enumerate(structure.springs):
        add(f"spring.{sp.name}.deflection", "rad", f"deflection of spring {sp.name}",
            lambda b, k=k: b.col("sp_d")[:, k], "sp_d")
        add(f"spring.{sp.name}.torque", "N m", f"torque of spring {sp.name}",
            lambda b, k=k: b.col("sp_tau")[:, k], "sp_tau")
        add(f"spring.{sp.name}.stiffness", "N m/rad", f"local stiffness of spring {sp.name}",
            lambda b, k=k: b.col("sp_k")[:, k], "sp_k")
        add(f"spring.{sp.name}.energy", "J", f"energy stored in spring {sp.name}",
            lambda b, k=k: b.col("sp_V")[:, k], "sp_V")
        add(f"spring.{sp.name}.power", "W", f"power spring {sp.name} delivers",
            lambda b, k=k: b.col("sp_tau")[:, k] * b.col("sp_dd")[:, k], "sp_dd", "sp_tau")
    if ports:
        flows = PortFlows(structure)
        for r, name, a in flows.connections:
            add(f"port.{name}.torque", "N m", f"torque through connection {name}",
                lambda b, r=r: flows.torque(b)[:, r], *PortFlows.TORQUE_READS)
            add(f"port.{name}.power", "W", f"power through connection {name}",
                lambda b, r=r, a=a: flows.torque(b)[:, r] * flows.speed(b)[:, a],
                *PortFlows.TORQUE_READS, *PortFlows.SPEED_READS)
    return table


def collect(structure: Structure, engine: Engine, layout: Layout, t_out, out, coulomb, stuck,
            *, ports: bool, table: list[SignalSpec] | None = None, controller=None
            ) -> tuple[dict[str, np.ndarray], dict[str, str]]:
    """Evaluate every signal at the samples (one compiled pass over the block), then name
    them: ``(signals, units)`` keyed by signal name. A signal that is one column of the
    engine's observation is a view of it, not a copy: the sinks copy what they keep
    (`vsj.simulate.MemorySink` into its arrays, a trajectory file into its own byte
    order)."""
    table = catalogue(structure, ports=ports, controller=controller) if table is None else table
    if ports is False:
        table = [s for s in table if not s.name.startswith("port.")]
    width = controller.width if controller is not None else 0
    # the engine observes sample by sample (rows); every signal reads whole columns, and
    # the sinks write them: a column-major copy makes each column one contiguous run
    raw = np.asfortranarray(engine.observe(t_out, out, coulomb))
    block = Block(raw=raw, stuck=stuck, columns=observation_layout(layout), cache={},
                  control=np.asarray(out)[:, np.asarray(out).shape[1] - width:] if width else None)
    if not len(t_out):
        return ({s.name: np.zeros(0) for s in table if not s.name.startswith("port.")},
                {s.name: s.unit for s in table if not s.name.startswith("port.")})
    return ({s.name: s.values(block) for s in table},
            {s.name: s.unit for s in table})


class PortFlows:
    """Torque and power through every connection, from Newton's law per flange.

    With all element torques known, the constraint forces follow from
    ``I domega/dt - Q = E^T nu`` (``E``: every kinematic constraint and source
    row). A connection ``a -- b`` transmits ``nu`` into flange ``a``; its
    power is ``nu * omega_a``.
    """

    #: observation columns `torque` and `speed` read
    TORQUE_READS = ("a", "ud", "fr_f", "sp_tau", "ld_tau", "current")
    SPEED_READS = ("v", "u")

    def __init__(self, structure: Structure):
        self.structure = structure
        self.connections = []
        used = []
        for r, name in enumerate(structure.constraint_names):
            if name.startswith("connection "):
                a, b = name[len("connection "):].split(" -- ")
                self.connections.append((len(used), f"{a}--{b}", structure.index(a)))
                used.append(r)
        # only the connections' forces are asked for: the other constraints' columns of
        # the solve are left out
        self.solve = np.linalg.pinv(structure.constraint_rows.T).T[:, used]

    def speed(self, block: Block) -> np.ndarray:
        """Speed of every flange [rad/s] at the block's samples (kept in its cache)."""
        if "speed" not in block.cache:
            s = self.structure
            block.cache["speed"] = rows(block.col("v"), s.A.T) + rows(block.col("u"), s.B.T)
        return block.cache["speed"]

    def torque(self, block: Block) -> np.ndarray:
        """Force of every connection [N m] at the block's samples (columns in the order
        of `connections`), from Newton's law per flange (kept in its cache)."""
        if "nu" not in block.cache:
            s = self.structure
            accel = rows(block.col("a"), s.A.T) + rows(block.col("ud"), s.B.T)
            applied = -rows(block.col("fr_f"), s.friction_rows)
            applied += rows(block.col("sp_tau"), s.spring_rows)
            for j, ld in enumerate(s.loads):
                applied[:, s.index(ld.flange)] += block.col("ld_tau")[:, j]
            for j, mo in enumerate(s.motors):
                applied[:, s.index(mo.flange)] += mo.torque_constant * block.col("current")[:, j]
            block.cache["nu"] = rows(accel * s.inertia - applied, self.solve)
        return block.cache["nu"]


def port_flows(structure: Structure, raw, cols):
    """``(name, torque, power)`` through every connection, from a block's raw
    observation (see `PortFlows`)."""
    flows = PortFlows(structure)
    block = Block(raw=raw, stuck=np.zeros((len(raw), 0), dtype=bool), columns=cols, cache={})
    nu, speed = flows.torque(block), flows.speed(block)
    return [(name, nu[:, r], nu[:, r] * speed[:, a]) for r, name, a in flows.connections]

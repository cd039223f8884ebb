"""Assembly: components connected through flanges become one linear structure.

Components (see `vsj.components`) describe themselves as `Parts`: the flanges
they own, the inertia on each, the kinematic constraints between flange speeds,
and the elements acting on them (friction, springs, prescribed speeds, applied
torques, DC motors, the pivot position). `Network.assemble` collects the parts
of every component and every connection, and eliminates the rigid constraints
once, symbolically in the linear-algebra sense:

    omega = A v + B u

where ``v`` are the speeds of the *free* flanges (the generalised coordinates
the simulator integrates) and ``u`` the prescribed speeds of the velocity
sources. Everything the engine needs is then a constant matrix: the mass matrix
``A^T diag(I) A``, each element's relative speed as a row over ``(v, u)``, and
so on. This is how 20-sim resolves inertias in derivative causality
(docs/model-notes/assembly.md): no stiff artificial springs, one degree of freedom per
independent chain.

Which flanges become free is decided by a priority each component may give its
flanges (an elastic element prefers its ring angle as a state, a compliance its
far side), so states carry physical names such as ``pg1.ring``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from collections.abc import Mapping

import numpy as np

from .errors import InputError
from .ports import SEPARATOR
from .friction import DEFAULT_SHARPNESS
from .springs import spring_law

#: Priority of flanges driven by a source or fixed to the ground: never free.
PRESCRIBED = -1_000_000


@dataclass(frozen=True)
class Constraint:
    """A kinematic relation ``sum(c_i omega_i) = 0`` between flange speeds."""

    name: str
    coefficients: Mapping[str, float]


@dataclass(frozen=True)
class Friction:
    """A resistive element on the relative speed ``s = sum(c_i omega_i)``.

    ``viscous`` [N m s/rad], ``k`` [N m] and ``sharpness`` (arctan ``k_b``)
    [s/rad] are physical; the law is chosen per run (`vsj.friction`), unless
    ``law`` fixes it here. ``k`` is the report's stiction parameter: the gain
    of the equivalent arctan law ``k atan(k_b s)`` (section 4.1.3), so every
    law's Coulomb level is ``coulomb`` = ``k pi/2``. Components take the level
    as they prefer (`vsj.components.Bearing` accepts either).

    Clutches and brakes (`vsj.components.clutch`) scale the level: by the value
    of input channel ``normal`` (a normalised normal force, clipped to [0, 1])
    and by ``table``'s coefficient at the slip speed (rows of slip speed
    [rad/s] >= 0 and coefficient, linear between rows, constant beyond). With
    true stiction a stuck element holds up to ``peak`` (>= 1) times the level
    at zero speed before it breaks away.

    ``damper`` marks a damper (a spring-damper's viscous part): the
    time-stepper integrates its viscous part with the trapezoidal rule, as it
    does springs, so an oscillator keeps second-order accuracy; other
    elements' viscous parts take implicit Euler, which damps however stiff.

    ``contact`` makes it a contact of the environment instead (law ``contact``,
    `vsj.components.Contact`): ``(stiffness, exponent, damping, gap)``, ``speed`` then
    the row of its penetration [m per unit of each flange's angle].
    """

    name: str
    speed: Mapping[str, float]
    viscous: float = 0.0
    k: float = 0.0
    sharpness: float = DEFAULT_SHARPNESS
    law: str | None = None
    peak: float = 1.0
    normal: str | None = None
    table: tuple[tuple[float, float], ...] | None = None
    damper: bool = False
    contact: tuple[float, float, float, float] | None = None

    @property
    def coulomb(self) -> float:
        """The Coulomb (kinetic) friction level ``k pi/2`` [N m]."""
        return self.k * math.pi / 2


@dataclass(frozen=True)
class Spring:
    """An elastic element on the deflection ``d = sum(c_i phi_i)``.

    ``law`` and ``parameters`` select a law of
    `vsj.springs`; laws that depend on the pivot position
    read the network's `Pivot`.
    """

    name: str
    deflection: Mapping[str, float]
    law: int
    parameters: tuple[float, ...]


@dataclass(frozen=True)
class Source:
    """A velocity source: the speed of ``flange`` follows input ``channel``."""

    name: str
    flange: str
    channel: str


@dataclass(frozen=True)
class Load:
    """An applied torque from input ``channel`` on ``flange``."""

    name: str
    flange: str
    channel: str


@dataclass(frozen=True)
class Motor:
    """Armature circuit of a DC motor driving the rotor ``flange``.

    ``L di/dt = V - R i - k omega`` and the torque ``k i`` on the rotor, with
    the voltage ``V`` from input ``channel`` (SI: ``k`` in N m/A = V s/rad);
    ``voltage_limit`` [V] is its rating (a run above it is warned about).
    """

    name: str
    flange: str
    channel: str
    resistance: float
    inductance: float
    torque_constant: float
    voltage_limit: float = math.inf


@dataclass(frozen=True)
class Pivot:
    """The pivot position ``q`` [m] that the elastic elements read.

    ``q = amplitude * sin(angle of flange)`` (report section 3.4: the sine of
    the pivot planetary's carrier angle times the ring radius and a gain), or a
    constant ``fixed`` when ``flange`` is None (a bench with a pinned pivot).
    ``[q_min, q_max]`` [m] is the range the mechanism is allowed to use: a run
    whose pivot leaves it fails (the model carries its own limit, so no caller
    can forget to pass it).
    """

    flange: str | None
    amplitude: float = 0.0
    fixed: float = 0.0
    q_min: float = -math.inf
    q_max: float = math.inf


@dataclass(frozen=True)
class Signal:
    """A named output: the angle and speed of a flange."""

    name: str
    flange: str
    description: str = ""


@dataclass
class Parts:
    """What a component contributes to a network."""

    flanges: list[str] = field(default_factory=list)
    inertia: dict[str, float] = field(default_factory=dict)
    constraints: list[Constraint] = field(default_factory=list)
    frictions: list[Friction] = field(default_factory=list)
    springs: list[Spring] = field(default_factory=list)
    sources: list[Source] = field(default_factory=list)
    loads: list[Load] = field(default_factory=list)
    motors: list[Motor] = field(default_factory=list)
    pivots: list[Pivot] = field(default_factory=list)
    signals: list[Signal] = field(default_factory=list)
    priority: dict[str, int] = field(default_factory=dict)

    def embedded(self, flanges: Mapping[str, str], prefix: str) -> "Parts":
        """These parts as a piece of a larger component: every flange renamed through
        ``flanges`` (names not in it get ``prefix``), every element and constraint
        name prefixed with ``prefix``; the flange priorities are dropped (the
        larger component states its own)."""
        def fl(name: str) -> str:
            return flanges.get(name, f"{prefix}{name}")

        def over(mapping: Mapping[str, float]) -> dict[str, float]:
            out: dict[str, float] = {}
            for name, value in mapping.items():
                out[fl(name)] = out.get(fl(name), 0.0) + value
            return out

        rename = dataclasses.replace
        return Parts(
            flanges=[fl(f) for f in self.flanges],
            inertia=over(self.inertia),
            constraints=[Constraint(prefix + c.name, over(c.coefficients))
                         for c in self.constraints],
            frictions=[rename(f, name=prefix + f.name, speed=over(f.speed))
                       for f in self.frictions],
            springs=[rename(s, name=prefix + s.name, deflection=over(s.deflection))
                     for s in self.springs],
            sources=[rename(s, name=prefix + s.name, flange=fl(s.flange)) for s in self.sources],
            loads=[rename(ld, name=prefix + ld.name, flange=fl(ld.flange)) for ld in self.loads],
            motors=[rename(m, name=prefix + m.name, flange=fl(m.flange)) for m in self.motors],
            pivots=[rename(pv, flange=None if pv.flange is None else fl(pv.flange))
                    for pv in self.pivots],
            signals=[rename(sg, name=prefix + sg.name, flange=fl(sg.flange))
                     for sg in self.signals],
        )

    def merge(self, other: "Parts") -> "Parts":
        """Add ``other``'s elements to these parts in place: lists are extended, inertias on
        one flange add up, other mappings take ``other``'s value. Returns self."""
        for f in dataclasses.fields(self):
            mine = getattr(self, f.name)
            theirs = getattr(other, f.name)
            if isinstance(mine, dict):
                for key, value in theirs.items():
                    mine[key] = mine.get(key, 0.0) + value if f.name == "inertia" else value
            else:
                mine.extend(theirs)
        return self


class Component:
    """Base class: a named sub-model with flanges ``<name>.<port>``."""

    #: The ports other components may connect to.
    ports: tuple[str, ...] = ()

    def __init__(self, name: str):
        if not name or SEPARATOR in name:
            raise ValueError(f"component name {name!r} must be non-empty and contain no "
                             f"{SEPARATOR!r}")
        self.name = name

    def port(self, port: str) -> str:
        """Full flange name of one of this component's ports."""
        if port not in self.ports:
            raise ValueError(f"{type(self).__name__} {self.name!r} has no port {port!r}; "
                             f"ports: {', '.join(self.ports)}")
        return f"{self.name}{SEPARATOR}{port}"

    def node(self, local: str) -> str:
        """Full name of a flange of this component (a port or an internal one)."""
        return f"{self.name}{SEPARATOR}{local}"

    def embed(self, child: "Component", **ports: str) -> Parts:
        """The parts of ``child`` as a piece of this component (composition, as
        MSL's ``Gearbox`` is a ``LossyGear`` plus an ``ElastoBacklash``).

        ``ports`` joins each named port of the child to a flange of this one
        (``sun="pg_1.sun"``); the child's other flanges become internal nodes of
        this component, and its elements are named ``<this>.<child's name>``
        (a `Bearing` called ``bearing_sun`` in ``pg_1`` gives the friction
        element ``pg_1.bearing_sun``).
        """
        unknown = sorted(set(ports) - set(child.ports))
        if unknown:
            raise ValueError(f"{self.name}: {type(child).__name__} {child.name!r} has no port(s) "
                             f"{', '.join(unknown)}; ports: {', '.join(child.ports)}")
        joined = {child.port(port): flange for port, flange in ports.items()}
        return child.parts().embedded(joined, f"{self.name}{SEPARATOR}")

    def parts(self) -> Parts:
        """What this component adds to a network (the extension point of `Component`).

        Return a fresh `Parts` every call. Flanges are named with `port` (for
        the ports in ``ports``, which other components connect to) or `node`
        (internal ones); every flange an element refers to must be listed in
        ``flanges``. Inertias add up where several components give one to the
        same flange. Element names (frictions, springs, ...) should start with
        the component's name, since they name the signals of a run
        (``friction.<name>.torque``). Relations between flange speeds go in
        ``constraints``; ``priority`` says which flanges a component prefers
        as states (higher: more likely free). Parameters are checked in the
        constructor, so that ``parts`` cannot fail.
        """
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.name!r})"


class Network:
    """Components and the rigid connections between their flanges."""

    def __init__(self, name: str = "network"):
        self.name = name
        self.components: list[Component] = []
        self.connections: list[tuple[str, str]] = []
        self.signals: list[Signal] = []

    def add(self, *components: Component) -> "Network":
        """Add components (their names must be unique in the network); returns the network,
        for chaining."""
        names = {c.name for c in self.components}
        for c in components:
            if c.name in names:
                raise ValueError(f"network {self.name!r} already has a component {c.name!r}")
            names.add(c.name)
            self.components.append(c)
        return self

    def replace(self, component: Component) -> "Network":
        """Put ``component`` in place of the sub-model of the same name.

        The connections stay as they are, so the new component must offer
        every port they use (a custom elastic element named ``vsm_1`` with a
        ``ring`` port, say). Returns the network, for chaining.
        """
        names = [c.name for c in self.components]
        if component.name not in names:
            raise InputError(f"network {self.name!r} has no component {component.name!r} to "
                             f"replace; its components are {', '.join(names)}")
        used = {flange.split(SEPARATOR, 1)[1] for pair in self.connections for flange in pair
                if flange.split(SEPARATOR, 1)[0] == component.name}
        missing = sorted(used - set(component.ports))
        if missing:
            raise InputError(f"{type(component).__name__} {component.name!r} cannot replace the "
                             f"{type(self.components[names.index(component.name)]).__name__}: "
                             f"the network connects its port(s) {', '.join(missing)}, which it "
                             f"lacks (its ports: {', '.join(component.ports) or 'none'})")
        self.components[names.index(component.name)] = component
        return self

    def connect(self, a: str, b: str) -> "Network":
        """Join two flanges rigidly (common speed, report section 3.1)."""
        self.connections.append((a, b))
        return self

    def signal(self, signal: Signal) -> "Network":
        """Publish the angle and speed of a flange under a name of its own."""
        self.signals.append(signal)
        return self

    def parts(self) -> Parts:
        """Everything the components contribute, merged, with the network's own published
        signals."""
        total = Parts()
        for c in self.components:
            total.merge(c.parts())
        total.signals.extend(self.signals)
        return total

    def assemble(self) -> "Structure":
        """The network's `Structure`: every component's parts collected and the rigid
        constraints eliminated once (`Structure.build`). Raises `InputError` for a
        network the engine cannot run (an unknown flange, a degree of freedom
        without inertia, over-determined sources)."""
        return Structure.build(self.name, self.parts(), self.connections)


def _row(coefficients: Mapping[str, float], index: Mapping[str, int], what: str) -> np.ndarray:
    row = np.zeros(len(index))
    for name, c in coefficients.items():
        if name not in index:
            raise InputError(f"{what} refers to unknown flange {name!r}")
        row[index[name]] += c
    return row


def eliminate(equations: np.ndarray, prescribed: np.ndarray, order: np.ndarray,
              tol: float = 1e-10):
    """Solve ``equations @ omega = prescribed @ u`` for omega = A v + B u.

    ``order`` lists node indices from most to least eager to be dependent; the
    reduced row echelon form picks pivots in that order, so the nodes left
    free (the generalised coordinates) are the last ones that can be.
    Returns ``(A, B, free, conflicts)`` where ``conflicts`` lists, for each
    equation that reduces to ``0 = (combination of u)``, the sources in it:
    sources that over-determine the mechanism.
    """
    E = equations.astype(float).copy()
    F = prescribed.astype(float).copy()
    n_rows, n_nodes = E.shape
    scale = np.max(np.abs(E)) if E.size else 1.0
    pivots: list[tuple[int, int]] = []
    row = 0
    for col in order:
        if row >= n_rows:
            break
        candidates = np.abs(E[row:, col])
        best = int(np.argmax(candidates)) + row if candidates.size else row
        if candidates.size == 0 or abs(E[best, col]) <= tol * scale:
            continue
        E[[row, best]] = E[[best, row]]
        F[[row, best]] = F[[best, row]]
        factor = E[row, col]
        E[row] /= factor
        F[row] /= factor
        for other in range(n_rows):
            if other != row and E[other, col] != 0.0:
                g = E[other, col]
                E[other] -= g * E[row]
                F[other] -= g * F[row]
        pivots.append((row, col))
        row += 1
    E[np.abs(E) < tol * scale] = 0.0
    dependent = {col for _, col in pivots}
    free = [col for col in order if col not in dependent]
    free.sort()
    conflicts = [[int(j) for j in np.flatnonzero(np.abs(F[r]) > tol)]
                 for r in range(row, n_rows) if np.any(np.abs(F[r]) > tol)]
    A = np.zeros((n_nodes, len(free)))
    B = np.zeros((n_nodes, F.shape[1]))
    for j, col in enumerate(free):
        A[col, j] = 1.0
    for r, col in pivots:
        A[col] = -E[r, free]
        B[col] = F[r]
    return A, B, free, conflicts


def _rigid_motion(Sx: np.ndarray, Su: np.ndarray, springs, pivot) -> np.ndarray:
    """How the free coordinates follow the sources when every spring stays undeflected.

    Returns ``E`` (n x s) such that measuring the free coordinates relative to
    ``E sigma`` keeps them as small as the springs' deflections (the
    stiffness-weighted least-squares solution of ``Sx E = -Su``). Modelica
    prefers springs' relative angles as states for the same reason: a
    carrier turning 100 rad must not cost the accuracy of a 1e-5 rad twist.
    """
    n, s = Sx.shape[1], Su.shape[1]
    if n == 0 or s == 0 or not len(springs) or not np.any(Su):
        return np.zeros((n, s))
    q = pivot.fixed
    weights = np.array([max(spring_law(sp.law, tuple(sp.parameters), 0.0, q)[1], 1e-12)
                        for sp in springs])
    Wsx = Sx * weights[:, None]
    return -np.linalg.pinv(Sx.T @ Wsx, rcond=1e-12) @ (Wsx.T @ Su)


def kinematics(parts: Parts, connections) -> tuple[list[str], list[Constraint], np.ndarray]:
    """Flanges, constraints and the constraint matrix ``C`` (``C omega = 0``)."""
    nodes = list(dict.fromkeys(parts.flanges))
    index = {n: i for i, n in enumerate(nodes)}
    for a, b in connections:
        for f in (a, b):
            if f not in index:
                raise InputError(f"connection {a} -- {b}: unknown flange {f!r}; "
                                 f"known flanges: {', '.join(nodes)}")
    constraints = list(parts.constraints) + [
        Constraint(f"connection {a} -- {b}", {a: 1.0, b: -1.0}) for a, b in connections]
    C = np.array([_row(c.coefficients, index, c.name) for c in constraints])
    return nodes, constraints, C.reshape(len(constraints), len(nodes))


@dataclass
class Structure:
    """A network after elimination: everything the engine needs, as matrices.

    Speeds of all flanges are ``A v + B u``; angles are ``A x + B sigma`` with
    ``sigma`` the integrals of the source speeds. Row vectors named ``*_x``
    multiply ``v`` (or ``x``), ``*_u`` multiply ``u`` (or ``sigma``).
    """

    name: str
    nodes: tuple[str, ...]
    inertia: np.ndarray
    free: tuple[str, ...]
    A: np.ndarray
    B: np.ndarray
    sources: tuple[Source, ...]
    frictions: tuple[Friction, ...]
    springs: tuple[Spring, ...]
    loads: tuple[Load, ...]
    motors: tuple[Motor, ...]
    pivot: Pivot
    signals: tuple[Signal, ...]
    friction_rows: np.ndarray
    spring_rows: np.ndarray
    constraint_names: tuple[str, ...]
    constraint_rows: np.ndarray
    #: least-norm solutions of the initial state's rows, per named flanges (`_least_norm`),
    #: kept as long as the structure: its matrices are not changed once it is built
    _solvers: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @classmethod
    def build(cls, name: str, parts: Parts, connections) -> "Structure":
        """Eliminate the rigid constraints of ``parts`` plus ``connections`` (pairs of
        flanges) into ``omega = A v + B u`` and collect every element's row.

        Free flanges are chosen by ``parts.priority`` (sources never are); a
        spring-weighted offset keeps the free coordinates as small as the
        deflections (`_rigid_motion`). The result is immutable in use: the
        engine compiles it (`vsj.engine.compile_model`) once per run.
        """
        nodes, constraints, C = kinematics(parts, connections)
        index = {n: i for i, n in enumerate(nodes)}
        rows = list(C)
        driven = {}
        for s in parts.sources:
            if s.flange not in index:
                raise InputError(f"source {s.name!r} drives unknown flange {s.flange!r}")
            if s.flange in driven:
                raise InputError(f"flange {s.flange!r} is driven by two sources: "
                                 f"{driven[s.flange]!r} and {s.name!r}")
            driven[s.flange] = s.name
        n_nodes, n_src = len(nodes), len(parts.sources)
        source_rows = np.zeros((n_src, n_nodes))
        for j, s in enumerate(parts.sources):
            source_rows[j, index[s.flange]] = 1.0
        equations = np.vstack([np.array(rows).reshape(len(rows), n_nodes), source_rows])
        prescribed = np.vstack([np.zeros((len(rows), n_src)), np.eye(n_src)])

        priority = {n: parts.priority.get(n, 0) for n in nodes}
        for s in parts.sources:
            priority[s.flange] = PRESCRIBED
        order = np.array(sorted(range(n_nodes), key=lambda i: (priority[nodes[i]], i)), dtype=int)
        A, B, free, conflicts = eliminate(equations, prescribed, order)
        if conflicts:
            names = sorted({parts.sources[j].name for group in conflicts for j in group})
            raise InputError(
                f"network {name!r} is over-determined: the velocity sources "
                f"{', '.join(names)} prescribe speeds that the rigid connections do not allow "
                f"independently (remove a source or add a compliance)")
        inertia = np.array([parts.inertia.get(n, 0.0) for n in nodes])
        for n, value in parts.inertia.items():
            if n not in index:
                raise InputError(f"inertia given for unknown flange {n!r}")
            if not value >= 0.0:
                raise InputError(f"inertia of flange {n!r} must be >= 0, got {value!r}")
        pivots = parts.pivots or [Pivot(None, 0.0, 0.0)]
        if len(pivots) > 1:
            raise InputError(f"network {name!r} has {len(pivots)} pivot mechanisms; "
                             "the elastic elements share one pivot position")
        pivot = pivots[0]
        if pivot.flange is not None and pivot.flange not in index:
            raise InputError(f"pivot refers to unknown flange {pivot.flange!r}")
        friction_rows = np.array([_row(f.speed, index, f"friction {f.name!r}")
                                  for f in parts.frictions]).reshape(len(parts.frictions), n_nodes)
        spring_rows = np.array([_row(s.deflection, index, f"spring {s.name!r}")
                                for s in parts.springs]).reshape(len(parts.springs), n_nodes)
        B = B + A @ _rigid_motion(spring_rows @ A, spring_rows @ B, parts.springs, pivots[0])
        for element in list(parts.loads) + list(parts.motors):
            if element.flange not in index:
                raise InputError(f"{element.name!r} acts on unknown flange {element.flange!r}")
        for sig in parts.signals:
            if sig.flange not in index:
                raise InputError(f"signal {sig.name!r} refers to unknown flange {sig.flange!r}")
        structure = cls(
            name=name, nodes=tuple(nodes), inertia=inertia,
            free=tuple(nodes[i] for i in free), A=A, B=B,
            sources=tuple(parts.sources), frictions=tuple(parts.frictions),
            springs=tuple(parts.springs), loads=tuple(parts.loads),
            motors=tuple(parts.motors), pivot=pivot, signals=tuple(parts.signals),
            friction_rows=friction_rows, spring_rows=spring_rows,
            constraint_names=tuple([c.name for c in constraints]
                                   + [f"source {s.name}" for s in parts.sources]),
            constraint_rows=equations,
        )
        structure._check_inertia()
        return structure

    # -- derived matrices ---------------------------------------------------
    @property
    def n(self) -> int:
        """Number of degrees of freedom (free generalised speeds)."""
        return len(self.free)

    def index(self, flange: str) -> int:
        """Position of ``flange`` in ``nodes``; `InputError` if there is no such flange."""
        try:
            return self.nodes.index(flange)
        except ValueError:
            raise InputError(f"unknown flange {flange!r} in network {self.name!r}; its "
                             f"flanges are {', '.join(self.nodes)}") from None

    def mass_matrix(self) -> np.ndarray:
        """The mass matrix ``A^T diag(inertia) A`` [kg m^2] of the free speeds."""
        return self.A.T @ (self.inertia[:, None] * self.A)

    def _check_inertia(self) -> None:
        M = self.mass_matrix()
        if M.size == 0:
            return
        w, V = np.linalg.eigh(M)
        scale = max(float(np.max(np.abs(M))), 1e-300)
        massless = [j for j in range(len(w)) if w[j] <= 1e-12 * scale]
        if massless:
            names = sorted({self.free[i] for j in massless
                            for i in np.flatnonzero(np.abs(V[:, j]) > 1e-6)})
            raise InputError(
                f"network {self.name!r}: a degree of freedom has no inertia; it involves "
                f"{', '.join(names)}. Give one of these flanges an inertia, or remove the "
                f"compliance or connection that frees it")

    def rows(self, flange: str) -> tuple[np.ndarray, np.ndarray]:
        """``(row_x, row_u)`` of one flange's speed (and angle)."""
        i = self.index(flange)
        return self.A[i].copy(), self.B[i].copy()

    def channels(self) -> tuple[str, ...]:
        """Input channels in the order the engine stores them (sources first, then
        loads, motor voltages and normal forces)."""
        names = [s.channel for s in self.sources]
        names += [ld.channel for ld in self.loads] + [m.channel for m in self.motors]
        names += [f.normal for f in self.frictions if f.normal is not None]
        return tuple(dict.fromkeys(names))

    def describe(self) -> str:
        """A few lines in words: flanges, degrees of freedom, sources and element counts."""
        lines = [f"network {self.name}: {len(self.nodes)} flanges, {self.n} degrees of "
                 f"freedom ({', '.join(self.free) or 'none'})"]
        lines.append(f"  sources: {', '.join(s.name for s in self.sources) or 'none'}")
        lines.append(f"  friction elements: {len(self.frictions)}, springs: {len(self.springs)},"
                     f" loads: {len(self.loads)}, motors: {len(self.motors)}")
        return "\n".join(lines)

    def initial_positions(self, angles: Mapping[str, float]) -> tuple[np.ndarray, np.ndarray]:
        """Generalised positions ``x0`` and source angles ``sigma0`` for given flange angles.

        Flanges not named keep the smallest motion consistent with the named
        ones (least-norm solution); contradictory requests raise `InputError`.
        """
        n, s = self.n, len(self.sources)
        if not angles:
            return np.zeros(n), np.zeros(s)
        names = tuple(angles)
        target = np.array([angles[f] for f in names], dtype=float)
        sol = self._least_norm(target, names, True, "initial angles", "kinematic constraints")
        return sol[:n], sol[n:]

    def initial_speeds(self, speeds: Mapping[str, float], u0: np.ndarray) -> np.ndarray:
        """Generalised speeds ``v0`` for given flange speeds, given source speeds ``u0``."""
        if not speeds:
            return np.zeros(self.n)
        names = tuple(speeds)
        target = np.array([speeds[f] - self.rows(f)[1] @ u0 for f in names], dtype=float)
        return self._least_norm(target, names, False, "initial speeds",
                                "constraints or the source speeds")

    def _least_norm(self, target: np.ndarray, names: tuple[str, ...], angles: bool,
                    what: str, against: str) -> np.ndarray:
        """The least-norm solution of the named flanges' rows (their angles over the
        generalised and the source angles, or their speeds over the generalised speeds)
        equal to ``target``; `InputError` if no solution meets every row. The rows'
        pseudo-inverse is kept per set of names: batches and sweeps start many runs of
        one network from different angles."""
        key = (angles, names)
        if key not in self._solvers:
            rows = np.array([np.concatenate(self.rows(f)) if angles else self.rows(f)[0]
                             for f in names])
            # singular values cut off where lstsq's default cuts them (eps x size)
            cutoff = max(rows.shape) * np.finfo(float).eps
            self._solvers[key] = (rows, np.linalg.pinv(rows, rcond=cutoff))
        rows, inverse = self._solvers[key]
        sol = inverse @ target
        off = np.abs(rows @ sol - target) > 1e-9 * (1 + np.abs(target))
        if off.any():
            bad = [names[i] for i in np.flatnonzero(off)]
            raise InputError(f"{what} of {', '.join(bad)} contradict the {against} of network "
                             f"{self.name!r}")
        return sol

    def pivot_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """``(row_x, row_u)`` of the pivot flange's angle (zeros if the pivot is pinned)."""
        if self.pivot.flange is None:
            return np.zeros(self.n), np.zeros(len(self.sources))
        return self.rows(self.pivot.flange)

    def pivot_angle_for(self, q: float) -> float:
        """Angle of the pivot flange that puts the pivot at ``q`` [m]."""
        amp = self.pivot.amplitude
        if not abs(q) <= amp:
            raise InputError(f"pivot position {q!r} m is outside the mechanism's reach "
                             f"(|q| <= {amp} m)")
        return math.asin(q / amp)

"""The compiled form of a network: the plain arrays the C engine reads.

`compile_model` turns an assembled `Structure`, its inputs and the run's
options into an `EngineModel` (a named tuple of NumPy arrays, laid out as
``vsj_model`` in ``c/vsj.h``) and a `Layout` that names every slot of the
state and the accumulators.

Element rows are stacked in one matrix ``rows`` of shape ``(R, n + s)``: the
first ``n`` columns multiply the generalised coordinates, the last ``s`` the
source coordinates. The engine reads them in compressed sparse row form (most
rows hold one or two nonzeros), split into the two parts. Row order: friction
elements, springs, loads, motors, and the pivot last. ``par`` holds each row's
parameters, ``code`` its law code (friction, spring) or input channel (load,
motor).
"""

from __future__ import annotations

import fnmatch
import math
from dataclasses import dataclass
from collections import namedtuple
from collections.abc import Mapping

import numpy as np

from .. import friction as friction_laws
from ..errors import InputError
from ..inputs import Constant, Input, engine_pieces
from ..network import Structure
from ..control.controller import NO_CONTROLLER_ARRAYS, NO_CONTROLLER_SIZES

from .. import _core

#: Columns of ``par`` (rows are padded with zeros).
N_PAR = _core.NPAR
#: The model's sizes and arrays, in the order of the C layout (c/vsj_layout.h), which
#: declares each once with its type and what it holds.
SIZES: tuple[str, ...] = _core.LAYOUT["sizes"]
ARRAYS: tuple[str, ...] = tuple(name for name, _, _ in _core.LAYOUT["arrays"])
_KINDS = {name: np.dtype(kind) for name, kind, _ in _core.LAYOUT["arrays"]}
# indices into ``dims`` (the first eight sizes)
D_N, D_S, D_F, D_K, D_L, D_M, D_CH, D_R = range(8)


class EngineModel(namedtuple("EngineModel", ("sizes", "rows") + ARRAYS)):
    """A compiled model: its ``sizes`` (a dict, `SIZES`), the dense element ``rows``
    (``(R, n + s)``: free-coordinate then source part) and one field per array of the C
    layout (`ARRAYS`, see c/vsj_layout.h for what each holds)."""

    __slots__ = ()

    @property
    def dims(self) -> np.ndarray:
        """n, sources, frictions, springs, loads, motors, channels, rows (int64)."""
        return np.array([self.sizes[k] for k in SIZES[:8]], dtype=np.int64)

    def _asdict(self) -> dict:
        """Every field, the sizes as an int64 array (so that models compare as arrays)."""
        out = super()._asdict()
        out["sizes"] = np.array([self.sizes[k] for k in SIZES], dtype=np.int64)
        return out

    def _replace(self, **changes):
        if "sizes" in changes and not isinstance(changes["sizes"], dict):
            changes["sizes"] = dict(zip(SIZES, (int(v) for v in changes["sizes"])))
        return super()._replace(**changes)

    def arrays(self) -> dict[str, np.ndarray]:
        """The C layout's arrays, by name, as the engine takes them."""
        return {name: np.ascontiguousarray(getattr(self, name), dtype=_KINDS[name]).reshape(-1)
                for name in ARRAYS}


@dataclass(frozen=True)
class Layout:
    """Sizes, and where things live in the state and accumulator vectors."""

    n: int
    n_sources: int
    n_frictions: int
    n_springs: int
    n_loads: int
    n_motors: int

    @property
    def n_state(self) -> int:
        """Length of the engine's state: angles and speeds of the ``n`` free coordinates,
        and one armature current per motor."""
        return 2 * self.n + self.n_motors

    @property
    def n_acc(self) -> int:
        """Number of energy accumulators [J] the engine keeps (see `acc_slices`)."""
        return (self.n_sources + self.n_loads + 2 * self.n_motors + self.n_frictions
                + 3 * self.n_springs)

    def acc_slices(self) -> dict[str, slice]:
        """Accumulated energies [J]: work done by sources, loads and motor supplies,
        dissipation in friction and armature resistance, work done by the springs on
        the mechanism and by the pivot on the springs, and the energy the springs'
        end stops take out of the mechanism (time-stepper: impacts, and the implicit
        treatment of compliant stops)."""
        sizes = [("sources", self.n_sources), ("loads", self.n_loads),
                 ("electric", self.n_motors), ("friction", self.n_frictions),
                 ("resistance", self.n_motors), ("spring", self.n_springs),
                 ("pivot", self.n_springs), ("stops", self.n_springs)]
        out, start = {}, 0
        for name, size in sizes:
            out[name] = slice(start, start + size)
            start += size
        return out


def _ints(values) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(values, dtype=np.int64).reshape(-1))


def _csr(matrix: np.ndarray):
    """Compressed sparse rows of a dense matrix: (pointers, columns, values)."""
    ptr, cols, vals = [0], [], []
    for row in matrix:
        nz = np.flatnonzero(row)
        cols.extend(nz.tolist())
        vals.extend(row[nz].tolist())
        ptr.append(len(cols))
    return _ints(ptr), _ints(cols), np.ascontiguousarray(vals, dtype=float)


def friction_laws_for(structure: Structure, default: str,
                      overrides: Mapping[str, str] | None = None) -> list[str]:
    """Law of each friction element: its own, else an override pattern, else ``default``.

    Overrides map shell-style patterns on element names (``"pg*.bearing_*"``)
    to law names; the last matching pattern wins.
    """
    friction_laws.law_code(default)
    laws = []
    for element in structure.frictions:
        if element.contact is not None:  # a contact keeps its law whatever the run's
            laws.append(friction_laws.CONTACT)
            continue
        law = element.law or default
        for pattern, name in (overrides or {}).items():
            friction_laws.law_code(name)
            if fnmatch.fnmatchcase(element.name, pattern):
                law = name
        laws.append(law)
    for pattern in overrides or {}:
        if not any(fnmatch.fnmatchcase(e.name, pattern) for e in structure.frictions):
            names = ", ".join(e.name for e in structure.frictions)
            raise InputError(f"friction override {pattern!r} matches no element; elements: "
                             f"{names}")
    return laws


def input_bank(structure: Structure, inputs: Mapping[str, Input], t_end: float,
               extra: Mapping[str, Input] | None = None):
    """Splines of every input channel, concatenated: (knots, coef, cum, first, count,
    period); the channels of ``extra`` (a controller's references) follow the
    network's. A signal that repeats (`Input.repeats`) within ``t_end`` is splined up to
    the end of its first whole period only, and the engine repeats that period
    (``period``: its length and the channel's integral over it), so that its memory
    does not grow with the run."""
    channels = structure.channels()
    unknown = sorted(set(inputs) - set(channels))
    if unknown:
        raise InputError(f"unknown input channel(s) {', '.join(unknown)}; network "
                         f"{structure.name!r} has {', '.join(channels) or 'none'}")
    inputs = {**inputs, **(extra or {})}
    channels = channels + tuple(extra or ())
    source_channels = {s.channel for s in structure.sources}
    knots, coefs, cums, first, count = [np.zeros(0)], [np.zeros((0, 4))], [np.zeros(0)], [], []
    if channels:
        knots, coefs, cums = [], [], []
    offset = 0
    period = np.zeros((len(channels), 2))
    for i, ch in enumerate(channels):
        signal = inputs.get(ch, Constant(0.0))
        if signal.is_position and ch not in source_channels:
            raise InputError(f"input {ch!r}: only velocity sources can be driven by an angle")
        k, c, period[i, 0] = engine_pieces(signal, t_end)
        k = np.asarray(k, dtype=float)
        c = np.asarray(c, dtype=float).reshape(-1, 4)
        dt = np.diff(k)
        integral = (c[:, 0] * dt + c[:, 1] * dt ** 2 / 2 + c[:, 2] * dt ** 3 / 3
                    + c[:, 3] * dt ** 4 / 4)
        knots.append(k)
        coefs.append(c)
        cums.append(np.concatenate([[0.0], np.cumsum(integral)]))
        if period[i, 0] > 0.0:  # the integral over the last period (knots end it)
            start = int(np.searchsorted(k, k[-1] - period[i, 0] * (1 + 1e-12)))
            if abs(k[-1] - k[start] - period[i, 0]) > 1e-9 * period[i, 0]:
                raise ValueError(f"input {ch!r}: its repeating period does not start on a knot")
            period[i, 1] = cums[-1][-1] - cums[-1][start]
        first.append(offset)
        count.append(len(c))
        offset += len(c)
    return (np.concatenate(knots), np.ascontiguousarray(np.vstack(coefs)),
            np.concatenate(cums), _ints(first), _ints(count), period.reshape(-1))


def compile_model(structure: Structure, inputs: Mapping[str, Input], t_end: float, *,
                  friction: str = "arctan", friction_overrides: Mapping[str, str] | None = None,
                  slope_width: float = 0.01, source_angles: np.ndarray | None = None,
                  controller=None) -> tuple[EngineModel, Layout]:
    """Arrays for the engine. ``t_end`` bounds the input splines; ``source_angles``
    are the sources' angles at t = 0 (see `Structure.initial_positions`); ``controller``
    a `vsj.control.CompiledController` the model carries (its references are input
    channels after the network's)."""
    if not (math.isfinite(slope_width) and slope_width > 0.0):
        raise InputError(f"slope width must be > 0 rad/s, got {slope_width!r}")
    n, s = structure.n, len(structure.sources)
    A, B, I = structure.A, structure.B, structure.inertia
    AB = np.hstack([A, B])
    mass = AB.T @ (I[:, None] * AB)
    Minv = np.linalg.inv(mass[:n, :n]) if n else np.zeros((0, 0))
    chan = {c: i for i, c in enumerate(structure.channels())}
    laws = friction_laws_for(structure, friction, friction_overrides)

    rows, par, code = [], [], []

    def add(row, params, c):
        rows.append(row)
        padded = np.zeros(N_PAR)
        padded[:len(params)] = params
        par.append(padded)
        code.append(c)

    table: list[tuple[float, float]] = []
    for element, row, law in zip(structure.frictions, structure.friction_rows, laws):
        if element.contact is not None:  # vsj_contact_par: damping, stiffness, exponent, gap
            stiffness, exponent, damping, gap = element.contact
            add(row @ AB, [damping, stiffness, exponent, gap, 1.0, -1, 0, 0, 0.0],
                friction_laws.LAWS[friction_laws.CONTACT])
            continue
        mu = list(element.table or ())
        add(row @ AB, [element.viscous, element.k, element.sharpness, slope_width,
                       element.peak, -1 if element.normal is None else chan[element.normal],
                       len(table) if mu else 0, len(mu), float(element.damper)],
            friction_laws.law_code(law))
        table += mu
    for spring, row in zip(structure.springs, structure.spring_rows):
        add(row @ AB, spring.parameters, spring.law)
    for load in structure.loads:
        add(AB[structure.index(load.flange)], [], chan[load.channel])
    for motor in structure.motors:
        add(AB[structure.index(motor.flange)],
            [motor.resistance, motor.inductance, motor.torque_constant], chan[motor.channel])
    pivot = structure.pivot
    pivot_row = (AB[structure.index(pivot.flange)] if pivot.flange is not None
                 else np.zeros(n + s))
    add(pivot_row, [pivot.amplitude, pivot.fixed, 0.0 if pivot.flange is None else 1.0,
                    pivot.q_min, pivot.q_max],
        0)
    bank = input_bank(structure, inputs, t_end,
                      controller.references if controller is not None else None)
    dense = np.array(rows).reshape(len(rows), n + s)
    xp, xc, xv = _csr(dense[:, :n])
    up, uc, uv = _csr(dense[:, n:])
    src_pos0 = np.zeros(s) if source_angles is None else np.asarray(source_angles, dtype=float)
    sizes = dict(n=n, n_sources=s, n_frictions=len(structure.frictions),
                 n_springs=len(structure.springs), n_loads=len(structure.loads),
                 n_motors=len(structure.motors), n_channels=len(bank[3]), n_rows=len(rows),
                 n_pieces=len(bank[1]), n_table=len(table))
    sizes.update(controller.sizes if controller is not None else NO_CONTROLLER_SIZES)
    ctl_arrays = controller.arrays if controller is not None else NO_CONTROLLER_ARRAYS
    model = EngineModel(
        sizes=sizes, mass=np.ascontiguousarray(mass), Minv=np.ascontiguousarray(Minv),
        rows=np.ascontiguousarray(dense), xp=xp, xc=xc, xv=xv, up=up, uc=uc, uv=uv,
        par=np.ascontiguousarray(np.array(par)), code=_ints(code),
        src_ch=_ints([chan[src.channel] for src in structure.sources]),
        src_pos0=np.ascontiguousarray(src_pos0, dtype=float),
        knots=bank[0], coef=bank[1], cum=bank[2], first=bank[3], count=bank[4],
        period=bank[5], table=np.ascontiguousarray(np.array(table, dtype=float).reshape(-1, 2)),
        **ctl_arrays)
    layout = Layout(n=n, n_sources=s, n_frictions=len(structure.frictions),
                    n_springs=len(structure.springs), n_loads=len(structure.loads),
                    n_motors=len(structure.motors))
    return model, layout

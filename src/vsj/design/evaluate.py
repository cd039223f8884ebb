"""Evaluating designs: a design vector to its objectives and constraint margins.

A design is the base parameter set with the design parameters replaced. Its
quantities come from vsj's own models, through the same compiled code that
simulations run: the static ones from `vsj.datasheet.Statics` (the elastic
elements' laws about theta_x with both motors held, the datasheet's numbers), the
tracking lag and the impact force from `vsj.safety.tradeoff` (two closed-loop
simulations of report fig 4.15's motion, in free space and with the hand surrogate).
Pivot positions are the datasheet's grid: ``q_points`` from ``pivot.q_max`` down to
``pivot.q_min``.

`evaluate_chunk` is the sweep machinery's unit of work (`vsj.sweep.schedulers.Pool`):
a pure function of the `Problem` and the designs' values, returning a
`vsj.sweep.runner.ChunkResult` whose ``metrics`` are the columns of `Problem.columns`
(objectives in their natural sense, constraint margins, then auxiliary values). A
design whose values break `vsj.params.RELATIONS`, or whose evaluation fails (a
simulation that does not finish, a stiffness <= 0 somewhere over the pivot range: the
joint is unstable there), is
recorded with status `FAILED` and its message; the optimiser counts it infeasible.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import brentq

from ..datasheet import Statics
from ..datasheet.compute import output_kinematics
from ..errors import InputError, SimulationError
from ..params import RELATIONS as PARAMETER_RELATIONS, Parameters
from ..safety import tradeoff
from ..springs import evaluate as spring_law, extensions
from ..sweep.runner import ChunkResult
from .spec import RELATIONS, DesignSpec, Goal

#: Status of a design that was evaluated, and of one that could not be (`evaluate_chunk`).
OK, FAILED = 0, -1
#: Absolute tolerance [m] of the pivot position at which a design has the stiffness an
#: objective asks for (brentq's xtol): a picometre, far below any pivot's travel, so
#: the stiffness there is the target's to the solver's precision.
Q_TOLERANCE = 1e-12
#: Kinematics kept per process (`_kinematics_of`): one per distinct set of the values
#: they depend on.
MAX_KINEMATICS = 64
#: The objectives computed by simulating fig 4.15's motion (two runs per design).
SIMULATED = ("tracking_lag", "impact_force")


@dataclass(frozen=True)
class Column:
    """One recorded number per design: its name, what it is (``objective``, ``margin``
    or ``auxiliary``), SI unit, unit to show, and the scale that makes a margin
    comparable with the others in the optimiser's constraint violation."""

    name: str
    role: str
    unit: str
    display: str
    scale: float = 1.0


@dataclass(frozen=True)
class Problem:
    """A design file with its base parameter set: what `evaluate` needs (picklable)."""

    spec: DesignSpec
    base: Parameters

    def __post_init__(self):
        geometric = self.spec.elastic.startswith("geometric")
        for goal in self.spec.objectives + self.spec.constraints:
            if goal.name in ("spring_force", "no_slack", "slack_free_range") and not geometric:
                raise InputError(f"{goal.where}: needs springs: set design.elastic to "
                                 "geometric or geometric-report")

    @cached_property
    def columns(self) -> list[Column]:
        """The recorded columns: objectives, margins, auxiliary values."""
        out = [Column(g.name, "objective", g.kind.unit, g.kind.display)
               for g in self.spec.objectives]
        for g in self.spec.constraints:
            scale = {"spring_force": g.options.get("max"), "end_stop": g.options.get("torque"),
                     "no_slack": self.base["elastic_element.end_stop"]}[g.name]
            out.append(Column(g.name, "margin", g.kind.unit, g.kind.display, scale or 1.0))
        out.append(Column(RELATIONS, "margin", "m", "cm", self.base["pivot.amplitude"]))
        for target in self.targets:
            out.append(Column(f"stiffness_reach_{_key(target)}", "margin", "N*m", "N m/rad",
                              target))
            out.append(Column(f"q_at_{_key(target)}", "auxiliary", "m", "cm"))
        return out

    @cached_property
    def targets(self) -> list[float]:
        """The stiffnesses [N m/rad] at which the simulated objectives are wanted."""
        return sorted({g.options["stiffness"] for g in self.spec.objectives
                       if g.name in SIMULATED})

    def index(self, name: str) -> int:
        """The column of ``name``."""
        return [c.name for c in self.columns].index(name)

    def parameters(self, x) -> tuple[Parameters | None, float, str]:
        """The parameter set of the design ``x`` (SI values in the order of the design
        parameters), the smallest margin [m] of `vsj.params.RELATIONS` and, if a
        relation breaks (the set is then None), which."""
        values = dict(self.base.values)
        texts, sources = dict(self.base.texts), dict(self.base.sources)
        for v, value in zip(self.spec.variables, x):
            values[v.name] = float(value)
            texts[v.name] = f"{float(value)!r} {v.spec.unit}"
            sources[v.name] = f"design vector of {self.spec.origin}"
        margin = min(r.margin(values) for r in PARAMETER_RELATIONS)
        broken = [r.text for r in PARAMETER_RELATIONS if not r.holds(values)]
        if broken:
            return None, margin, "; ".join(broken)
        return (Parameters(values=values, sources=sources, texts=texts,
                           origin=f"{self.spec.origin} (a design)", meta=dict(self.base.meta)),
                margin, "")


def _key(stiffness: float) -> str:
    return f"{stiffness:.6g}".replace(".", "p").replace("-", "m").replace("+", "")


#: Each process's kinematics by the values they depend on (`_kinematics_of`).
_KINEMATICS: dict[tuple, tuple] = {}


def _kinematics_of(params: Parameters, elastic: str) -> tuple:
    """`vsj.datasheet.compute.output_kinematics` of ``params``: the wrist's static map
    and mass matrix, which depend on every section but the elastic element's (the
    springs do not enter the kinematics), so a design that changes only those reuses
    them."""
    key = (elastic, tuple(sorted((k, v) for k, v in params.values.items()
                                 if not k.startswith("elastic_element."))))
    if key not in _KINEMATICS:
        if len(_KINEMATICS) >= MAX_KINEMATICS:
            _KINEMATICS.clear()
        _KINEMATICS[key] = output_kinematics(params, elastic)
    return _KINEMATICS[key]


class _Clock:
    """Seconds spent in the engine (the spring laws and the simulations)."""

    def __init__(self):
        self.seconds = 0.0

    def __call__(self, work, *args):
        began = time.perf_counter()
        try:
            return work(*args)
        finally:
            self.seconds += time.perf_counter() - began


def evaluate(problem: Problem, x, clock: _Clock | None = None) -> tuple[np.ndarray, str]:
    """The row of `Problem.columns` of the design ``x`` and a message ("" if it was
    evaluated; else why not, the row then NaN but for what was computed)."""
    clock = clock or _Clock()
    spec = problem.spec
    row = np.full(len(problem.columns), np.nan)
    params, relations, broken = problem.parameters(x)
    row[problem.index(RELATIONS)] = relations
    if params is None:
        return row, f"breaks a relation between parameters: {broken}"
    statics = Statics(params, spec.elastic, kinematics=_kinematics_of(params, spec.elastic))
    qs = [float(q) for q in np.linspace(params.pivot.q_max, params.pivot.q_min,
                                        spec.q_points)]
    k = [clock(statics.output_stiffness, q) for q in qs]
    if min(k) <= 0.0:
        q = qs[int(np.argmin(k))]
        return row, (f"the stiffness is {min(k):.4g} N m/rad <= 0 at q = {100 * q:.4g} cm: the "
                     "joint is unstable there")
    quantities = _Quantities(problem, params, statics, qs, k, clock)
    try:
        for g in spec.objectives + spec.constraints:
            row[problem.index(g.name)] = quantities.value(g)
        for target in problem.targets:
            reach, q = quantities.reach(target)
            row[problem.index(f"stiffness_reach_{_key(target)}")] = reach
            row[problem.index(f"q_at_{_key(target)}")] = q
    except (InputError, SimulationError) as exc:
        return row, f"evaluation failed: {exc}"
    bad = [c.name for c, value in zip(problem.columns, row) if not math.isfinite(value)]
    if bad:
        return row, f"not finite: {', '.join(bad)}"
    return row, ""


class _Quantities:
    """The objectives and margins of one design, each computed once when first asked."""

    def __init__(self, problem: Problem, params: Parameters, statics: Statics,
                 qs: list[float], k: list[float], clock: _Clock):
        self.problem, self.params, self.statics = problem, params, statics
        self.qs, self.k, self.clock = qs, k, clock
        self._held: dict[float, dict] | None = None
        self._runs: dict[float, tradeoff.Tradeoff] = {}

    @property
    def held(self) -> dict[float, dict]:
        if self._held is None:
            self._held = {q: self.clock(self.statics.at, q) for q in self.qs}
        return self._held

    def value(self, goal: Goal) -> float:
        """The objective's value or the constraint's margin (SI)."""
        k, o = self.k, goal.options
        if goal.name == "stiffness_ratio":
            return max(k) / min(k)
        if goal.name == "min_stiffness":
            return min(k)
        if goal.name == "max_stiffness":
            return max(k)
        if goal.name == "max_deflection":
            return min(row["max_deflection"] for row in self.held.values())
        if goal.name == "max_energy":
            return max(row["max_energy"] for row in self.held.values())
        if goal.name == "end_stop":
            return min(row["peak_torque"] for row in self.held.values()) - o["torque"]
        if goal.name == "slack_free_range":
            return self._slack_free(o["deflection"])
        if goal.name == "no_slack":
            return min(self._slack_deflection(q) for q in self.qs) - o["deflection"]
        if goal.name == "spring_force":
            return o["max"] - self._largest_force()
        if goal.name == "holding_torque":
            return self._holding_torque()
        run = self._run(o["stiffness"])
        return run.lag[0] if goal.name == "tracking_lag" else run.peak_force[0]

    def _slack_deflection(self, q: float) -> float:
        """Output deflection [rad] at which a spring first goes slack at ``q``, at most
        the end stop's (`Statics.pretension_loss_deflection`)."""
        loss = self.clock(self.statics.pretension_loss_deflection, q)
        return min(loss, float(self.statics.deflections[-1]))

    def _slack_free(self, deflection: float) -> float:
        """Length [m] of the pivot range where no spring goes slack up to ``deflection``
        [rad]: where the margin, linear between grid points, is > 0."""
        qs = self.qs[::-1]  # ascending
        margin = [self._slack_deflection(q) - deflection for q in qs]
        length = 0.0
        for (qa, ma), (qb, mb) in zip(zip(qs, margin), zip(qs[1:], margin[1:])):
            if ma > 0.0 and mb > 0.0:
                length += qb - qa
            elif ma > 0.0 or mb > 0.0:
                length += (qb - qa) * max(ma, mb) / abs(ma - mb)
        return length

    def _largest_force(self) -> float:
        """Largest spring force [N] over the pivot grid and the output deflections up
        to the end stop, both elastic elements (a spring only pulls: k times its
        extension where taut)."""
        element = self.statics.element
        row = np.asarray(element.parameters, dtype=float)
        k_spring = self.params["elastic_element.spring_stiffness"]
        largest = 0.0
        began = time.perf_counter()
        for q in self.qs:
            for c in self.statics.ring_per_output:
                for theta in self.statics.deflections:
                    largest = max(largest, *extensions(c * theta, q, row))
        self.clock.seconds += time.perf_counter() - began
        return k_spring * largest

    def _holding_torque(self) -> float:
        """Largest rotor torque [N m] of the stiffness motor that holds the pivot: the
        springs push the pivot with -dV/dq (both elements share it), which the carrier
        feels through dq/dphi_C = sqrt(amplitude^2 - q^2) and the motor through the
        pivot's and the gearhead's ratios."""
        element = self.statics.element
        theta = self.statics.deflections
        pv = self.params.pivot
        largest = 0.0
        for q in self.qs:
            dvdq = sum(self.clock(spring_law, element.law, element.parameters, c * theta, q)[3]
                       for c in self.statics.ring_per_output)
            arm = math.sqrt(max(pv.amplitude ** 2 - q ** 2, 0.0))
            largest = max(largest, float(np.max(np.abs(dvdq))) * arm)
        return largest / abs(pv.ratio * self.params["motor.gear_ratio"])

    def reach(self, target: float) -> tuple[float, float]:
        """How far inside the stiffness range ``target`` [N m/rad] lies (margin, N m/rad)
        and the pivot position [m] with that stiffness (or, outside the range, the grid
        position nearest to it)."""
        k, qs = self.k, self.qs
        margin = min(target - min(k), max(k) - target)
        if margin < 0.0:
            return margin, qs[int(np.argmin(np.abs(np.asarray(k) - target)))]
        for j in range(len(qs) - 1):
            a, b = k[j] - target, k[j + 1] - target
            if a == 0.0:
                return margin, qs[j]
            if a * b < 0.0:
                q = brentq(lambda q: self.clock(self.statics.output_stiffness, q) - target,
                           qs[j], qs[j + 1], xtol=Q_TOLERANCE)
                return margin, float(q)
        return margin, qs[-1]

    def _run(self, target: float) -> tradeoff.Tradeoff:
        if target not in self._runs:
            _, q = self.reach(target)
            setup = tradeoff.Setup(elastic=self.problem.spec.elastic)
            self._runs[target] = self.clock(tradeoff.run, self.params, [q], setup)
        return self._runs[target]


def evaluate_chunk(problem: Problem, start: int, values: np.ndarray,
                   threads: int | None = None) -> ChunkResult:
    """The designs ``start ..`` with design vectors ``values`` (designs x parameters,
    SI): `evaluate` of each as a `ChunkResult` (``threads`` is the sweep's argument,
    unused: a design runs on one core). ``kernel_time`` is the time in the engine."""
    clock = _Clock()
    rows = np.full((len(values), len(problem.columns)), np.nan)
    status = np.full(len(values), OK, dtype=np.int64)
    messages = [""] * len(values)
    for r, x in enumerate(values):
        rows[r], messages[r] = evaluate(problem, x, clock)
        if messages[r]:
            status[r] = FAILED
    return ChunkResult(start, np.empty((len(values), 0, 0)), rows, status, messages,
                       np.zeros(len(values), dtype=np.int64), clock.seconds)


def margins_violation(problem: Problem, rows: np.ndarray, status: np.ndarray) -> np.ndarray:
    """The optimiser's constraints (<= 0 where met): each margin over its scale, negated,
    and a last column 1 for a design that failed (0 otherwise)."""
    cols = [j for j, c in enumerate(problem.columns) if c.role == "margin"]
    scales = np.array([problem.columns[j].scale for j in cols])
    G = -rows[:, cols] / scales
    # a margin not computed (the design failed first) counts through the last column
    G = np.where(np.isnan(G), 0.0, G)
    failed = (status != OK).astype(float)
    return np.column_stack([G, failed])


def objective_matrix(problem: Problem, rows: np.ndarray) -> np.ndarray:
    """The objectives as the optimiser minimises them (larger-is-better ones negated)."""
    signs = np.array([g.sign for g in problem.spec.objectives])
    return rows[:, :len(signs)] * signs


def prototype(problem: Problem) -> tuple[np.ndarray, np.ndarray, str]:
    """The base design's vector, row and message (the report's prototype with the bundled
    set)."""
    x = np.array([problem.base[v.name] for v in problem.spec.variables])
    row, message = evaluate(problem, x)
    return x, row, message


__all__ = ["Column", "FAILED", "OK", "Problem", "evaluate", "evaluate_chunk",
           "margins_violation", "objective_matrix", "prototype"]

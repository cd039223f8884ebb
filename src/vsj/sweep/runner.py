"""Running one chunk of a sweep: models, the batch kernel, signals, metrics.

`run_chunk` is a pure function of a `Job` (the sweep, with the text of its
scenario and its parameter set resolved, every file it ``extends`` merged, so a
worker on another machine needs no files) and
the chunk's values of the varied quantities. Each run is built exactly as
``vsj simulate`` builds it (the parameter set with the run's values, the
network, the compiled model, the initial state), integrated by the batch kernel
(`vsj.engine.plan.run_batch`, one run per thread, results independent of the
thread count) and sampled at the kept samples only. So a run's numbers depend
on nothing but its own values: not on the chunk, the worker or the scheduler.

A run that cannot be built (values that break the parameter set's relations, a
pivot position outside its range) or whose integration fails is recorded with
its status and message; the others go on.
"""

from __future__ import annotations

import hashlib
import math
import pickle
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from ..engine import STATUS_TEXT, Engine, compile_model, core, observation_layout
from ..engine.plan import Plan, Scheme, initial_state, run_batch
from ..control import compile_controller
from ..engine.retune import RETUNABLE, Slots, find_passthrough, retune
from .. import params as params_module
from .. import scenario as scenarios
from ..errors import InputError, read_text
from ..params import RELATIONS, Parameters, _relations
from ..simulate import InitialState, choose_solver
from ..simulate.signals import Block, catalogue
from ..wrist import elastic_models, unread_keys
from .metrics import Context, Evaluator, Expression, sampled
from .sampling import to_values
from .spec import Q, SweepSpec, spec_of

#: Status of a run that could not be built (the engine's codes are 0 and up).
SETUP_FAILED = -1
#: Compiled models a process keeps for runs that retune them (one per distinct set
#: of values of the parameters that are not pass-through).
MAX_SHARED = 64
#: Bytes of the observation a chunk's signals are evaluated on at once: its runs are
#: taken in groups that fit (a chunk of many runs with many samples would otherwise
#: hold all their observations at the same time).
BLOCK_BYTES = 1 << 24


@dataclass(frozen=True)
class Job:
    """What every chunk of a sweep needs, as plain data (picklable, hashable)."""

    spec: SweepSpec
    scenario_text: str
    scenario_origin: str
    #: the parameter set as resolved where the sweep starts (``extends`` followed there)
    params: Parameters
    #: the varied parameters that reach the compiled arrays unchanged, and where
    #: (`Prepared.passthrough`), found once where the sweep starts (`probed`) so that
    #: workers do not each compile the probes again; None: each process finds them
    passthrough: Mapping[str, Slots] | None = field(default=None, compare=False, repr=False)

    @cached_property
    def key(self) -> str:
        """A digest of everything the runs depend on (sweep text and method, scenario,
        parameter set), which names the job's prepared state in a worker."""
        return hashlib.sha256(pickle.dumps((self.spec.text, self.spec.method,
                                            self.scenario_text, self.scenario_origin,
                                            self.params.hash(),
                                            self.params.origin))).hexdigest()


@dataclass
class ChunkResult:
    """The runs ``start`` to ``start + len(status) - 1`` of a sweep."""

    start: int
    kept: np.ndarray        # (runs, samples, kept signals)
    metrics: np.ndarray     # (runs, metrics)
    status: np.ndarray      # (runs,) int64: 0 ok, an engine status, or SETUP_FAILED
    messages: list[str]
    steps: np.ndarray       # (runs,) int64
    kernel_time: float = 0.0

    @property
    def failed(self) -> int:
        """Number of the chunk's runs that did not succeed."""
        return int(np.count_nonzero(self.status != core.OK))

    @classmethod
    def joined(cls, parts: Sequence[ChunkResult]) -> ChunkResult:
        """The result of the runs of ``parts`` (results of consecutive runs, in any
        order) as one: their arrays concatenated, their kernel times summed."""
        parts = sorted(parts, key=lambda part: part.start)
        for before, after in zip(parts, parts[1:]):
            end = before.start + len(before.status)
            if after.start != end:
                raise ValueError(f"ChunkResult.joined: the part from run {after.start} does "
                                 f"not follow the runs {before.start} to {end - 1}")
        if len(parts) == 1:
            return parts[0]
        return cls(parts[0].start, np.concatenate([p.kept for p in parts]),
                   np.concatenate([p.metrics for p in parts]),
                   np.concatenate([p.status for p in parts]),
                   [m for p in parts for m in p.messages],
                   np.concatenate([p.steps for p in parts]),
                   sum(p.kernel_time for p in parts))


class _Memo:
    """An input signal whose spline pieces are made once (they do not depend on the
    parameters, and making them is most of the cost of compiling a model), and whose
    initial angle (a position source's, taken by every run's initial state) too."""

    def __init__(self, signal):
        self._signal = signal
        self._pieces = {}
        self._initial = None

    def __getattr__(self, name):
        return getattr(self._signal, name)

    def pieces(self, t_end: float):
        if t_end not in self._pieces:
            self._pieces[t_end] = self._signal.pieces(t_end)
        return self._pieces[t_end]

    def initial_angle(self) -> float:
        if self._initial is None:
            self._initial = self._signal.initial_angle()
        return self._initial


class Prepared:
    """A `Job` made ready in one process: scenario, base model, signals, metrics."""

    def __init__(self, job: Job):
        spec = job.spec
        self.spec = spec
        scen = scenarios.loads(job.scenario_text, job.scenario_origin)
        params = job.params
        case = pick_case(scen, spec)
        self.case = case
        prepared = scenarios.prepare_case(scen, case, params)
        resolved, structure, inputs = prepared.params, prepared.structure, prepared.inputs
        unread = set(unread_keys(prepared.network))
        #: what the sweep varies in vain: parameters its scenario's model does not read
        self.warnings = [f'{spec.origin}: vary."{name}": {elastic_models(prepared.network)} '
                         f"of scenario {scen.name} does not read {name}: the runs differ in "
                         "it only where a value is refused; a scenario's [model] elastic "
                         "chooses the model" for name in spec.varied if name in unread]
        self.base_params = resolved
        self.structure = structure
        #: the case's controller (its arrays compiled with each run's network)
        self.controller = prepared.controller
        self.compiled_controller = prepared.plan.controller
        self.inputs = {k: _Memo(v) for k, v in inputs.items()}
        self.options = case.options
        self.duration = case.duration
        self.solver = choose_solver(structure, case.options)
        self.varied = spec.varied
        self.parameter_keys = [n for n in self.varied if n != Q]
        #: the relations a run's values can break (the base set meets all of them)
        self.relations = [r for r in RELATIONS if any(k in self.parameter_keys
                                                      for k, _ in r.terms)]
        base, layout = self._compile(structure)
        self.layout = layout
        self.base_model = base
        self.scheme = Scheme.of(self.solver, case.options)
        self._shared: dict[bytes, _Compiled | None] = {}
        if job.passthrough is not None:
            self.passthrough = dict(job.passthrough)
        self.u0 = Engine(base).source_speeds(0.0)
        step = case.options.output_step
        n_out = math.floor(self.duration / step + 1e-9) + 1
        every = spec.every if spec.every is not None else step
        ratio = every / step
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise InputError(f"{spec.origin}: output.every = {every:g} s must be a whole "
                             f"multiple of the scenario's output_step ({step:g} s)")
        if every > self.duration * (1 + 1e-9):
            raise InputError(f"{spec.origin}: output.every = {every:g} s is longer than the "
                             f"run ({self.duration:g} s): its metrics would see the first "
                             "sample only")
        self.stride = round(ratio)
        self.t_out = np.arange(0, n_out, self.stride) * step
        self.t_out.flags.writeable = False  # shared by every run and metric
        # the signals of `vsj simulate` (ports aside), less those a batch run of the
        # time-stepper cannot give (the stiction impulses are sampled by single runs only)
        table = catalogue(structure, ports=False, controller=self.compiled_controller)
        single_only = {spec.name for spec in table
                       if self.solver == "timestep" and spec.needs_impulses}
        self.recipes = {spec.name: spec for spec in table if spec.name not in single_only}
        units = {k: spec.unit for k, spec in self.recipes.items()}
        parameters = set(params.values)
        self.derived: dict[str, Expression] = {}
        for name, text in spec.signals.items():
            if name in self.recipes:
                raise InputError(f"{spec.origin}: signals.{name}: a signal of that name exists")
            self.derived[name] = Expression(text, set(self.recipes) | set(self.derived),
                                            parameters, f"{spec.origin}: signals.{name}")
        names = set(self.recipes) | set(self.derived)
        powers = [k for k in self.recipes if k.startswith("friction.") and k.endswith(".power")]
        self.metrics = [Evaluator(m, names, parameters, units, powers) for m in spec.metrics]
        for metric in spec.metrics:
            check_window(metric, self.t_out, spec.table.get("metrics", {}).get(metric.name))
        for i, name in enumerate(spec.keep):
            if name not in names:
                why = (" (the time-stepper's batch runs do not sample the stiction impulses; "
                       "keep it with vsj simulate)" if name in single_only else "")
                raise InputError(f"{spec.origin}: output.keep[{i}] = {name!r}: not a signal of "
                                 f"this scenario or of [signals]{why}")
        self.keep = list(spec.keep)
        self.units = {**units, **{k: "" for k in self.derived}}
        needed, todo = set(), [*self.keep, *(n for m in self.metrics for n in m.signals)]
        while todo:
            name = todo.pop()
            if name not in needed:
                needed.add(name)
                if name in self.derived:
                    todo += self.derived[name].signals
        #: whether every signal the runs need is the state or a source (no observe)
        self.light = all(self.recipes[n].light for n in needed if n in self.recipes)
        self.columns = observation_layout(layout)

    def origin(self, structure, model, *, keep: bool = True) -> Plan:
        """The plan of ``model`` (a compiled network of this sweep) that its runs start
        from (`Plan.started`), kept per model with ``keep``, so that their checked
        models share its arrays."""
        origins = self.__dict__.setdefault("_origins", {})
        found = origins.get(id(model))
        if found is not None and found[0] is model:
            return found[1]
        plan = Plan(structure, model, self.layout, self.scheme, self.duration,
                    np.zeros(self.layout.n_state + self.layout.n_acc), self.inputs,
                    self.options, controller=self.compiled_controller)
        if keep:
            if len(origins) > MAX_SHARED:  # as many as the shared models kept, and the base
                origins.clear()
            origins[id(model)] = (model, plan)
        return plan

    def _compile(self, structure):
        o = self.options
        # a controller's arrays follow the network (its sensors' rows, its motors' limits)
        controller = (compile_controller(self.controller, structure, structure.channels())
                      if self.controller is not None else None)
        return compile_model(structure, self.inputs, self.duration, friction=o.friction,
                             friction_overrides=o.friction_overrides,
                             slope_width=o.slope_width, controller=controller)

    @cached_property
    def passthrough(self) -> dict[str, Slots]:
        """The varied parameters that reach the compiled arrays unchanged, and where
        (`vsj.engine.retune`); their runs retune a shared model instead of compiling."""
        base = {k: self.base_params.values[k] for k in self.parameter_keys}
        probes = {k: self._probe_values(k) for k in self.parameter_keys}
        joint = [{k: v[i % len(v)] if v else base[k] for k, v in probes.items()}
                 for i in range(3)]
        return find_passthrough(self._probe_arrays, base, probes, joint)

    def _probe_values(self, name: str) -> list[float]:
        """Values of ``name`` to compile the model at: near the base value, and in the
        range the sweep file gives it; all within the parameter's allowed range."""
        spec = self.spec
        base = self.base_params.values[name]
        out = [base * (1.0 + d) for d in (0.0123, -0.0234, 0.0345)] if base != 0.0 else []
        out += [v for f in spec.fixed if f.name == name for v in f.values]
        out += [float(v) for d in spec.sampled if d.name == name
                for v in to_values(np.array([[0.2], [0.5], [0.8]]), (d,))[:, 0]]
        cov = spec.covariance
        if cov is not None and name in cov.names:
            j = cov.names.index(name)
            sd, (lo, hi) = math.sqrt(cov.matrix[j][j]), cov.bounds[j]
            out += [min(max(cov.mean[j] + k * sd, lo), hi) for k in (-0.5, 0.0, 0.5)]
        return [v for v in out if math.isfinite(v) and not spec_of(name).check(v)]

    def _probe_arrays(self, values: Mapping[str, float]) -> dict | None:
        """The compiled arrays and initial state with ``values`` of the parameters
        (the initial state the scenario's), or None if they cannot be built."""
        vector = np.array([values.get(n, math.nan) for n in self.varied])
        try:
            params = self.parameters_for(vector)
            shared = _compiled(self, params)
            x0, v0, sigma0, currents = initial_state(shared.structure, self.inputs,
                                                     self.case.initial, self.u0)
        except (InputError, ArithmeticError, ValueError, np.linalg.LinAlgError):
            return None
        return {**shared.model._asdict(), "x0": np.asarray(x0, dtype=float),
                "v0": np.asarray(v0, dtype=float), "sigma0": np.asarray(sigma0, dtype=float),
                "currents": np.asarray(currents, dtype=float)}

    def compiled_for(self, values: np.ndarray) -> _Compiled | None:
        """The compiled model a run with ``values`` retunes: compiled with its values
        of the parameters that are not pass-through and the base values of those that
        are, once for all runs alike; None where that cannot be built (the run is then
        compiled on its own)."""
        passthrough = self.passthrough
        key = np.array([v for n, v in zip(self.varied, values)
                        if n != Q and n not in passthrough]).tobytes()
        if key not in self._shared:
            vector = np.array([self.base_params.values[n] if n in passthrough else v
                               for n, v in zip(self.varied, values)])
            try:
                self._shared[key] = _compiled(self, self.parameters_for(vector))
            except InputError:
                self._shared[key] = None
            if len(self._shared) > MAX_SHARED:
                self._shared.pop(next(iter(self._shared)))
        return self._shared[key]

    def parameters_for(self, values: np.ndarray) -> Parameters:
        """The base set with the run's parameter values (SI), checked as a file would be."""
        if not self.parameter_keys:
            return self.base_params
        base = self.base_params
        new = dict(base.values)
        problems = []
        for name, value in zip(self.varied, values):
            if name == Q:
                continue
            why = spec_of(name).check(float(value))
            if why:
                problems.append(f"{name} = {value!r}: {why}")
            new[name] = float(value)
        problems += _relations(new, "the run's parameters", among=self.relations)
        if problems:
            raise InputError("; ".join(problems))
        sources = {**base.sources, **{k: "sweep" for k in self.parameter_keys}}
        texts = {**base.texts, **{k: repr(new[k]) for k in self.parameter_keys}}
        return replace(base, values=new, sources=sources, texts=texts)

    def initial_for(self, values: np.ndarray, params: Parameters) -> InitialState:
        """The initial state of a run: the case's, at the varied pivot position if q is
        varied (`InputError` outside the pivot's range for ``params``)."""
        initial = self.case.initial
        if Q in self.varied:
            q = float(values[self.varied.index(Q)])
            lo, hi = params.pivot.q_min, params.pivot.q_max
            if not lo <= q <= hi:
                raise InputError(f"q = {q * 100:g} cm is outside the pivot range "
                                 f"[{lo * 100:g}, {hi * 100:g}] cm")
            initial = replace(initial, q=q)
        return initial


def check_window(metric, time: np.ndarray, entry) -> None:
    """`InputError` unless ``metric``'s window holds enough of the samples ``time`` (s):
    one for a reduction, two for a lag (its sine and cosine fit), and a lag's frequency
    below the samples' Nyquist frequency (above it the fit sees an alias)."""
    options = metric.options
    if "start" not in options and "stop" not in options and "frequency" not in options:
        return
    entry = entry if isinstance(entry, Mapping) else {}
    start, stop = options.get("start", 0.0), options.get("stop", math.inf)
    # the same slack as the evaluator's window (`vsj.sweep.metrics.Evaluator`)
    inside = np.count_nonzero((time >= start - 1e-12) & (time <= stop + 1e-12))
    needed = 2 if metric.kind == "lag" else 1
    if inside < needed:
        spacing = time[1] - time[0] if len(time) > 1 else 0.0
        shown = ", ".join(f"{k} = {entry.get(k, options[k])!r}" for k in ("start", "stop")
                          if k in options)
        raise InputError(f"{metric.where}: the window {shown} holds {inside} of the run's "
                         f"samples ({time[0]:g} s to {time[-1]:g} s every {spacing:g} s); "
                         f"a {metric.kind} metric needs at least {needed}")
    if "frequency" in options and len(time) > 1:
        nyquist = 0.5 / (time[1] - time[0])
        if not options["frequency"] < nyquist:
            raise InputError(f"{metric.where}.frequency = {entry.get('frequency')!r}: at or "
                             f"above the Nyquist frequency {nyquist:g} Hz of the samples "
                             f"every {time[1] - time[0]:g} s (output.every)")


def pick_case(scen, spec: SweepSpec):
    """The sweep's case of the scenario (the first unless named), with its duration."""
    if spec.case is None:
        case = scen.cases[0]
    else:
        labels = [c.label for c in scen.cases]
        if spec.case not in labels:
            raise InputError(f"{spec.origin}: sweep.case = {spec.case!r}: scenario "
                             f"{scen.name!r} has the cases {', '.join(labels)}")
        case = scen.cases[labels.index(spec.case)]
    if spec.duration is not None:
        case = replace(case, duration=spec.duration)
    return case


_PREPARED: dict[str, Prepared] = {}


def probed(job: Job) -> Job:
    """``job`` carrying its pass-through parameters (`Prepared.passthrough`), found here
    once for every worker (they depend on the job only, as the draws do)."""
    return job if job.passthrough is not None else replace(
        job, passthrough=prepared(job).passthrough)


def prepared(job: Job) -> Prepared:
    """The `Prepared` of ``job`` in this process (made once; it holds no run's state)."""
    if job.key not in _PREPARED:
        if len(_PREPARED) > 4:
            _PREPARED.pop(next(iter(_PREPARED)))
        _PREPARED[job.key] = Prepared(job)
    return _PREPARED[job.key]


@dataclass
class _Run:
    params: Parameters
    plan: Plan


@dataclass
class _Compiled:
    """A network built and compiled once, shared by the runs that retune it."""

    structure: object
    model: object


def _compiled(p: Prepared, params: Parameters) -> _Compiled:
    """The network of ``params`` built, assembled and compiled as `vsj simulate` does."""
    structure = p.case.build(params).assemble()
    model, layout = p._compile(structure)
    if layout != p.layout:
        raise InputError("these values change the network's structure")
    return _Compiled(structure, model)


def _build(p: Prepared, values: np.ndarray) -> _Run:
    params = p.parameters_for(values)
    initial = p.initial_for(values, params)
    arrays: dict = {}
    if params is p.base_params:
        origin = p.origin(p.structure, p.base_model)
    else:
        shared = p.compiled_for(values)
        if shared is None:  # compiled for this run alone: its plan is not kept
            shared = _compiled(p, params)
            origin = p.origin(shared.structure, shared.model, keep=False)
        else:
            origin = p.origin(shared.structure, shared.model)
            if p.passthrough:
                named = dict(zip(p.varied, values.tolist()))
                tuned = retune(shared.model._asdict(), p.passthrough, named)
                arrays = {k: tuned[k] for k in RETUNABLE}
    # the run's checked model shares the origin's arrays but those it retunes
    return _Run(params, origin.started(initial, p.u0, **arrays))


def run_chunk(job: Job, start: int, values: np.ndarray, threads: int | None = None
              ) -> ChunkResult:
    """Simulate the runs from ``start`` on with the varied quantities ``values`` (runs x
    varied, SI); ``threads`` share the kernel's runs (default: every core)."""
    p = prepared(job)
    runs = len(values)
    n_t, n_keep, n_metrics = len(p.t_out), len(p.keep), len(p.metrics)
    kept = np.full((runs, n_t, n_keep), np.nan)
    metrics = np.full((runs, n_metrics), np.nan)
    status = np.full(runs, SETUP_FAILED, dtype=np.int64)
    steps = np.zeros(runs, dtype=np.int64)
    messages = [""] * runs
    built: dict[int, _Run] = {}
    for r in range(runs):
        try:
            built[r] = _build(p, values[r])
        except InputError as exc:
            messages[r] = f"not built: {exc}"
    members = sorted(built)
    began = time.perf_counter()
    batch = run_batch([built[r].plan for r in members], p.t_out, threads=threads) \
        if members else None
    kernel = time.perf_counter() - began
    for i, r in enumerate(members):
        st = int(batch.status[i])
        status[r], steps[r] = st, batch.steps[i]
        messages[r] = (STATUS_TEXT[st] if st == core.OK else
                       f"{STATUS_TEXT[st]} at t = {batch.stop_time[i]:.6g} s")
    if members:
        _measure(p, built, members, batch, kept, metrics)
    return ChunkResult(start, kept, metrics, status, messages, steps, kernel)


def _measure(p: Prepared, built: Mapping[int, _Run], members: list[int], batch,
             kept: np.ndarray, metrics: np.ndarray) -> None:
    """Fill the rows ``members`` of ``kept`` (runs x samples x kept signals) and
    ``metrics`` (runs x metrics) for the runs ``built[r]`` of those rows, whose sampled
    states are the rows of ``batch`` in that order.

    Every signal and metric is evaluated for a group of runs at once (as many as fit
    `BLOCK_BYTES`). The table's signals take the runs' samples stacked one run after
    another: each is a function of one sample, whose sums take their terms in the same
    order however many samples there are (`vsj.simulate.signals.rows`). The [signals]
    expressions and the metrics take them as runs x samples and reduce along each run's
    own row (`vsj.sweep.metrics`). So a run's numbers are those it would have on its
    own, in a chunk of any size."""
    n_t = len(p.t_out)
    if not (p.keep or p.metrics):
        return
    width = p.columns["u"].stop if p.light else max(c.stop for c in p.columns.values())
    group = max(1, BLOCK_BYTES // (8 * max(1, n_t * width)))
    for a in range(0, len(members), group):
        rows = members[a:a + group]
        part = (np.empty((len(rows), n_t, len(p.keep))), np.empty((len(rows), len(p.metrics))))
        _measure_group(p, [built[r] for r in rows], batch.states[a:a + group],
                       batch.transitions[a:a + group], *part)
        kept[rows], metrics[rows] = part


def _measure_group(p: Prepared, runs: list[_Run], states: np.ndarray,
                   transitions: np.ndarray, kept: np.ndarray, metrics: np.ndarray) -> None:
    """`_measure` for one group of runs: their kept signals and metrics into ``kept``
    and ``metrics`` (the group's rows)."""
    n_t, n_state, n_runs = len(p.t_out), p.layout.n_state, len(runs)
    raw = parts = None
    if p.light:
        parts = _light_columns(p, runs, states)
    else:
        no_impulses = np.zeros((n_t, p.layout.n_frictions))
        raw = np.stack([run.plan.engine().observe(p.t_out, states[i], no_impulses)
                        for i, run in enumerate(runs)]).reshape(n_runs * n_t, -1)
    # batch runs sample no stick states: friction.*.stuck is 0 (dopri) or not offered
    block = Block(raw=raw, stuck=np.zeros((n_runs * n_t, p.layout.n_frictions), dtype=bool),
                  columns=p.columns, cache={}, parts=parts,
                  control=(states[:, :, n_state:].reshape(n_runs * n_t, -1)
                           if p.compiled_controller is not None else None))
    shape = (n_runs, n_t)
    computed: dict[str, np.ndarray] = {}

    def signal(name: str) -> np.ndarray:
        """A signal of every run of the group (runs x samples)."""
        if name not in computed:
            if name in p.recipes:
                value = np.ascontiguousarray(
                    sampled(p.recipes[name].values(block), (n_runs * n_t,))).reshape(shape)
            else:
                value = sampled(p.derived[name](context), shape)
            computed[name] = value
        return computed[name]

    context = Context(p.t_out, signal, _Columns(runs), np.asarray(transitions, dtype=np.int64))
    for j, name in enumerate(p.keep):
        kept[:, :, j] = signal(name)
    with np.errstate(all="ignore"):  # a failed run's samples are NaN after the failure
        for j, metric in enumerate(p.metrics):
            try:
                metrics[:, j] = metric(context)
            except (FloatingPointError, ValueError, np.linalg.LinAlgError):
                metrics[:, j] = math.nan


#: The compiled arrays the sources' speeds, and their angles but for where they start
#: (``src_pos0``), are computed from (c/internal.h, vsj__eval_inputs).
SOURCE_ARRAYS = ("src_ch", "knots", "coef", "cum", "first", "count", "period")


def _light_columns(p: Prepared, runs: list[_Run], states: np.ndarray) -> dict:
    """The columns a light signal reads (`vsj.simulate.signals.LIGHT_COLUMNS`) of the
    runs' samples, stacked run after run: the numbers `Engine.observe` writes there (a
    zero's sign aside). The state's are views of ``states``. The sources' are evaluated
    once for the runs whose plans share their input arrays, as runs retuned from one
    model do: their speeds, and their angles from 0, to which each run's starting
    angles are added as the engine adds them."""
    n_runs, n_t = states.shape[:2]
    stacked = states.reshape(n_runs * n_t, -1)
    parts = {name: stacked[:, p.columns[name]] for name in ("x", "v", "current")}
    n_sources = p.columns["u"].stop - p.columns["u"].start
    sigma, u = np.empty((2, n_runs, n_t, n_sources))
    alike: dict[tuple, list[int]] = {}
    for i, run in enumerate(runs):
        # identities are safe keys: the runs hold their arrays for the whole call
        alike.setdefault(tuple(id(getattr(run.plan.model, k)) for k in SOURCE_ARRAYS),
                         []).append(i)
    for members in alike.values():
        model = runs[members[0]].plan.model
        turned, u[members] = Engine(model._replace(src_pos0=np.zeros(n_sources))
                                    ).source_signals(p.t_out)
        starts = np.array([runs[i].plan.model.src_pos0 for i in members])
        sigma[members] = turned + starts[:, None, :]
    parts["sigma"] = sigma.reshape(n_runs * n_t, n_sources)
    parts["u"] = u.reshape(n_runs * n_t, n_sources)
    return parts


class _Columns(dict):
    """The runs' values of each parameter the expressions read, as columns (runs x 1),
    made on first use."""

    def __init__(self, runs: list[_Run]):
        super().__init__()
        self.runs = runs

    def __missing__(self, name: str) -> np.ndarray:
        column = self[name] = np.array([[run.params.values[name]] for run in self.runs])
        return column


def job_for(spec: SweepSpec) -> Job:
    """The `Job` of a sweep file: its scenario's text read and its parameter set loaded
    here (the files it ``extends`` read relative to it), so workers read no files."""
    try:
        scen = scenarios.load(spec.scenario)
    except InputError as exc:
        raise InputError(f"{spec.origin}: sweep.scenario = {spec.scenario!r}: {exc}") from None
    text = scen_text(scen, spec.scenario)
    return Job(spec, text, scen.origin, params_module.load(spec.params))


def scen_text(scen, name: str) -> str:
    """The text of the scenario ``scen`` named ``name`` (a file, or a built-in one)."""
    path = Path(name)
    if path.suffix == ".toml" or path.exists():
        return read_text(path, "scenario file")
    return read_text(scenarios._builtin_dir() / f"{name}.toml", "scenario file")


def describe(job: Job) -> Mapping:
    """Names and units of the kept signals and metrics, and the sample times."""
    p = prepared(job)
    return {"time": p.t_out, "keep": p.keep, "keep_units": [p.units[k] for k in p.keep],
            "metrics": [m.name for m in p.metrics], "metric_units": [m.unit for m in p.metrics],
            "base_params": p.base_params, "solver": p.solver, "warnings": p.warnings}

"""Scenarios: what to simulate, written as TOML (built-in ones ship with vsj).

A scenario names a network (the wrist or a bench), its inputs over time, the
duration, the initial state, the friction law and solver settings, parameter
overrides, and optionally several ``[[cases]]`` that each override part of it
(a sweep over the pivot position, say). Every number carries its unit. Example::

    name = "my-run"
    description = "Circular motion at the stiffest setting"
    network = "wrist"                 # wrist | planetary-bench | elastic-bench
    duration = "10 s"

    [model]                           # wrist: which sub-models (vsj.wrist.WristOptions)
    elastic = "geometric"
    mesh_relation = "printed"         # eq 3.27: printed | equal-force

    [solver]
    friction = "stiction"             # viscous | arctan | sign | slope | stiction
    step = "1 ms"

    [initial]
    q = "-2.2 cm"

    [inputs.motor_1]                  # one table per input channel
    kind = "sine"
    amplitude = "3 rad/s"
    frequency = "0.5 Hz"
    fade_in = "1 s"

    [params]                          # overrides of the parameter set
    "transmission.series_compliance_1" = "0.05 rad/(N m)"

    [[cases]]
    label = "soft"
    initial = { q = "0.5 cm" }

Input kinds: ``constant`` (value), ``sine`` (amplitude, frequency, phase,
offset, start, fade_in, stop), ``step`` (height, start, offset), ``table``
(times, values, time_unit, unit, interpolation), ``steps`` (levels, unit, hold,
ramp, start: plateaus joined by ramps), ``position`` (signal: an angle whose derivative drives a velocity
source) and ``circle`` (radius, period, fade_in, axis: a position input).

Every value is checked as it is read: its type, unit and range. `prepare_case`
then builds and compiles each case without running it, so whatever a run would
refuse (an initial angle of no flange, an input signal too large for memory) is
refused before anything is written. Every message names the file and the key
path, such as ``scen.toml: cases[1].solver.rtol``.
"""

from __future__ import annotations

import copy
import math
import threading
import tomllib
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Mapping

from . import benches
from .components.planetary import MESH_RELATIONS
from .errors import InputError, read_text
from .friction import law_code
from .inputs import Constant, Input, Position, Sine, Step, Table, circle
from .engine.core import available_cores
from .engine.plan import Plan
from .network import Network, Structure
from .params import Parameters, default
from .progress import progress as bar
from .simulate.options import SOLVERS
from .simulate import (
    InitialState,
    MemorySink,
    Result,
    SimulationOptions,
    check_run_size,
    choose_solver,
    prepare,
    run_plan,
    simulate,
)
from .units import to_si
from .wrist import DRIVES, ELASTIC_MODELS, WristOptions, build_wrist

TOP_KEYS = {"name", "description", "network", "duration", "model", "bench", "solver",
            "initial", "inputs", "params", "cases"}
CASE_KEYS = {"label", "model", "bench", "solver", "initial", "inputs", "params", "duration"}
NETWORKS = ("wrist", "planetary-bench", "elastic-bench")
MODEL_KEYS = {"elastic", "motors", "pivot_drive", "end_effector", "linear_stiffness", "fixed_q",
              "mesh_relation"}
#: [bench] keys of each bench network, with the choices of its text keys.
PLANETARY_BENCH = {"fixed": ("sun", "ring"), "drive": ("speed", "torque"),
                   "sensor_stiffness": None}
ELASTIC_BENCH = {"q": None, "model": tuple(m for m in ELASTIC_MODELS if m != "linear"),
                 "sensor_stiffness": None}
SOLVER_KEYS = {"friction", "method", "rtol", "atol", "step", "output_step", "slope_width",
               "max_step", "max_steps", "friction_overrides"}
INITIAL_KEYS = {"q", "angles", "speeds", "currents"}
INPUT_KINDS = {
    "constant": {"kind", "value"},
    "sine": {"kind", "amplitude", "frequency", "phase", "offset", "start", "fade_in", "stop"},
    "step": {"kind", "height", "start", "offset"},
    "table": {"kind", "times", "values", "time_unit", "unit", "interpolation"},
    "steps": {"kind", "levels", "unit", "hold", "ramp", "start"},
    "position": {"kind", "signal"},
    "circle": {"kind", "radius", "period", "fade_in", "axis"},
}
_REQUIRED = object()


@dataclass(frozen=True)
class Where:
    """A place in a scenario, for messages: the file and a key path (``cases[1].solver``)."""

    origin: str
    path: str = ""

    def key(self, name: str) -> Where:
        """The place one key ``name`` deeper."""
        return Where(self.origin, f"{self.path}.{name}" if self.path else name)

    def __str__(self) -> str:
        return f"{self.origin}: {self.path}" if self.path else self.origin


@dataclass(frozen=True)
class Case:
    """One simulation of a scenario, ready to run."""

    label: str
    network: str
    build: Callable[[Parameters], Network]
    inputs: Mapping[str, Mapping]
    duration: float
    options: SimulationOptions
    initial: InitialState
    params: Mapping[str, Any]
    where: Where


@dataclass(frozen=True)
class Scenario:
    """A scenario loaded and checked: its name, description, origin (file or built-in), its
    cases and the table it was read from."""
    name: str
    description: str
    origin: str
    cases: tuple[Case, ...]
    table: Mapping = field(repr=False, default_factory=dict)

    def resolved_params(self, case: Case, params: Parameters) -> Parameters:
        """``params`` with the case's parameter overrides applied (the same set if it has
        none)."""
        if not case.params:
            return params
        return params.with_overrides(case.params, origin=str(case.where.key("params")),
                                     source=f"scenario {self.name}")


@contextmanager
def _context(where: Where):
    """Prefix an `InputError` of a lower layer, which does not know the file, with ``where``."""
    try:
        yield
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def _check_keys(table: Mapping, allowed, where: Where) -> None:
    if not isinstance(table, Mapping):
        raise InputError(f"{where}: expected a table, got {type(table).__name__} {table!r}")
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: "
                         f"{', '.join(sorted(allowed))}")


def _table(table: Mapping, key: str, where: Where) -> Mapping:
    value = table.get(key, {})
    if not isinstance(value, Mapping):
        raise InputError(f"{where.key(key)}: expected a table, got {type(value).__name__} "
                         f"{value!r}")
    return value


def _quantity(table: Mapping, key: str, unit: str, where: Where, default=_REQUIRED, *,
              positive: bool = False, nonnegative: bool = False):
    """``table[key]`` in SI, or ``default`` when absent (required when no default is given)."""
    if key not in table:
        if default is _REQUIRED:
            raise InputError(f"{where}: missing {key!r} (unit {unit})")
        return default
    value = to_si(table[key], unit, where=str(where.key(key)))
    zero = "0" if unit == "1" else f"0 {unit}"
    if positive and not value > 0.0:
        raise InputError(f"{where.key(key)} = {table[key]!r}: must be > {zero}")
    if nonnegative and not value >= 0.0:
        raise InputError(f"{where.key(key)} = {table[key]!r}: must be >= {zero}")
    return value


def _choice(table: Mapping, key: str, choices, where: Where, default: str) -> str:
    value = table.get(key, default)
    if not isinstance(value, str) or value not in choices:
        raise InputError(f"{where.key(key)}: {value!r} is not one of {', '.join(choices)}")
    return value


def _text(table: Mapping, key: str, where: Where, default: str) -> str:
    value = table.get(key, default)
    if not isinstance(value, str):
        raise InputError(f"{where.key(key)}: expected text in quotes, got {value!r}")
    return value


def _merge(base: Mapping, over: Mapping) -> dict:
    out = copy.deepcopy(dict(base))
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def parse_input(spec: Mapping, unit: str, where: Where, *, angle: bool = False) -> Input:
    """One input channel's signal from its table (values in ``unit``)."""
    if not isinstance(spec, Mapping) or "kind" not in spec:
        raise InputError(f"{where}: an input is a table with a 'kind' "
                         f"({', '.join(INPUT_KINDS)}), got {spec!r}")
    kind = spec["kind"]
    if not isinstance(kind, str) or kind not in INPUT_KINDS:
        raise InputError(f"{where.key('kind')}: unknown input kind {kind!r}; choose one of "
                         f"{', '.join(INPUT_KINDS)}")
    _check_keys(spec, INPUT_KINDS[kind], where)
    if kind == "position":
        if not angle:
            raise InputError(f"{where}: a position input drives a velocity source by its angle; "
                             "this channel is not a velocity source")
        inner = spec.get("signal")
        if isinstance(inner, Mapping) and inner.get("kind") in ("position", "circle"):
            raise InputError(f"{where.key('signal')}: a position signal cannot be nested")
        return Position(parse_input(inner, "rad", where.key("signal")))
    if kind == "circle" and not angle:
        raise InputError(f"{where}: a circle input drives a velocity source by its angle; "
                         "this channel is not a velocity source")
    make, arguments = _signal(kind, spec, unit, where)
    with _context(where):  # what the signal itself refuses (times that do not increase, ...)
        return make(**arguments)


def _signal(kind: str, spec: Mapping, unit: str, where: Where) -> tuple[Callable, dict]:
    """The function that makes an input of ``kind`` and its arguments, read from ``spec``."""
    if kind == "constant":
        return Constant, {"level": _quantity(spec, "value", unit, where)}
    if kind == "sine":
        return Sine, {"amplitude": _quantity(spec, "amplitude", unit, where),
                      "frequency": _quantity(spec, "frequency", "Hz", where, positive=True),
                      "phase": _quantity(spec, "phase", "rad", where, 0.0),
                      "offset": _quantity(spec, "offset", unit, where, 0.0),
                      "start": _quantity(spec, "start", "s", where, 0.0),
                      "fade_in": _quantity(spec, "fade_in", "s", where, 0.0, nonnegative=True),
                      "stop": _quantity(spec, "stop", "s", where, math.inf)}
    if kind == "step":
        return Step, {"height": _quantity(spec, "height", unit, where),
                      "start": _quantity(spec, "start", "s", where, 0.0),
                      "offset": _quantity(spec, "offset", unit, where, 0.0)}
    if kind == "circle":
        return circle, {
            "radius": _quantity(spec, "radius", "rad", where),
            "period": _quantity(spec, "period", "s", where, positive=True),
            "fade_in": _quantity(spec, "fade_in", "s", where, 0.0, nonnegative=True),
            "cos_axis": _choice(spec, "axis", ("cos", "sin"), where, "cos") == "cos"}
    scale = to_si(f"1 {_text(spec, 'unit', where, unit)}", unit, where=str(where.key("unit")))
    if kind == "table":
        time_unit = _text(spec, "time_unit", where, "s")
        time_scale = to_si(f"1 {time_unit}", "s", where=str(where.key("time_unit")))
        times = _numbers(spec.get("times"), where.key("times"))
        values = _numbers(spec.get("values"), where.key("values"))
        return Table, {"times": tuple(t * time_scale for t in times),
                       "values": tuple(v * scale for v in values),
                       "interpolation": _choice(spec, "interpolation", ("linear", "cubic"),
                                                where, "linear")}
    levels = _numbers(spec.get("levels"), where.key("levels"))
    return staircase, {"levels": [v * scale for v in levels],
                       "hold": _quantity(spec, "hold", "s", where, positive=True),
                       "ramp": _quantity(spec, "ramp", "s", where, positive=True),
                       "start": _quantity(spec, "start", "s", where, 0.0, nonnegative=True)}


def _numbers(values, where: Where) -> list[float]:
    if not isinstance(values, list) or not values:
        raise InputError(f"{where}: expected a non-empty list of numbers, got {values!r}")
    out = []
    for i, v in enumerate(values):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputError(f"{where}[{i}]: expected a finite number, got {v!r}")
        out.append(float(v))
    return out


def staircase(levels, *, hold: float, ramp: float, start: float = 0.0) -> Table:
    """Plateaus at ``levels`` joined by linear ramps, from and back to zero."""
    times, values = [0.0], [0.0]
    t = start
    if start > 0:
        times.append(start)
        values.append(0.0)
    for level in levels:
        t += ramp
        times += [t, t + hold]
        values += [level, level]
        t += hold
    times.append(t + ramp)
    values.append(0.0)
    return Table(tuple(times), tuple(values))


def _channel_units(net: Network) -> tuple[dict[str, str], set[str]]:
    structure_parts = net.parts()
    units = {}
    for src in structure_parts.sources:
        units[src.channel] = "rad/s"
    for load in structure_parts.loads:
        units[load.channel] = "N*m"
    for motor in structure_parts.motors:
        units[motor.channel] = "V"
    return units, {s.channel for s in structure_parts.sources}


def _network(network: str, model: Mapping, bench: Mapping,
             where: Where) -> Callable[[Parameters], Network]:
    """The function that builds the case's network from a parameter set."""
    mw, bw = where.key("model"), where.key("bench")
    if network == "wrist":
        if bench:
            raise InputError(f"{bw}: only bench networks take a [bench] table")
        _check_keys(model, MODEL_KEYS, mw)
        options = WristOptions(
            elastic=_choice(model, "elastic", ELASTIC_MODELS, mw, "geometric"),
            motors=_choice(model, "motors", DRIVES, mw, "velocity"),
            pivot_drive=_choice(model, "pivot_drive", DRIVES + ("fixed",), mw, "velocity"),
            end_effector=_choice(model, "end_effector", ("loaded", "driven"), mw, "loaded"),
            linear_stiffness=_quantity(model, "linear_stiffness", "N*m", mw, None,
                                       positive=True),
            fixed_q=_quantity(model, "fixed_q", "m", mw, 0.0),
            mesh_relation=_choice(model, "mesh_relation", tuple(MESH_RELATIONS), mw, "printed"))
        with _context(mw):
            options.validate()
        return lambda params: build_wrist(params, options)
    if model:
        raise InputError(f"{mw}: the {network} takes a [bench] table instead")
    sensor = _quantity(bench, "sensor_stiffness", "N*m", bw, benches.SENSOR_STIFFNESS,
                       positive=True)
    if network == "planetary-bench":
        _check_keys(bench, PLANETARY_BENCH, bw)
        fixed = _choice(bench, "fixed", PLANETARY_BENCH["fixed"], bw, "sun")
        drive = _choice(bench, "drive", PLANETARY_BENCH["drive"], bw, "speed")
        return lambda params: benches.planetary_bench(params, fixed=fixed, drive=drive,
                                                      sensor_stiffness=sensor)
    _check_keys(bench, ELASTIC_BENCH, bw)
    q = _quantity(bench, "q", "m", bw)
    elastic = _choice(bench, "model", ELASTIC_BENCH["model"], bw, "geometric")
    return lambda params: benches.elastic_bench(params, q=q, model=elastic,
                                                sensor_stiffness=sensor)


def _options(solver: Mapping, where: Where) -> SimulationOptions:
    """The [solver] table as simulation options, every value checked."""
    _check_keys(solver, SOLVER_KEYS, where)
    friction = solver.get("friction", "arctan")
    with _context(where.key("friction")):
        law_code(friction)
    overrides = _table(solver, "friction_overrides", where)
    for pattern, law in overrides.items():
        with _context(where.key("friction_overrides").key(pattern)):
            law_code(law)
    rtol = _quantity(solver, "rtol", "1", where, 1e-8, positive=True)
    if not rtol < 1.0:
        raise InputError(f"{where.key('rtol')} = {solver['rtol']!r}: must be below 1 (a "
                         "relative tolerance)")
    max_steps = solver.get("max_steps", 20_000_000)
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise InputError(f"{where.key('max_steps')}: expected a whole number >= 1, got "
                         f"{max_steps!r}")
    return SimulationOptions(
        friction=friction,
        friction_overrides=dict(overrides),
        solver=_choice(solver, "method", SOLVERS, where, "auto"), rtol=rtol,
        atol=_quantity(solver, "atol", "1", where, 1e-10, positive=True),
        step=_quantity(solver, "step", "s", where, 1e-3, positive=True),
        output_step=_quantity(solver, "output_step", "s", where, 1e-3, positive=True),
        slope_width=_quantity(solver, "slope_width", "rad/s", where, 0.01, positive=True),
        max_step=_quantity(solver, "max_step", "s", where, math.inf, positive=True),
        max_steps=max_steps)


def _quantities(table: Mapping, key: str, unit: str, where: Where) -> dict[str, float]:
    """A table of named quantities (``angles = { ring = "0.1 rad" }``) in SI."""
    return {name: to_si(text, unit, where=str(where.key(key).key(name)))
            for name, text in _table(table, key, where).items()}


def _case(table: Mapping, label: str, where: Where) -> Case:
    network = _choice(table, "network", NETWORKS, where, "wrist")
    duration = _quantity(table, "duration", "s", where, positive=True)
    build = _network(network, _table(table, "model", where), _table(table, "bench", where),
                     where)
    options = _options(_table(table, "solver", where), where.key("solver"))
    iw = where.key("initial")
    init = _table(table, "initial", where)
    _check_keys(init, INITIAL_KEYS, iw)
    q0 = _quantity(init, "q", "m", iw, None)
    if network != "wrist" and q0 is not None:
        raise InputError(f"{iw.key('q')}: only the wrist has a pivot mechanism; the elastic "
                         "bench takes [bench] q")
    initial = InitialState(angles=_quantities(init, "angles", "rad", iw),
                           speeds=_quantities(init, "speeds", "rad/s", iw), q=q0,
                           currents=_quantities(init, "currents", "A", iw))
    return Case(label=label, network=network, build=build,
                inputs=dict(_table(table, "inputs", where)), duration=duration,
                options=options, initial=initial, params=dict(_table(table, "params", where)),
                where=where)


def parse_inputs(case: Case, net: Network) -> dict[str, Input]:
    """The case's input tables, parsed with the units of the network's channels; each
    signal is checked to fit in memory over the case's duration."""
    units, sources = _channel_units(net)
    out = {}
    for channel, spec in case.inputs.items():
        where = case.where.key("inputs").key(channel)
        if channel not in units:
            raise InputError(f"{where}: the {case.network} network has no input "
                             f"{channel!r}; its inputs are {', '.join(sorted(units))}")
        out[channel] = parse_input(spec, units[channel], where, angle=channel in sources)
        with _context(where):
            out[channel].knots(case.duration)
    return out


def loads(text: str, origin: str) -> Scenario:
    """Parse scenario text; ``origin`` names it in messages."""
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{origin}: not valid TOML: {exc}") from None
    top = Where(origin)
    _check_keys(table, TOP_KEYS, top)
    name = _text(table, "name", top, Path(origin).stem)
    description = _text(table, "description", top, "")
    base = {k: v for k, v in table.items() if k not in ("name", "description", "cases")}
    cases_table = table.get("cases", [])
    if not isinstance(cases_table, list):
        raise InputError(f"{top.key('cases')}: must be an array of tables ([[cases]])")
    cases = []
    if not cases_table:
        cases.append(_case(base, name, top))
    labels = set()
    for i, entry in enumerate(cases_table):
        where = top.key(f"cases[{i}]")
        _check_keys(entry, CASE_KEYS, where)
        label = _text(entry, "label", where, f"case{i + 1}")
        if label in labels:
            raise InputError(f"{where.key('label')}: duplicate label {label!r}")
        labels.add(label)
        merged = _merge(base, {k: v for k, v in entry.items() if k != "label"})
        cases.append(_case(merged, label, where))
    return Scenario(name=name, description=description, origin=origin, cases=tuple(cases),
                    table=table)


def _builtin_dir() -> Path:
    return Path(str(resources.files("vsj") / "data" / "scenarios"))


def builtin_names() -> list[str]:
    """Names of the built-in scenarios, sorted."""
    return sorted(p.stem for p in _builtin_dir().glob("*.toml"))


def load(name_or_path: str) -> Scenario:
    """A built-in scenario by name, or a scenario file."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        return loads(read_text(path, "scenario file"), str(path))
    builtin = _builtin_dir() / f"{name_or_path}.toml"
    if not builtin.exists():
        raise InputError(f"unknown scenario {name_or_path!r}: not a file, and not one of the "
                         f"built-in scenarios ({', '.join(builtin_names())})")
    return loads(read_text(builtin, "scenario file"), f"built-in scenario {name_or_path}")


@dataclass(frozen=True)
class Prepared:
    """One case built and checked against its parameters, ready to run."""

    case: Case
    params: Parameters  # the set with the case's overrides
    network: Network
    structure: Structure
    inputs: Mapping[str, Input]
    plan: Plan  # the run of the case, compiled (`vsj.engine.plan.Plan`)

    def run(self, *, duration: float | None = None, ports: bool = True, sink=None) -> Result:
        """Simulate the case (for ``duration`` instead of its own, if given; its samples
        to ``sink``, see `vsj.simulate.simulate`)."""
        if duration is None or duration == self.case.duration:
            return run_plan(self.plan, ports=ports, sink=sink)
        return simulate(self.structure, self.inputs, duration, options=self.case.options,
                        initial=self.case.initial, ports=ports, sink=sink)


def prepare_case(scenario: Scenario, case: Case, params: Parameters, *,
                 in_memory: bool = True) -> Prepared:
    """Everything a run of ``case`` needs, checked as far as it can be without
    running: what a run would refuse in its inputs is raised here, before
    anything is written, with the file and key. ``in_memory`` False: the run's
    samples go to a file (`vsj.output.TrajectoryFile`), so only a block of them
    has to fit in memory."""
    where = case.where
    resolved = scenario.resolved_params(case, params)
    with _context(where):
        net = case.build(resolved)
        structure = net.assemble()
    inputs = parse_inputs(case, net)
    pivot = structure.pivot
    if case.initial.q is not None and not pivot.q_min <= case.initial.q <= pivot.q_max:
        raise InputError(f"{where.key('initial').key('q')}: {case.initial.q * 100:g} cm is "
                         f"outside the pivot range [{pivot.q_min * 100:g}, "
                         f"{pivot.q_max * 100:g}] cm")
    options = case.options
    with _context(where.key("solver")):
        check_run_size(structure, case.duration, options, choose_solver(structure, options),
                       in_memory=in_memory)
    with _context(where):  # the initial state against the network, and the compiled inputs
        plan = prepare(structure, inputs, case.duration, options, case.initial)
    return Prepared(case=case, params=resolved, network=net, structure=structure,
                    inputs=inputs, plan=plan)


@dataclass(frozen=True)
class Run:
    """A case and what running it gave."""

    case: Case
    params: Parameters
    result: Result


class Stopped(Exception):
    """Raised in a run of `run_cases` at its next block of samples once its ``stop`` is
    set (another case failed, the user interrupted, or the caller set it)."""


class _StoppableSink:
    """A sink (`vsj.simulate.MemorySink`'s protocol) that passes the blocks of a run on
    to ``sink`` and stops the run at its next block once ``stop`` is set."""

    def __init__(self, sink, stop: threading.Event):
        self.sink, self.stop = sink, stop
        self.keeps_samples = getattr(sink, "keeps_samples", True)

    def begin(self, table, time) -> None:
        self.sink.begin(table, time)

    def write(self, start: int, signals) -> None:
        if self.stop.is_set():
            raise Stopped
        self.sink.write(start, signals)

    def end(self, samples: int):
        return self.sink.end(samples)


def run_cases(prepared: list[Prepared], *, sinks=None, duration: float | None = None,
              ports: bool = True, label: str | None = None,
              stop: threading.Event | None = None) -> list[Result]:
    """Run prepared cases (`prepare_case`), as many at a time as this process has cores,
    and return their results in the cases' order.

    The cases are independent runs, each of its own plan with its own engine work, and
    the engine integrates without holding Python's lock: running them side by side
    gives each the bits it gets alone. ``sinks`` (one per case) take the samples
    (default: in memory, in each `Result`); ``duration`` and ``ports`` as in
    `Prepared.run`; ``label`` shows a progress bar so labelled. Setting ``stop`` ends
    every run at its next block of samples; it is set when a case raises or the user
    interrupts, and the first exception in the cases' order is raised, as a run of
    one case after the other would raise it.
    """
    sinks = [MemorySink() for _ in prepared] if sinks is None else list(sinks)
    stop = threading.Event() if stop is None else stop

    def one(k: int) -> Result:
        return prepared[k].run(duration=duration, ports=ports,
                               sink=_StoppableSink(sinks[k], stop))

    order = range(len(prepared))
    if label is not None:
        order = bar(order, desc=label, unit="case")
    threads = min(available_cores(), len(prepared))
    if threads <= 1:
        return [one(k) for k in order]
    pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="vsj-case")
    futures = [pool.submit(one, k) for k in range(len(prepared))]
    try:
        return [futures[k].result() for k in order]
    except BaseException:
        stop.set()
        raise
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def run(scenario: Scenario | str, params: Parameters | None = None, *,
        duration: float | None = None, ports: bool = True, progress: bool = False,
        ) -> list[Run]:
    """Run every case of a scenario (a `Scenario`, a built-in name or a file), several at
    a time on a machine with several cores (`run_cases`: the same results).

    All cases are prepared before the first runs, so a bad case is refused
    before any time is spent. ``params`` defaults to the bundled set;
    ``duration`` replaces the cases' own; ``ports`` adds connection torques
    and powers to the results; ``progress`` shows a bar on stderr. A failed
    run is returned with ``result.success`` False: the caller decides.
    """
    scen = load(scenario) if isinstance(scenario, str) else scenario
    params = default() if params is None else params
    prepared = [prepare_case(scen, case, params) for case in scen.cases]
    results = run_cases(prepared, duration=duration, ports=ports,
                        label=f"simulate {scen.name}" if progress else None)
    return [Run(p.case, p.params, result) for p, result in zip(prepared, results)]

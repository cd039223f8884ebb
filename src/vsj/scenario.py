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
offset, start, fade_in), ``table`` (times, values, time_unit, unit,
interpolation), ``steps`` (levels, unit, hold, ramp, start: plateaus joined by
ramps), ``position`` (signal: an angle whose derivative drives a velocity
source) and ``circle`` (radius, period, fade_in, axis: a position input).
"""

from __future__ import annotations

import copy
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Callable, Mapping

from . import benches
from .errors import InputError
from .inputs import Constant, Input, Position, Sine, Table, circle
from .network import Network
from .params import Parameters
from .simulate import InitialState, SimulationOptions
from .units import to_si
from .wrist import WristOptions, build_wrist

TOP_KEYS = {"name", "description", "network", "duration", "model", "bench", "solver",
            "initial", "inputs", "params", "cases"}
CASE_KEYS = {"label", "model", "bench", "solver", "initial", "inputs", "params", "duration"}
NETWORKS = ("wrist", "planetary-bench", "elastic-bench")
MODEL_KEYS = {"elastic", "motors", "pivot_drive", "end_effector", "linear_stiffness", "fixed_q"}
BENCH_KEYS = {"fixed", "drive", "sensor_stiffness", "q", "model"}
SOLVER_KEYS = {"friction", "method", "rtol", "atol", "step", "output_step", "slope_width",
               "max_step", "max_steps", "friction_overrides"}
INITIAL_KEYS = {"q", "angles", "speeds", "currents"}


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
    pivot_from_params: bool


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    origin: str
    cases: tuple[Case, ...]
    table: Mapping = field(repr=False, default_factory=dict)

    def resolved_params(self, case: Case, params: Parameters) -> Parameters:
        if not case.params:
            return params
        return params.with_overrides(case.params, origin=f"{self.origin} [{case.label}]",
                                     source=f"scenario {self.name}")


def _check_keys(table: Mapping, allowed: set, where: str) -> None:
    if not isinstance(table, Mapping):
        raise InputError(f"{where}: expected a table, got {type(table).__name__}")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: "
                         f"{', '.join(sorted(allowed))}")


def _quantity(table: Mapping, key: str, unit: str, where: str, default=None):
    if key not in table:
        if default is None:
            raise InputError(f"{where}: missing {key!r} (unit {unit})")
        return default
    return to_si(table[key], unit, where=f"{where}.{key}")


def _merge(base: Mapping, over: Mapping) -> dict:
    out = copy.deepcopy(dict(base))
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def parse_input(spec: Mapping, unit: str, where: str, *, angle: bool = False) -> Input:
    """One input channel's signal from its table (values in ``unit``)."""
    if not isinstance(spec, Mapping) or "kind" not in spec:
        raise InputError(f"{where}: an input is a table with a 'kind' (constant, sine, table, "
                         "steps, position, circle)")
    kind = spec["kind"]
    allowed = {
        "constant": {"kind", "value"},
        "sine": {"kind", "amplitude", "frequency", "phase", "offset", "start", "fade_in"},
        "table": {"kind", "times", "values", "time_unit", "unit", "interpolation"},
        "steps": {"kind", "levels", "unit", "hold", "ramp", "start"},
        "position": {"kind", "signal"},
        "circle": {"kind", "radius", "period", "fade_in", "axis"},
    }
    if kind not in allowed:
        raise InputError(f"{where}.kind: unknown input kind {kind!r}; choose one of "
                         f"{', '.join(allowed)}")
    _check_keys(spec, allowed[kind], where)
    if kind == "constant":
        return Constant(_quantity(spec, "value", unit, where))
    if kind == "sine":
        return Sine(amplitude=_quantity(spec, "amplitude", unit, where),
                    frequency=_quantity(spec, "frequency", "Hz", where),
                    phase=_quantity(spec, "phase", "rad", where, 0.0),
                    offset=_quantity(spec, "offset", unit, where, 0.0),
                    start=_quantity(spec, "start", "s", where, 0.0),
                    fade_in=_quantity(spec, "fade_in", "s", where, 0.0))
    if kind in ("table", "steps"):
        value_unit = spec.get("unit", unit)
        scale = to_si(f"1 {value_unit}", unit, where=f"{where}.unit")
        if kind == "table":
            time_scale = to_si(f"1 {spec.get('time_unit', 's')}", "s", where=f"{where}.time_unit")
            times = _numbers(spec.get("times"), f"{where}.times")
            values = _numbers(spec.get("values"), f"{where}.values")
            return Table(tuple(t * time_scale for t in times), tuple(v * scale for v in values),
                         spec.get("interpolation", "linear"))
        levels = _numbers(spec.get("levels"), f"{where}.levels")
        hold = _quantity(spec, "hold", "s", where)
        ramp = _quantity(spec, "ramp", "s", where)
        start = _quantity(spec, "start", "s", where, 0.0)
        if not (hold > 0 and ramp > 0):
            raise InputError(f"{where}: hold and ramp must be > 0 s")
        return staircase([v * scale for v in levels], hold=hold, ramp=ramp, start=start)
    if kind == "position":
        if not angle:
            raise InputError(f"{where}: a position input drives a velocity source by its angle; "
                             "this channel is not a velocity source")
        inner = spec.get("signal")
        if isinstance(inner, Mapping) and inner.get("kind") in ("position", "circle"):
            raise InputError(f"{where}.signal: a position signal cannot be nested")
        return Position(parse_input(inner, "rad", f"{where}.signal"))
    if not angle:
        raise InputError(f"{where}: a circle input drives a velocity source by its angle; "
                         "this channel is not a velocity source")
    axis = spec.get("axis", "cos")
    if axis not in ("cos", "sin"):
        raise InputError(f"{where}.axis: must be 'cos' or 'sin', got {axis!r}")
    period = _quantity(spec, "period", "s", where)
    if not period > 0:
        raise InputError(f"{where}.period: must be > 0 s")
    return circle(_quantity(spec, "radius", "rad", where), period,
                  fade_in=_quantity(spec, "fade_in", "s", where, 0.0), cos_axis=axis == "cos")


def _numbers(values, where: str) -> list[float]:
    if not isinstance(values, list) or not values:
        raise InputError(f"{where}: expected a non-empty list of numbers")
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


def _case(table: Mapping, label: str, where: str) -> Case:
    network = table.get("network", "wrist")
    if network not in NETWORKS:
        raise InputError(f"{where}.network: must be one of {', '.join(NETWORKS)}, got "
                         f"{network!r}")
    duration = _quantity(table, "duration", "s", where)
    if not duration > 0:
        raise InputError(f"{where}.duration: must be > 0 s")
    model = table.get("model", {})
    bench = table.get("bench", {})
    _check_keys(model, MODEL_KEYS, f"{where}.model")
    _check_keys(bench, BENCH_KEYS, f"{where}.bench")
    if network == "wrist":
        if bench:
            raise InputError(f"{where}.bench: only bench networks take a [bench] table")
        wrist_options = WristOptions(
            elastic=model.get("elastic", "geometric"), motors=model.get("motors", "velocity"),
            pivot_drive=model.get("pivot_drive", "velocity"),
            end_effector=model.get("end_effector", "loaded"),
            linear_stiffness=(_quantity(model, "linear_stiffness", "N*m", f"{where}.model")
                              if "linear_stiffness" in model else None),
            fixed_q=_quantity(model, "fixed_q", "m", f"{where}.model", 0.0))
        wrist_options.validate()

        def build(params, _o=wrist_options):
            return build_wrist(params, _o)
    elif network == "planetary-bench":
        if model:
            raise InputError(f"{where}.model: the planetary bench takes a [bench] table instead")
        fixed = bench.get("fixed", "sun")
        drive = bench.get("drive", "speed")
        sensor = (_quantity(bench, "sensor_stiffness", "N*m", f"{where}.bench")
                  if "sensor_stiffness" in bench else benches.SENSOR_STIFFNESS)

        def build(params, _f=fixed, _d=drive, _s=sensor):
            return benches.planetary_bench(params, fixed=_f, drive=_d, sensor_stiffness=_s)
    else:
        if model:
            raise InputError(f"{where}.model: the elastic bench takes a [bench] table instead")
        q = _quantity(bench, "q", "m", f"{where}.bench")
        elastic = bench.get("model", "geometric")
        sensor = (_quantity(bench, "sensor_stiffness", "N*m", f"{where}.bench")
                  if "sensor_stiffness" in bench else benches.SENSOR_STIFFNESS)

        def build(params, _q=q, _m=elastic, _s=sensor):
            return benches.elastic_bench(params, q=_q, model=_m, sensor_stiffness=_s)
    solver = table.get("solver", {})
    _check_keys(solver, SOLVER_KEYS, f"{where}.solver")
    sw = f"{where}.solver"
    overrides = solver.get("friction_overrides", {})
    if not isinstance(overrides, Mapping):
        raise InputError(f"{sw}.friction_overrides: expected a table of pattern = law")
    options = SimulationOptions(
        friction=solver.get("friction", "arctan"), friction_overrides=dict(overrides),
        solver=solver.get("method", "auto"),
        rtol=float(solver.get("rtol", 1e-8)), atol=float(solver.get("atol", 1e-10)),
        step=_quantity(solver, "step", "s", sw, 1e-3),
        output_step=_quantity(solver, "output_step", "s", sw, 1e-3),
        slope_width=_quantity(solver, "slope_width", "rad/s", sw, 0.01),
        max_step=_quantity(solver, "max_step", "s", sw, math.inf),
        max_steps=int(solver.get("max_steps", 20_000_000)))
    try:
        options.validate()
    except InputError as exc:
        raise InputError(f"{sw}: {exc}") from None
    init = table.get("initial", {})
    _check_keys(init, INITIAL_KEYS, f"{where}.initial")
    iw = f"{where}.initial"
    angles = {k: to_si(v, "rad", where=f"{iw}.angles.{k}") for k, v in
              init.get("angles", {}).items()}
    speeds = {k: to_si(v, "rad/s", where=f"{iw}.speeds.{k}") for k, v in
              init.get("speeds", {}).items()}
    currents = {k: to_si(v, "A", where=f"{iw}.currents.{k}") for k, v in
                init.get("currents", {}).items()}
    q0 = _quantity(init, "q", "m", iw) if "q" in init else None
    if network != "wrist" and q0 is not None:
        raise InputError(f"{iw}.q: only the wrist has a pivot mechanism; the elastic bench "
                         "takes [bench] q")
    initial = InitialState(angles=angles, speeds=speeds, q=q0, currents=currents)
    params = table.get("params", {})
    if not isinstance(params, Mapping):
        raise InputError(f"{where}.params: expected a table of 'section.key' = value")
    inputs = table.get("inputs", {})
    if not isinstance(inputs, Mapping):
        raise InputError(f"{where}.inputs: expected one table per input channel")
    return Case(label=label, network=network, build=build, inputs=dict(inputs),
                duration=duration, options=options, initial=initial, params=dict(params),
                pivot_from_params=(network == "wrist"))


def parse_inputs(case: Case, net: Network, where: str) -> dict[str, Input]:
    """The case's input tables, parsed with the units of the network's channels."""
    units, sources = _channel_units(net)
    out = {}
    for channel, spec in case.inputs.items():
        if channel not in units:
            raise InputError(f"{where}.inputs.{channel}: the {case.network} network has no input "
                             f"{channel!r}; its inputs are {', '.join(sorted(units))}")
        out[channel] = parse_input(spec, units[channel], f"{where}.inputs.{channel}",
                                   angle=channel in sources)
    return out


def loads(text: str, origin: str) -> Scenario:
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{origin}: not valid TOML: {exc}") from None
    _check_keys(table, TOP_KEYS, origin)
    name = str(table.get("name", Path(origin).stem))
    base = {k: v for k, v in table.items() if k not in ("name", "description", "cases")}
    cases_table = table.get("cases", [])
    if not isinstance(cases_table, list):
        raise InputError(f"{origin}: 'cases' must be an array of tables ([[cases]])")
    cases = []
    if not cases_table:
        cases.append(_case(base, name, origin))
    labels = set()
    for i, entry in enumerate(cases_table):
        where = f"{origin}: cases[{i}]"
        _check_keys(entry, CASE_KEYS, where)
        label = str(entry.get("label", f"case{i + 1}"))
        if label in labels:
            raise InputError(f"{where}.label: duplicate label {label!r}")
        labels.add(label)
        merged = _merge(base, {k: v for k, v in entry.items() if k != "label"})
        cases.append(_case(merged, label, where))
    return Scenario(name=name, description=str(table.get("description", "")), origin=origin,
                    cases=tuple(cases), table=table)


def _builtin_dir() -> Path:
    return Path(str(resources.files("vsj") / "data" / "scenarios"))


def builtin_names() -> list[str]:
    return sorted(p.stem for p in _builtin_dir().glob("*.toml"))


def load(name_or_path: str) -> Scenario:
    """A built-in scenario by name, or a scenario file."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise InputError(f"{name_or_path}: cannot read scenario file ({exc.strerror})") \
                from None
        return loads(text, str(path))
    builtin = _builtin_dir() / f"{name_or_path}.toml"
    if not builtin.exists():
        raise InputError(f"unknown scenario {name_or_path!r}: not a file, and not one of the "
                         f"built-in scenarios ({', '.join(builtin_names())})")
    return loads(builtin.read_text(encoding="utf-8"), f"built-in scenario {name_or_path}")


def prepare_case(scenario: Scenario, case: Case, params: Parameters):
    """Everything `vsj.simulate.simulate` needs for one case (validated, nothing run)."""
    where = f"{scenario.origin} [{case.label}]"
    resolved = scenario.resolved_params(case, params)
    net = case.build(resolved)
    structure = net.assemble()
    inputs = parse_inputs(case, net, where)
    pivot_range = (resolved.pivot.q_min, resolved.pivot.q_max) if case.pivot_from_params else None
    if case.initial.q is not None and pivot_range is not None:
        lo, hi = pivot_range
        if not lo <= case.initial.q <= hi:
            raise InputError(f"{where}: initial q = {case.initial.q * 100:g} cm is outside the "
                             f"pivot range [{lo * 100:g}, {hi * 100:g}] cm")
    return resolved, structure, inputs, pivot_range

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

A ``[controller]`` table closes the loop (`vsj.control`): a sampled controller with
its rate, references (the value kinds above), sensors, blocks (PIDs with the semantics
of Modelica's LimPID, discrete linear systems) and actuators, on one bus of named
signals. It drives DC motors' voltages or loads' torques, so the wrist needs
``[model] motors = "dc"`` (voltage_1, voltage_2) and ``pivot_drive = "dc"``
(voltage_s). Example::

    network = "wrist"
    duration = "1 s"

    [model]
    motors = "dc"
    pivot_drive = "dc"

    [controller]
    rate = "1 kHz"                    # or period = "1 ms"; seed = 0 (sensor noise)

    [controller.references.m1]        # a kind of [inputs], in its signal's unit
    kind = "step"
    height = "0.2 rad"

    [[controller.sensors]]
    signal = "motor_1"                # quantity = "angle" | "speed" | "current" | "q"
    counts_per_revolution = 4096      # or resolution, in the reading's unit
    noise = "0.1 mrad"                # standard deviation
    delay = 1                         # samples

    [[controller.sensors]]
    signal = "motor_2"

    [[controller.pid]]
    name = "u1"                       # its output on the bus
    setpoint = "m1"
    measurement = "motor_1"           # or a weighted sum { motor_1 = 0.5, motor_2 = 0.5 }
    k = "40 V/rad"                    # (what it drives) / (what it measures)
    Ti = "0.1 s"                      # also Td, Nd, wp, wd, y_min, y_max, Ni, anti_windup,
                                      # feed_forward

    [[controller.linear]]             # x+ = A x + B u, y = C x + D u at the rate
    name = "u2"
    inputs = [{ m1 = 1.0, motor_2 = -1.0 }]
    unit = "V/rad"                    # of its numbers (SI without it)
    num = [350.0, -316.666655]        # or A, B, C, D (D alone: a static gain)
    den = [1.0, -0.3333333]

    [[controller.actuators]]
    channel = "voltage_1"             # a motor's voltage or a load's torque
    command = "u1"
    limits = ["-12 V", "12 V"]        # default: the motor's voltage_limit
    current_limit = "1 A"

    [[controller.actuators]]
    channel = "voltage_2"
    command = "u2"

Each signal on the bus has a unit: a sensor's that of what it reads, an actuator's
command that of its channel, and the others follow from where signals meet (a PID's
set-point shares its measurement's unit, its output the unit of what reads it, a
weighted sum's terms share one), so that every gain is checked against (its output's
unit) / (its input's). A linear block's own poles may lie on the unit circle (an
integrator); outside it only with ``allow_unstable = true`` (a compensator whose loop
is stable). A case changes an entry of a controller's arrays by its name
(``[cases.controller.pid.u1]``; sensors by their bus name, actuators by channel), or
replaces a whole array.

An ``[environment]`` table puts walls and free bodies at the tip of a link on the
wrist's end-effector (`vsj.environment`): each a Hunt-Crossley contact (force
k d^n + lambda d^n d', never pulling) whose force, penetration, power and energy are
signals (``contact.<name>.force``, ...) and whose energy the ledger books. Example::

    network = "wrist"
    duration = "1 s"

    [environment]
    link = "10 cm"                    # from the end-effector's axes to its tip
    tip_mass = "50 g"
    tip_radius = "5 mm"               # a rounded tip (or tip_area = "1 cm^2", a flat face):
                                      # the safety figures then check the pressure too

    [[environment.walls]]             # a compliant surface on a rigid backing
    name = "table"
    angle = "6 deg"                   # touched where the tip's angle along direction is this
    direction = "+x"                  # +x, -x, +y, -y, or an angle ("45 deg")
    stiffness = "2e4 N/m"             # k [N/m^n]; "7.5e4 N/m^1.5" with exponent = 1.5
    exponent = 1                      # n >= 1
    damping = "4000 N s/m^2"          # lambda [N s/m^(n+1)], or restitution = 0.8 at
                                      # impact_speed = "0.25 m/s"

    [[environment.bodies]]            # a mass on a spring and damper to the ground
    name = "hand"
    angle = "0.1 rad"
    direction = "-x"
    mass = "0.6 kg"
    stiffness = "75 N/mm"             # the contact (skin and tissue), as for walls
    support_stiffness = "1 N/mm"      # the support [N/m] and support_damping [N s/m]

A case changes one contact by its name (``[cases.environment.walls.table] stiffness =
"1e5 N/m"``) or replaces a whole array. A contact that starts penetrated is refused.

Every value is checked as it is read: its type, unit and range. `prepare_case`
then builds and compiles each case without running it, so whatever a run would
refuse (an initial angle of no flange, an input signal too large for memory) is
refused before anything is written. Every message names the file and the key
path, such as ``scen.toml: cases[1].solver.rtol``.
"""

from __future__ import annotations

import copy
import math
import re
import threading
import tomllib
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from . import benches
from .components.planetary import MESH_RELATIONS
from .control import PID, Actuator, Controller, Linear, Sensor, compile_controller
from .control.controller import ANTI_WINDUP, MAX_DELAY, Combination
from .errors import InputError, read_text
from .friction import law_code
from .inputs import Constant, Input, Position, Sine, Step, Table, circle
from .engine.core import available_cores
from .engine.plan import Plan
from .network import Network, Structure
from .params import Parameters, default, did_you_mean
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
from .wrist import DRIVES, ELASTIC_MODELS, WristOptions, build_wrist, unread_changes

if TYPE_CHECKING:  # imported where an [environment] is read: most scenarios have none
    from .environment import Body, Environment, Wall
    from .safety.iso_ts_15066 import Tip

TOP_KEYS = {"name", "description", "network", "duration", "model", "bench", "solver",
            "initial", "inputs", "params", "controller", "environment", "cases"}
CASE_KEYS = {"label", "model", "bench", "solver", "initial", "inputs", "params", "duration",
             "controller", "environment"}
NETWORKS = ("wrist", "planetary-bench", "elastic-bench")
MODEL_KEYS = {"elastic", "motors", "pivot_drive", "end_effector", "linear_stiffness", "fixed_q",
              "mesh_relation"}
#: [bench] keys of each bench network, with the choices of its text keys.
PLANETARY_BENCH = {"fixed": ("sun", "ring"), "drive": ("speed", "torque"),
                   "sensor_stiffness": None}
ELASTIC_BENCH = {"q": None, "model": tuple(m for m in ELASTIC_MODELS if m != "linear"),
                 "sensor_stiffness": None}
SOLVER_KEYS = {"friction", "method", "rtol", "atol", "step", "output_step", "slope_width",
               "max_step", "max_steps", "friction_overrides", "ledger_tolerance"}
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
    #: the [controller] table as written (checked against the network by `prepare_case`)
    controller: Mapping | None = None
    #: the [environment] table read (`vsj.environment.Environment`, in ``build``'s network)
    environment: Environment | None = None
    #: what a [[cases]] entry sets itself, as written (the rest it takes from the file's
    #: top level)
    own: Mapping = field(default_factory=dict, compare=False)


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
            "radius": _quantity(spec, "radius", "rad", where, positive=True),
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


def _channel_units(net: Network | Structure) -> tuple[dict[str, str], set[str]]:
    """The unit of each input channel of a network (or of its assembled structure,
    which holds the same sources, loads and motors), and the channels of its sources."""
    structure_parts = net.parts() if isinstance(net, Network) else net
    units = {}
    for src in structure_parts.sources:
        units[src.channel] = "rad/s"
    for load in structure_parts.loads:
        units[load.channel] = "N*m"
    for motor in structure_parts.motors:
        units[motor.channel] = "V"
    return units, {s.channel for s in structure_parts.sources}


def _network(network: str, model: Mapping, bench: Mapping, where: Where,
             environment: Environment | None = None) -> Callable[[Parameters], Network]:
    """The function that builds the case's network from a parameter set (with the
    ``environment`` at the wrist's end-effector)."""
    mw, bw = where.key("model"), where.key("bench")
    if environment is not None and network != "wrist":
        raise InputError(f"{where.key('environment')}: the {network} has no end-effector to "
                         "touch an environment; [environment] needs network = \"wrist\"")
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
        fixed = options.pivot_drive == "fixed"

        def wrist(params: Parameters) -> Network:
            if fixed and not params["pivot.q_min"] <= options.fixed_q <= params["pivot.q_max"]:
                raise InputError(f"model.fixed_q = {options.fixed_q * 100:g} cm: outside the "
                                 f"pivot range of the parameter set, [{params['pivot.q_min'] * 100:g}"
                                 f", {params['pivot.q_max'] * 100:g}] cm (pivot.q_min, q_max)")
            return build_wrist(params, options)

        if environment is None:
            return wrist
        # lazy: only an [environment] needs it, and vsj simulate starts faster without
        from .environment import add_environment

        return lambda params: add_environment(wrist(params), environment)
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
    """The [solver] table as simulation options, every value checked; a key left out
    takes `SimulationOptions`' default."""
    _check_keys(solver, SOLVER_KEYS, where)
    default = SimulationOptions()
    friction = solver.get("friction", default.friction)
    with _context(where.key("friction")):
        law_code(friction)
    overrides = _table(solver, "friction_overrides", where)
    for pattern, law in overrides.items():
        with _context(where.key("friction_overrides").key(pattern)):
            law_code(law)
    rtol = _quantity(solver, "rtol", "1", where, default.rtol, positive=True)
    if not rtol < 1.0:
        raise InputError(f"{where.key('rtol')} = {solver['rtol']!r}: must be below 1 (a "
                         "relative tolerance)")
    max_steps = solver.get("max_steps", default.max_steps)
    if isinstance(max_steps, bool) or not isinstance(max_steps, int) or max_steps < 1:
        raise InputError(f"{where.key('max_steps')}: expected a whole number >= 1, got "
                         f"{max_steps!r}")
    return SimulationOptions(
        friction=friction,
        friction_overrides=dict(overrides),
        solver=_choice(solver, "method", SOLVERS, where, default.solver), rtol=rtol,
        atol=_quantity(solver, "atol", "1", where, default.atol, positive=True),
        step=_quantity(solver, "step", "s", where, default.step, positive=True),
        output_step=_quantity(solver, "output_step", "s", where, default.output_step,
                              positive=True),
        slope_width=_quantity(solver, "slope_width", "rad/s", where, default.slope_width,
                              positive=True),
        max_step=_quantity(solver, "max_step", "s", where, default.max_step, positive=True),
        max_steps=max_steps,
        ledger_tolerance=_quantity(solver, "ledger_tolerance", "1", where,
                                   default.ledger_tolerance, positive=True))


def _quantities(table: Mapping, key: str, unit: str, where: Where) -> dict[str, float]:
    """A table of named quantities (``angles = { ring = "0.1 rad" }``) in SI."""
    return {name: to_si(text, unit, where=str(where.key(key).key(name)))
            for name, text in _table(table, key, where).items()}


def _case(table: Mapping, label: str, where: Where) -> Case:
    network = _choice(table, "network", NETWORKS, where, "wrist")
    duration = _quantity(table, "duration", "s", where, positive=True)
    environment = None
    if "environment" in table:
        environment = environment_from_table(table["environment"], where.key("environment"))
    build = _network(network, _table(table, "model", where), _table(table, "bench", where),
                     where, environment)
    solver = _table(table, "solver", where)
    options = _options(solver, where.key("solver"))
    if "output_step" in solver and options.output_step > duration:
        raise InputError(f"{where.key('solver').key('output_step')} = {options.output_step:g} s: "
                         f"longer than the duration ({duration:g} s), so the run would keep "
                         "its start only; at most the duration")
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
    controller = table.get("controller")
    if controller is not None:
        _controller_shape(controller, where.key("controller"))
    return Case(label=label, network=network, build=build,
                inputs=dict(_table(table, "inputs", where)), duration=duration,
                options=options, initial=initial, params=dict(_table(table, "params", where)),
                where=where, controller=controller, environment=environment)


def parse_inputs(case: Case, net: Network | Structure) -> dict[str, Input]:
    """The case's input tables, parsed with the units of the network's channels (``net``
    a network or, once assembled, its structure); each signal is checked to fit in
    memory over the case's duration."""
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


# ----------------------------------------------------------------------- the controller
# The [controller] table (see the module's docstring) in the words of vsj.control.

CONTROLLER_KEYS = {"rate", "period", "seed", "references", "sensors", "pid", "linear",
                   "actuators"}
SENSOR_KEYS = {"signal", "quantity", "name", "counts_per_revolution", "resolution", "noise",
               "delay"}
PID_KEYS = {"name", "setpoint", "measurement", "feed_forward", "k", "Ti", "Td", "Nd", "wp",
            "wd", "y_min", "y_max", "Ni", "anti_windup"}
LINEAR_KEYS = {"name", "inputs", "outputs", "A", "B", "C", "D", "num", "den", "unit",
               "allow_unstable"}
ACTUATOR_KEYS = {"channel", "command", "offset", "limits", "current_limit"}
#: The arrays of tables of [controller], their keys, and the key that names an entry
#: (a case changes an entry by that name: [cases.controller.pid.u1]).
CONTROLLER_ARRAYS = {"sensors": (SENSOR_KEYS, "name"), "pid": (PID_KEYS, "name"),
                     "linear": (LINEAR_KEYS, "name"), "actuators": (ACTUATOR_KEYS, "channel")}
#: What a sensor reads, by its quantity (vsj.control.QUANTITIES).
SENSOR_UNITS = {"angle": "rad", "speed": "rad/s", "current": "A", "q": "m"}
#: The kinds of [inputs] a reference may take: those that give a value over time (a
#: position or circle input is a velocity source's angle).
REFERENCE_KINDS = tuple(k for k in INPUT_KINDS if k not in ("position", "circle"))


def _controller_shape(table: Mapping, where: Where) -> None:
    """The [controller] table's keys, and its arrays' entries' keys (values are read by
    `controller_from_table`, which needs the network)."""
    _check_keys(table, CONTROLLER_KEYS, where)
    for key, (allowed, _) in CONTROLLER_ARRAYS.items():
        entries = table.get(key, [])
        if not isinstance(entries, list):
            raise InputError(f"{where.key(key)}: must be an array of tables ([[controller."
                             f"{key}]]), got {type(entries).__name__} {entries!r}")
        for i, entry in enumerate(entries):
            _check_keys(entry, allowed, where.key(f"{key}[{i}]"))
    references = _table(table, "references", where)
    for name, spec in references.items():
        rw = where.key("references").key(name)
        if not isinstance(spec, Mapping) or spec.get("kind") not in REFERENCE_KINDS:
            got = spec.get("kind") if isinstance(spec, Mapping) else spec
            raise InputError(f"{rw}: a reference is a table with a 'kind' of "
                             f"{', '.join(REFERENCE_KINDS)}, got {got!r}")
        _check_keys(spec, INPUT_KINDS[spec["kind"]], rw)
    if not table.get("actuators"):
        raise InputError(f"{where}: the controller drives nothing; give at least one "
                         "[[controller.actuators]] (channel and command)")


def _entry_name(entry, key: str) -> str | None:
    """The name a case uses for an entry of the [controller] array ``key``."""
    if not isinstance(entry, Mapping):
        return None
    if key == "sensors" and "name" not in entry:
        signal, quantity = entry.get("signal", ""), entry.get("quantity", "angle")
        if not isinstance(signal, str) or not isinstance(quantity, str):
            return None
        return Sensor(signal, quantity).label
    name = entry.get(CONTROLLER_ARRAYS[key][1])
    return name if isinstance(name, str) else None


def _merge_named(base, over, where: Where, table: str, arrays, name_of):
    """A case's ``[table]`` (controller, environment) over the scenario's: tables merge key
    by key; an array of ``arrays`` is replaced by an array, or changed entry by entry by a
    table of its entries' names (``name_of(entry, key)``), as in
    ``[cases.controller.pid.u1] k = "60 V/rad"``."""
    if not isinstance(base, Mapping) or not isinstance(over, Mapping):
        return copy.deepcopy(over)
    by_name = {k: v for k, v in over.items() if k in arrays and isinstance(v, Mapping)}
    out = _merge(base, {k: v for k, v in over.items() if k not in by_name})
    for key, changes in by_name.items():
        entries = copy.deepcopy(base.get(key, []))
        if not isinstance(entries, list):
            raise InputError(f"{where.key(key)}: the scenario's {table} has no array "
                             f"[[{table}.{key}]] whose entries this could change")
        names = [name_of(e, key) for e in entries]
        for name, change in changes.items():
            cw = where.key(key).key(name)
            if name not in names:
                shown = ", ".join(repr(n) for n in names if n is not None) or "none"
                raise InputError(f"{cw}: the scenario's {table} has no {key} entry named "
                                 f"{name!r}; it has {shown}")
            if not isinstance(change, Mapping):
                raise InputError(f"{cw}: expected a table of the keys to change, got "
                                 f"{change!r}")
            entries[names.index(name)].update(copy.deepcopy(dict(change)))
        out[key] = entries
    return out


def _whole(table: Mapping, key: str, where: Where, default: int, *, low: int = 0,
           high: int | None = None, what: str = "a whole number") -> int:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or value < low \
            or (high is not None and value > high):
        bound = f">= {low}" if high is None else f"from {low} to {high}"
        raise InputError(f"{where.key(key)}: expected {what} {bound}, got {value!r}")
    return value


def _name(table: Mapping, key: str, where: Where) -> str:
    value = table.get(key)
    if not isinstance(value, str) or not value.strip():
        raise InputError(f"{where.key(key) if key in table else where}: "
                         f"{'missing ' + repr(key) if key not in table else 'expected a name'}"
                         f" (text in quotes){'' if key not in table else f', got {value!r}'}")
    return value


def _combination(table: Mapping, key: str, where: Where) -> Combination:
    """``table[key]``: a bus signal's name, or a table of names with their weights (plain
    numbers)."""
    if key not in table:
        raise InputError(f"{where}: missing {key!r} (a signal's name, or a table of names "
                         "with weights such as { m1 = 1.0, motor_1 = -1.0 })")
    return _combination_value(table[key], where.key(key))


def _combination_value(value, where: Where) -> Combination:
    if isinstance(value, str) and value.strip():
        return value
    if isinstance(value, Mapping) and value:
        for name, weight in value.items():
            if isinstance(weight, bool) or not isinstance(weight, (int, float)) \
                    or not math.isfinite(weight):
                raise InputError(f"{where.key(name)}: a weight is a finite plain number, got "
                                 f"{weight!r}")
        return {name: float(weight) for name, weight in value.items()}
    raise InputError(f"{where}: expected a signal's name or a table of names with weights "
                     f"({{ m1 = 1.0, motor_1 = -1.0 }}), got {value!r}")


def _terms(combination: Combination) -> list[str]:
    return [combination] if isinstance(combination, str) else list(combination)


def _matrix(table: Mapping, key: str, where: Where) -> np.ndarray:
    """A matrix written as a list of rows of plain numbers (a 1x1 one as a number)."""
    value = table[key]
    kw = where.key(key)
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [[value]]
    if not isinstance(value, list) or not all(isinstance(r, list) for r in value):
        raise InputError(f"{kw}: expected a matrix as a list of rows ([[1.0, 0.0], [0.0, "
                         f"1.0]]), got {value!r}")
    widths = {len(r) for r in value}
    if len(widths) > 1:
        raise InputError(f"{kw}: its rows have different lengths ({sorted(widths)})")
    rows = []
    for i, row in enumerate(value):
        rows.append(_numbers(row, kw.key(f"[{i}]")) if row else [])
    return np.array(rows, dtype=float).reshape(len(value), widths.pop() if widths else 0)


@dataclass
class _Block:
    """A [[controller.pid]] or [[controller.linear]] entry before its units are known."""

    kind: str
    entry: Mapping
    where: Where
    name: str
    outputs: tuple[str, ...]
    reads: dict  # key path under the entry -> combination


class _Units:
    """Units of the bus's signals, joined where signals meet (union-find): each class of
    names that must share a unit, with the unit once known and what fixed it."""

    def __init__(self):
        self.parent: dict[str, str] = {}
        self.unit: dict[str, tuple[str, str]] = {}  # root -> (unit, what fixed it)

    def find(self, name: str) -> str:
        self.parent.setdefault(name, name)
        while self.parent[name] != name:
            self.parent[name] = self.parent[self.parent[name]]
            name = self.parent[name]
        return name

    def of(self, name: str) -> str | None:
        return self.unit.get(self.find(name), (None, ""))[0]

    def fix(self, name: str, unit: str, because: str, where: Where) -> None:
        root = self.find(name)
        known = self.unit.get(root)
        if known is not None and known[0] != unit:
            raise InputError(f"{where}: {name!r} would be in {_shown(unit)} ({because}) but is "
                             f"in {_shown(known[0])} ({known[1]})")
        self.unit.setdefault(root, (unit, because))

    def join(self, names, where: Where, what: str) -> None:
        names = list(names)
        for other in names[1:]:
            a, b = self.find(names[0]), self.find(other)
            if a == b:
                continue
            ua, ub = self.unit.get(a), self.unit.get(b)
            if ua is not None and ub is not None and ua[0] != ub[0]:
                raise InputError(f"{where}: {what} must share a unit, but {names[0]!r} is in "
                                 f"{_shown(ua[0])} ({ua[1]}) and {other!r} in "
                                 f"{_shown(ub[0])} ({ub[1]})")
            self.parent[b] = a
            if ua is None and ub is not None:
                self.unit[a] = ub
            self.unit.pop(b, None)


def _shown(unit: str) -> str:
    return unit.replace("*", " ")


def _ratio(top: str, bottom: str) -> str:
    """The unit ``top`` per ``bottom``, as text `to_si` reads (``V/(rad/s)``)."""
    bottom = _shown(bottom)
    return f"{_shown(top)}/{bottom}" if bottom.isalpha() else f"{_shown(top)}/({bottom})"


def _period(table: Mapping, where: Where) -> tuple[float, Where]:
    """The controller's period [s] from ``rate`` or ``period``, and the key it came from."""
    if ("rate" in table) == ("period" in table):
        raise InputError(f"{where}: give either rate (such as \"1 kHz\") or period (such as "
                         "\"1 ms\"), " + ("not both" if "rate" in table else "one of them"))
    if "rate" in table:
        return 1.0 / _quantity(table, "rate", "Hz", where, positive=True), where.key("rate")
    return _quantity(table, "period", "s", where, positive=True), where.key("period")


def _check_period(period: float, pw: Where, case: Case, solver: str) -> None:
    """A controller of ``period`` against the case's run: the time-stepper's steps fit it a
    whole number of times, and it samples more than once and fewer times than the run
    may take steps."""
    options, duration = case.options, case.duration
    step_key = case.where.key("solver").key("step").path
    if solver == "timestep":
        ratio = period / options.step
        if ratio < 1.0 - 1e-9:
            raise InputError(f"{pw}: the controller samples every {period:g} s, more often "
                             f"than the time-stepper steps ({step_key} = {options.step:g} s); "
                             "sample at most once a step, or step shorter")
        # the engine's own test (engine/plan.py check_period): a whole number to round-off
        if abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise InputError(f"{pw}: the controller's period {period:g} s is not a whole "
                             f"number of the time-stepper's steps ({step_key} = "
                             f"{options.step:g} s); the plant would see its commands change "
                             "inside a step")
    if period > duration:
        raise InputError(f"{pw}: the controller's period {period:g} s is longer than the run "
                         f"({duration:g} s): it would sample once")
    if solver != "timestep" and duration / period > options.max_steps:
        raise InputError(f"{pw}: {duration / period:.3g} samples, each ending a step, are more "
                         f"than the run's {case.where.key('solver').key('max_steps').path} = "
                         f"{options.max_steps}")


def _sensor(entry: Mapping, where: Where, structure: Structure) -> Sensor:
    """One [[controller.sensors]] entry, its signal checked against the network."""
    quantity = _choice(entry, "quantity", tuple(SENSOR_UNITS), where, "angle")
    unit = SENSOR_UNITS[quantity]
    if quantity == "q":
        signal = _text(entry, "signal", where, "q")
        if signal != "q":
            raise InputError(f"{where.key('signal')}: the pivot position q is the only "
                             f"signal of quantity 'q', got {signal!r}")
        if structure.pivot.flange is None and not structure.springs:
            raise InputError(f"{where.key('quantity')}: network {structure.name!r} has no "
                             "pivot to measure")
        signal = ""
    else:
        signal = _name(entry, "signal", where)
        if quantity == "current":
            motors = [m.name for m in structure.motors]
            if signal not in motors:
                raise InputError(f"{where.key('signal')}: {signal!r} is not a DC motor of "
                                 f"this network; its motors: {', '.join(motors) or 'none'}"
                                 f"{_DC_HINT if not motors else ''}")
        else:
            signals = {s.name: s.flange for s in structure.signals}
            try:
                structure.index(signals.get(signal, signal))
            except (KeyError, ValueError, InputError):
                raise InputError(f"{where.key('signal')}: unknown signal {signal!r}; the "
                                 f"network's signals: {', '.join(signals)} (or a flange "
                                 "by name)") from None
    if "counts_per_revolution" in entry:
        if quantity != "angle":
            raise InputError(f"{where.key('counts_per_revolution')}: an encoder measures an "
                             f"angle, not a {quantity} (give resolution in {unit} instead)")
        if "resolution" in entry:
            raise InputError(f"{where}: give counts_per_revolution or resolution, not both")
        resolution = 2 * math.pi / _whole(entry, "counts_per_revolution", where, 0, low=1,
                                          what="a whole number of counts")
    else:
        resolution = _quantity(entry, "resolution", unit, where, 0.0, nonnegative=True)
    name = _text(entry, "name", where, "")
    if "name" in entry and not name.strip():
        raise InputError(f"{where.key('name')}: expected a name, got {name!r}")
    return Sensor(signal, quantity, resolution=resolution,
                  noise=_quantity(entry, "noise", unit, where, 0.0, nonnegative=True),
                  delay=_whole(entry, "delay", where, 0, high=MAX_DELAY,
                               what="a whole number of samples"), name=name)


_DC_HINT = ("; to drive the wrist's motors, give it DC motors: [model] motors = \"dc\" "
            "(voltage_1, voltage_2) and pivot_drive = \"dc\" (voltage_s)")


def _actuator_channel(entry: Mapping, where: Where, net: Network, case: Case) -> str:
    """The channel an actuator drives, checked: a DC motor's voltage or a load's torque."""
    channel = _name(entry, "channel", where)
    cw = where.key("channel")
    structure_parts = net.parts()
    sources = {s.channel for s in structure_parts.sources}
    drivable = sorted([m.channel for m in structure_parts.motors]
                      + [ld.channel for ld in structure_parts.loads])
    if channel in drivable:
        if channel in case.inputs:
            raise InputError(f"{case.where.key('inputs').key(channel)}: the controller drives "
                             f"{channel!r} ({cw.path}); remove it from the inputs")
        return channel
    if channel in sources:
        why = (f"{channel!r} is a velocity source (its speed is imposed; a controller drives "
               "a DC motor's voltage or a load's torque)")
    elif channel.startswith("voltage_"):
        why = f"this {case.network} network has no motor voltage {channel!r}"
    else:
        why = f"the {case.network} network has no input {channel!r} a controller can drive"
    hint = _DC_HINT if case.network == "wrist" and (channel in sources
                                                   or channel.startswith("voltage_")) else ""
    raise InputError(f"{cw}: {why}{hint}; this network's drivable inputs: "
                     f"{', '.join(drivable) or 'none'}")


def _pid(block: _Block, units: _Units, period: float) -> PID:
    entry, where = block.entry, block.where
    out, meas = units.of(block.name), units.of(_terms(block.reads["measurement"])[0])
    if out is None:
        raise InputError(f"{where}: the output {block.name!r} drives no actuator and feeds "
                         "no block that fixes its unit, so the unit of k cannot be checked; "
                         "name it in an actuator's command or another block's input")
    gain = _ratio(out, meas)
    if "k" not in entry:
        raise InputError(f"{where}: missing 'k' (unit {gain}: what it drives over what it "
                         "measures)")
    pid = PID(block.name, block.reads["setpoint"], block.reads["measurement"],
              k=to_si(entry["k"], gain, where=f"{where.key('k')} (unit {gain}: its output "
                      f"{block.name!r} over its measurement)"),
              Ti=_quantity(entry, "Ti", "s", where, math.inf, positive=True),
              Td=_quantity(entry, "Td", "s", where, 0.0, nonnegative=True),
              Nd=_quantity(entry, "Nd", "1", where, 10.0, positive=True),
              wp=_quantity(entry, "wp", "1", where, 1.0),
              wd=_quantity(entry, "wd", "1", where, 0.0),
              y_min=_quantity(entry, "y_min", out, where, -math.inf),
              y_max=_quantity(entry, "y_max", out, where, math.inf),
              Ni=_quantity(entry, "Ni", "1", where, 0.9, positive=True),
              anti_windup=_choice(entry, "anti_windup", tuple(ANTI_WINDUP), where,
                                  "back-calculation"),
              feed_forward=block.reads.get("feed_forward", {}))
    if not pid.y_min < pid.y_max:
        raise InputError(f"{where}: y_min = {entry.get('y_min')!r} must be below y_max = "
                         f"{entry.get('y_max')!r}")
    with _context(where):
        pid.parameters(period)
    return pid


def _linear(block: _Block, units: _Units, period: float) -> Linear:
    entry, where = block.entry, block.where
    n_in, n_out = len(block.reads), len(block.outputs)
    if ("num" in entry or "den" in entry) == any(k in entry for k in "ABCD"):
        raise InputError(f"{where}: give a transfer function (num, den) or matrices (A, B, "
                         "C, D; D alone for a static gain), not both and not neither")
    allowed = entry.get("allow_unstable", False)
    if not isinstance(allowed, bool):
        raise InputError(f"{where.key('allow_unstable')}: expected true or false, got "
                         f"{allowed!r}")
    scale = 1.0
    if "unit" in entry:
        ins = {units.of(t) for c in block.reads.values() for t in _terms(c)}
        outs = {units.of(o) for o in block.outputs}
        if None in outs or len(outs) > 1 or None in ins or len(ins) > 1:
            raise InputError(f"{where.key('unit')}: one unit for the block needs its inputs "
                             "to share a known unit and its outputs to share one (outputs: "
                             f"{', '.join(_shown(u) if u else '?' for u in sorted(outs, key=str))})"
                             "; leave unit out to give the numbers in SI")
        gain = _ratio(outs.pop(), ins.pop())
        scale = to_si(f"1 {_text(entry, 'unit', where, '')}", gain,
                      where=f"{where.key('unit')} (unit {gain}: its outputs over its inputs)")
    import control  # lazy: python-control takes ~1 s to import; only linear blocks need it

    if "num" in entry or "den" in entry:
        if n_in != 1 or n_out != 1:
            raise InputError(f"{where}: a transfer function (num, den) has one input and one "
                             f"output; this block names {n_in} and {n_out} (give A, B, C, D)")
        for key in ("num", "den"):
            if key not in entry:
                raise InputError(f"{where}: missing {key!r} (coefficients in descending "
                                 "powers of z)")
        num = _numbers(entry["num"], where.key("num"))
        den = _numbers(entry["den"], where.key("den"))
        if den[0] == 0.0:
            raise InputError(f"{where.key('den')}: the leading coefficient must not be 0")
        if len(np.trim_zeros(num, "f")) > len(den):
            raise InputError(f"{where.key('num')}: the transfer function is improper (num of "
                             "higher degree than den): it would need future inputs")
        _stable(np.roots(den), where.key("den"), allowed)
        system = control.tf([scale * v for v in num], den, period)
    else:
        D = _matrix(entry, "D", where) if "D" in entry else None
        if D is None:
            raise InputError(f"{where}: missing 'D' (a static gain is D alone)")
        if D.shape != (n_out, n_in):
            raise InputError(f"{where.key('D')}: {D.shape[0]} x {D.shape[1]}; the block has "
                             f"{n_out} output(s) and {n_in} input(s)")
        given = [k for k in "ABC" if k in entry]
        if not given:
            system = scale * D
        else:
            if len(given) < 3:
                raise InputError(f"{where}: give A, B and C together (or D alone), got "
                                 f"{', '.join(given)}")
            A, B, C = (_matrix(entry, k, where) for k in "ABC")
            n = A.shape[0]
            for key, m, shape in (("A", A, (n, n)), ("B", B, (n, n_in)),
                                  ("C", C, (n_out, n))):
                if m.shape != shape:
                    raise InputError(f"{where.key(key)}: {m.shape[0]} x {m.shape[1]}; "
                                     f"{shape[0]} x {shape[1]} needed ({n} states, {n_in} "
                                     f"input(s), {n_out} output(s))")
            _stable(np.linalg.eigvals(A), where.key("A"), allowed)
            system = control.ss(A, B, scale * C, scale * D, period)
    linear = Linear(block.name, system, tuple(block.reads.values()), block.outputs,
                    allow_unstable=allowed)
    with _context(where):
        linear.matrices(period)
    return linear


def _stable(poles: np.ndarray, where: Where, allowed: bool) -> None:
    """A linear block's own poles on or inside the unit circle (an integrator's at z = 1
    included), unless the file says ``allow_unstable = true``: outside it the block grows
    by itself, which only a loop that it stabilises can hold (vsj.control.Linear)."""
    largest = float(np.max(np.abs(poles))) if len(poles) else 0.0
    # the engine's own bound (Linear.matrices): the circle's poles within round-off
    if largest > 1.0 + 1e-9 and not allowed:
        raise InputError(f"{where}: a pole of modulus {largest:.6g} > 1: the controller "
                         "itself is unstable (a continuous design's coefficients given as "
                         "discrete ones?); if the loop it closes is stable, say "
                         "allow_unstable = true")


def _blocks(table: Mapping, where: Where) -> list[_Block]:
    blocks = []
    for i, entry in enumerate(table.get("pid", [])):
        bw = where.key(f"pid[{i}]")
        reads = {"setpoint": _combination(entry, "setpoint", bw),
                 "measurement": _combination(entry, "measurement", bw)}
        if "feed_forward" in entry:
            reads["feed_forward"] = _combination(entry, "feed_forward", bw)
        name = _name(entry, "name", bw)
        blocks.append(_Block("pid", entry, bw, name, (name,), reads))
    for i, entry in enumerate(table.get("linear", [])):
        bw = where.key(f"linear[{i}]")
        name = _name(entry, "name", bw)
        inputs = entry.get("inputs")
        if not isinstance(inputs, list) or not inputs:
            raise InputError(f"{bw.key('inputs') if 'inputs' in entry else bw}: "
                             f"{'missing ' if 'inputs' not in entry else ''}'inputs': a list "
                             "of signals' names or weighted sums, one per input of the "
                             "system" + (f", got {inputs!r}" if 'inputs' in entry else ""))
        reads = {f"inputs[{j}]": _combination_value(c, bw.key(f"inputs[{j}]"))
                 for j, c in enumerate(inputs)}
        outputs = entry.get("outputs", [name])
        if not isinstance(outputs, list) or not outputs \
                or not all(isinstance(o, str) and o.strip() for o in outputs):
            raise InputError(f"{bw.key('outputs')}: a list of names, one per output of the "
                             f"system, got {outputs!r}")
        blocks.append(_Block("linear", entry, bw, name, tuple(outputs), reads))
    return blocks


def _in_order(blocks: list[_Block], where: Where) -> list[_Block]:
    """The blocks in an order in which each reads only outputs of blocks before it (in
    the file's order where that is free); a loop is refused."""
    made = {o: b for b in blocks for o in b.outputs}
    done, order, todo = set(), [], list(blocks)
    while todo:
        for b in todo:
            needs = {id(made[t]) for c in b.reads.values() for t in _terms(c) if t in made}
            if needs <= done:
                order.append(b)
                done.add(id(b))
                todo.remove(b)
                break
        else:
            raise InputError(f"{where}: the blocks {', '.join(repr(b.name) for b in todo)} "
                             "read each other's outputs in a loop; a sampled controller needs "
                             "an order in which each block reads only references, sensors and "
                             "blocks before it")
    return order


def _check_bus(refs: Mapping, sensors: list, blocks: list[_Block], actuators: list,
               where: Where) -> None:
    """Every name once on the controller's bus, each channel driven once, every name
    read known."""
    origin: dict[str, Where] = {}
    named = ([(n, where.key("references").key(n)) for n in refs]
             + [(s.label, w) for s, w in sensors]
             + [(o, b.where) for b in blocks for o in b.outputs])
    for name, w in named:
        if name in origin:
            raise InputError(f"{w}: the name {name!r} is already taken on the controller's "
                             f"bus (by {origin[name].path}); give each signal its own name")
        origin[name] = w
    driven: dict[str, Where] = {}
    for _, aw, channel, _ in actuators:
        if channel in driven:
            raise InputError(f"{aw.key('channel')}: {channel!r} is driven by "
                             f"{driven[channel].path} already")
        driven[channel] = aw
    reads = [(b.where.key(k), c) for b in blocks for k, c in b.reads.items()]
    reads += [(aw.key("command"), command) for _, aw, _, command in actuators]
    for rw, combination in reads:
        for term in _terms(combination):
            if term not in origin:
                raise InputError(f"{rw}: unknown signal {term!r}; the controller's signals "
                                 f"are {', '.join(origin)} (references, sensors by name, "
                                 "blocks' outputs)")


def _bus_units(sensors: list, blocks: list[_Block], actuators: list,
               channel_units: Mapping[str, str]) -> _Units:
    """The units of the bus: fixed by the sensors and the actuators' channels, shared
    where signals meet."""
    units = _Units()
    for sensor, sw in sensors:
        units.fix(sensor.label, SENSOR_UNITS[sensor.quantity], f"sensor {sensor.label!r}", sw)
    for _, aw, channel, command in actuators:
        for term in _terms(command):
            units.fix(term, channel_units[channel], f"it drives {channel!r}", aw.key("command"))
    for b in blocks:
        if b.kind == "pid":
            units.join(_terms(b.reads["setpoint"]) + _terms(b.reads["measurement"]), b.where,
                       "a PID's setpoint and measurement")
            units.join([b.name] + _terms(b.reads.get("feed_forward", {})), b.where,
                       "a PID's output and feed_forward")
        else:
            for key, c in b.reads.items():
                units.join(_terms(c), b.where.key(key), "the terms of an input")
    for b in blocks:
        if b.kind == "pid" and units.of(_terms(b.reads["measurement"])[0]) is None:
            raise InputError(f"{b.where.key('measurement')}: its unit is unknown (it reads "
                             "no sensor); a PID measures through a sensor")
    return units


def _actuator(entry: Mapping, aw: Where, channel: str, command: Combination, unit: str,
              structure: Structure) -> Actuator:
    limits = None
    if "limits" in entry:
        value = entry["limits"]
        if not isinstance(value, list) or len(value) != 2:
            raise InputError(f"{aw.key('limits')}: expected [low, high] in {_shown(unit)}, "
                             f"got {value!r}")
        limits = tuple(to_si(v, unit, where=f"{aw.key('limits')}[{j}]")
                       for j, v in enumerate(value))
        if not limits[0] < limits[1]:
            raise InputError(f"{aw.key('limits')}: low < high needed, got {value!r}")
    current = _quantity(entry, "current_limit", "A", aw, math.inf, positive=True)
    if math.isfinite(current) and channel not in {m.channel for m in structure.motors}:
        raise InputError(f"{aw.key('current_limit')}: a current limit needs a motor's "
                         f"voltage; {channel!r} is a load's torque (limit it by limits)")
    return Actuator(channel, command, offset=_quantity(entry, "offset", unit, aw, 0.0),
                    limits=limits, current_limit=current)


def controller_from_table(case: Case, net: Network, structure: Structure
                          ) -> Controller | None:
    """The case's [controller] table as a `vsj.control.Controller` for its network, every
    value, unit and name checked (the file and key path in every message); None if the
    case has no controller."""
    table = case.controller
    if table is None:
        return None
    where = case.where.key("controller")
    period, pw = _period(table, where)
    with _context(case.where.key("solver")):
        solver = choose_solver(structure, case.options)
    _check_period(period, pw, case, solver)
    seed = _whole(table, "seed", where, 0, high=2 ** 53 - 1)
    refs = _table(table, "references", where)
    sensors = [(_sensor(e, where.key(f"sensors[{i}]"), structure), where.key(f"sensors[{i}]"))
               for i, e in enumerate(table.get("sensors", []))]
    blocks = _blocks(table, where)
    actuators = []
    for i, entry in enumerate(table["actuators"]):
        aw = where.key(f"actuators[{i}]")
        actuators.append((entry, aw, _actuator_channel(entry, aw, net, case),
                          _combination(entry, "command", aw)))
    _check_bus(refs, sensors, blocks, actuators, where)
    blocks = _in_order(blocks, where)
    channel_units, _ = _channel_units(net)
    units = _bus_units(sensors, blocks, actuators, channel_units)
    built = [(_pid if b.kind == "pid" else _linear)(b, units, period) for b in blocks]
    references = {}
    for name, spec in refs.items():
        rw = where.key("references").key(name)
        unit = units.of(name)
        if unit is None:
            raise InputError(f"{rw}: no block or actuator reads this reference in a way that "
                             "gives it a unit (compare it with a sensor's reading in a PID's "
                             "setpoint or a weighted sum)")
        references[name] = parse_input(spec, unit, rw)
        with _context(rw):
            references[name].knots(case.duration)
    acts = tuple(_actuator(entry, aw, channel, command, channel_units[channel], structure)
                 for entry, aw, channel, command in actuators)
    names = list(references) + [s.label for s, _ in sensors]
    names += [n for b in built for n in ((b.name,) if isinstance(b, PID) else b.outputs)]
    known = {name: units.of(name).replace("*", " ") for name in names
             if units.of(name) is not None}
    controller = Controller(period=period, actuators=acts,
                            sensors=tuple(s for s, _ in sensors), blocks=tuple(built),
                            references=references, seed=seed, units=known)
    with _context(where):  # what the engine's compiler checks besides (its own words)
        compile_controller(controller, structure, structure.channels())
    return controller


# ---------------------------------------------------------------------- the environment
# The [environment] table (see the module's docstring) in the words of vsj.environment.

ENVIRONMENT_KEYS = {"link", "tip_mass", "tip_area", "tip_radius", "walls", "bodies"}
LAW_KEYS = {"name", "angle", "direction", "stiffness", "exponent", "damping", "restitution",
            "impact_speed"}
#: The arrays of contacts of [environment] and their keys (a case changes an entry by its
#: name: [cases.environment.walls.<name>]).
ENVIRONMENT_ARRAYS = {"walls": LAW_KEYS,
                      "bodies": LAW_KEYS | {"mass", "support_stiffness", "support_damping"}}
#: Directions by name: the axis of the output angle a contact faces [rad].
DIRECTIONS = {"+x": 0.0, "x": 0.0, "-x": math.pi, "+y": math.pi / 2, "y": math.pi / 2,
              "-y": -math.pi / 2}
#: Restitution coefficients `restitution_damping` converts: as e falls to 0 the damping
#: that gives it nears the one at which the law's force vanishes at the rebound
#: (alpha e v -> 1), and below about 0.05 the root is the float next to that bound.
RESTITUTION_RANGE = (0.1, 1.0)
_CONTACT_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*")
_LEADING_NUMBER = re.compile(r"\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)(.*?)\s*$")
# "<force unit>/<length unit>^<power>" with a power that `to_si`'s exponents (one digit)
# cannot write: a decimal (1.5) or a fraction in parentheses ((3/2))
_PER_LENGTH = re.compile(r"(?P<top>.*?)\s*/\s*(?P<length>[^\W\d]\w*)\s*(?:\^|\*\*)\s*"
                         r"(?P<power>\d+(?:\.\d+)?|\(\s*\d+\s*/\s*[1-9]\d*\s*\))")


def _gain_drop(x: float) -> float:
    """x - ln(1 + x), for x > -1, without the cancellation near 0 (its series there)."""
    if abs(x) < 0.1:  # the series' terms fall by 0.1 each: 30 reach below round-off
        return sum((-1) ** k * x ** k / k for k in range(2, 32))
    return x - math.log1p(x)


def restitution_damping(stiffness: float, restitution: float, speed: float) -> float:
    """The Hunt-Crossley damping lambda [N s/m^(n+1)] that gives a free mass striking the
    contact (``stiffness`` k [N/m^n]) at ``speed`` [m/s] the coefficient of restitution
    ``restitution`` e (0.1 <= e <= 1), for any exponent n and mass.

    Along the impact the mass's energy equation separates, m v dv / (1 + alpha v) =
    -k d^n dd with alpha = lambda / k, and the right side integrates to zero between
    touching and leaving; so alpha v_in is the root a of
    ``a - ln(1 + a) = -e a - ln(1 - e a)``, whatever n, k and m are. Its first order
    in (1 - e) is Hunt and Crossley's own ``e = 1 - (2/3) alpha v``, which overstates
    e by 1 % at e = 0.9 and by 4 % at 0.8; the root is exact. As e falls to 0 the
    rebound's force 1 + alpha v_out falls to 0 (the law would pull): e stays >= 0.1.
    """
    low, high = RESTITUTION_RANGE
    if not low <= restitution <= high:
        raise InputError(f"restitution {restitution!r}: must be from {low:g} to {high:g}")
    if restitution == 1.0:
        return 0.0
    e = restitution

    def excess(a: float) -> float:  # > 0 below the root, < 0 above it
        return _gain_drop(a) - _gain_drop(-e * a)

    # bracket: at a -> 0 the excess is a^2 (1 - e^2) / 2 > 0; at a -> 1/e it falls to -inf
    lower, upper = 0.0, (1.0 - 1e-15) / e
    while True:  # bisection to the float spacing: the excess rises then falls once
        middle = 0.5 * (lower + upper)
        if middle in (lower, upper):
            break
        if excess(middle) > 0.0:
            lower = middle
        else:
            upper = middle
    return stiffness * lower / speed


def _per_length_text(top: str, power: float) -> str:
    return f"{top}/m" if power == 1.0 else f"{top}/m^{power:g}"


def _law_coefficient(entry: Mapping, key: str, where: Where, *, exponent: float,
                     force_time: bool) -> float:
    """``entry[key]``: Hunt and Crossley's stiffness k [N/m^n] (or, ``force_time``, their
    damping lambda [N s/m^(n+1)]) in SI. A non-integer n gives the length a non-integer
    power, which `to_si`'s grammar does not write: "7.5e4 N/mm^1.5" is read as a force
    over one length unit to that power (a decimal, or a fraction such as m^(3/2)), the
    power checked against n."""
    kw = where.key(key)
    top, top_si = ("N s", "N*s") if force_time else ("N", "N")
    power = exponent + (1.0 if force_time else 0.0)
    expected = _per_length_text(top, power)
    text = entry[key]
    why = (f"Hunt and Crossley's {'damping' if force_time else 'stiffness'} with exponent = "
           f"{exponent:g} is in {expected} (force{' times time' if force_time else ''} over "
           f"penetration^{power:g})")
    number = _LEADING_NUMBER.match(text) if isinstance(text, str) else None
    per = _PER_LENGTH.fullmatch(number.group(2).strip()) if number else None
    if per is not None and not re.fullmatch(r"\d", per["power"]):
        numbers = [float(v) for v in re.findall(r"\d+(?:\.\d+)?", per["power"])]
        written = numbers[0] / numbers[1] if len(numbers) == 2 else numbers[0]
        if not math.isclose(written, power, rel_tol=1e-12):  # a fraction's rounding
            raise InputError(f"{kw} = {text!r}: its length is to the power {written:g}; "
                             f"{why}")
        scale = to_si(f"1 {per['top']}" if per["top"] else "1", top_si,
                      where=f"{kw} ({why})")
        length = to_si(f"1 {per['length']}", "m", where=f"{kw} ({why})")
        value = float(number.group(1)) * scale / length ** power
        if not math.isfinite(value):
            raise InputError(f"{kw} = {text!r}: not a finite number in {expected}")
        return value
    if not float(power).is_integer():
        raise InputError(f"{kw} = {text!r}: {why}; write it as a number and that unit, such "
                         f"as \"2e4 {expected}\" (a force unit over one length unit to the "
                         f"power {power:g})")
    try:
        return to_si(text, _per_length_text(top_si, power), where=str(kw))
    except InputError as exc:
        raise InputError(f"{exc}; {why}") from None


def _damping(entry: Mapping, where: Where, stiffness: float, exponent: float) -> float:
    """The contact's damping lambda [N s/m^(n+1)]: given, or from a coefficient of
    restitution at an impact speed (`restitution_damping`); 0 without either."""
    given = [k for k in ("damping", "restitution", "impact_speed") if k in entry]
    if "damping" in entry:
        if len(given) > 1:
            raise InputError(f"{where}: give damping, or restitution with impact_speed, not "
                             "both")
        damping = _law_coefficient(entry, "damping", where, exponent=exponent,
                                   force_time=True)
        if not damping >= 0.0:
            raise InputError(f"{where.key('damping')} = {entry['damping']!r}: must be >= 0")
        return damping
    if not given:
        return 0.0
    if len(given) == 1:
        missing = ({"restitution", "impact_speed"} - set(given)).pop()
        raise InputError(f"{where}: {given[0]} needs {missing} (a coefficient of restitution "
                         "holds at one impact speed: Hunt and Crossley's law gives a speed-"
                         "dependent one)")
    restitution = _quantity(entry, "restitution", "1", where)
    low, high = RESTITUTION_RANGE
    if not low <= restitution <= high:
        raise InputError(f"{where.key('restitution')} = {entry['restitution']!r}: must be from "
                         f"{low:g} to {high:g} (1: no damping)")
    speed = _quantity(entry, "impact_speed", "m/s", where, positive=True)
    return restitution_damping(stiffness, restitution, speed)


def _contact(entry: Mapping, where: Where, body: bool) -> Wall | Body:
    """One [[environment.walls]] or [[environment.bodies]] entry, every value checked."""
    # lazy: only an [environment] needs it, and vsj simulate starts faster without
    from .environment import Body, Wall

    _check_keys(entry, ENVIRONMENT_ARRAYS["bodies" if body else "walls"], where)
    name = _name(entry, "name", where)
    if not _CONTACT_NAME.fullmatch(name):
        raise InputError(f"{where.key('name')}: {name!r} is not a contact's name (letters, "
                         "digits, _ and -, starting with a letter or _: it names the signals "
                         "contact.<name>.force, ...)")
    direction = entry.get("direction", "+x")
    if isinstance(direction, str) and direction.strip() in DIRECTIONS:
        direction = DIRECTIONS[direction.strip()]
    else:
        try:
            direction = _quantity(entry, "direction", "rad", where)
        except InputError as exc:
            raise InputError(f"{exc}; or name an axis: {', '.join(DIRECTIONS)}") from None
    exponent = _quantity(entry, "exponent", "1", where, 1.0)
    if not exponent >= 1.0:
        raise InputError(f"{where.key('exponent')} = {entry['exponent']!r}: must be >= 1 "
                         "(Hunt and Crossley's n in k d^n: 1 a linear spring, 1.5 Hertz's "
                         "sphere on a plane; below 1 the stiffness is infinite at first "
                         "touch)")
    if "stiffness" not in entry:
        raise InputError(f"{where}: missing 'stiffness' (unit "
                         f"{_per_length_text('N', exponent)}: k of the force k d^n)")
    stiffness = _law_coefficient(entry, "stiffness", where, exponent=exponent,
                                 force_time=False)
    if not stiffness > 0.0:
        raise InputError(f"{where.key('stiffness')} = {entry['stiffness']!r}: must be > 0")
    common = dict(name=name, angle=_quantity(entry, "angle", "rad", where),
                  direction=direction, stiffness=stiffness, exponent=exponent,
                  damping=_damping(entry, where, stiffness, exponent))
    if not body:
        return Wall(**common)
    if "mass" not in entry:
        raise InputError(f"{where}: missing 'mass' (unit kg): a body is a mass on its "
                         "support (the effective mass of the body part it stands for); a "
                         "fixed surface is a wall ([[environment.walls]])")
    return Body(**common, mass=_quantity(entry, "mass", "kg", where, positive=True),
                support_stiffness=_quantity(entry, "support_stiffness", "N/m", where, 0.0,
                                            nonnegative=True),
                support_damping=_quantity(entry, "support_damping", "N*s/m", where, 0.0,
                                          nonnegative=True))


def environment_from_table(table: Mapping, where: Where) -> Environment:
    """The [environment] table as a `vsj.environment.Environment`, every value, unit and
    name checked (the file and key path in every message): the link's ``link`` and
    ``tip_mass``, its ``walls`` and ``bodies``."""
    # lazy: only an [environment] needs it, and vsj simulate starts faster without
    from .environment import Environment

    _check_keys(table, ENVIRONMENT_KEYS, where)
    contacts, names = [], {}
    for key in ENVIRONMENT_ARRAYS:
        entries = table.get(key, [])
        if not isinstance(entries, list):
            raise InputError(f"{where.key(key)}: must be an array of tables ([[environment."
                             f"{key}]]), got {type(entries).__name__} {entries!r}")
        for i, entry in enumerate(entries):
            ew = where.key(f"{key}[{i}]")
            contact = _contact(entry, ew, key == "bodies")
            if contact.name in names:
                raise InputError(f"{ew.key('name')}: {contact.name!r} is taken by "
                                 f"{names[contact.name].path}; each contact has its own name")
            names[contact.name] = ew
            contacts.append(contact)
    environment = Environment(link=_quantity(table, "link", "m", where, positive=True),
                              contacts=tuple(contacts),
                              tip_mass=_quantity(table, "tip_mass", "kg", where, 0.0,
                                                 nonnegative=True),
                              tip=_tip(table, where))
    with _context(where):  # the environment's own checks (none should be left)
        environment.check()
    return environment


def _tip(table: Mapping, where: Where) -> Tip | None:
    """The tip's contact geometry: ``tip_area`` (a flat face) or ``tip_radius`` (a
    sphere), at most one; None without either."""
    # lazy: only an [environment] needs it, and vsj simulate starts faster without
    from .safety.iso_ts_15066 import Tip

    given = [key for key in ("tip_area", "tip_radius") if key in table]
    if len(given) > 1:
        raise InputError(f"{where}: give tip_area (a flat face) or tip_radius (a rounded "
                         "tip), not both")
    if not given:
        return None
    if given[0] == "tip_area":
        return Tip.flat(_quantity(table, "tip_area", "m^2", where, positive=True))
    return Tip.sphere(_quantity(table, "tip_radius", "m", where, positive=True))


def _contact_name(entry, key: str) -> str | None:
    """The name a case uses for an entry of the [environment] array ``key``."""
    name = entry.get("name") if isinstance(entry, Mapping) else None
    return name if isinstance(name, str) else None


def _contact_where(case: Case, message: str) -> Where | None:
    """The key of the case's contact that ``message`` (the engine's words) is about, or
    None: the engine names a contact, the file names its entry."""
    if case.environment is None:
        return None
    # lazy: only an [environment] needs it, and vsj simulate starts faster without
    from .environment import Body

    index = {"walls": 0, "bodies": 0}
    for contact in case.environment.contacts:
        key = "bodies" if isinstance(contact, Body) else "walls"
        if message.startswith(f"contact {contact.name!r} "):
            return case.where.key("environment").key(f"{key}[{index[key]}]")
        index[key] += 1
    return None


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
        merged = _merge(base, {k: v for k, v in entry.items()
                               if k not in ("label", "controller", "environment")})
        if "controller" in entry:
            merged["controller"] = _merge_named(
                base.get("controller"), entry["controller"], where.key("controller"),
                "controller", CONTROLLER_ARRAYS, _entry_name)
        if "environment" in entry:
            merged["environment"] = _merge_named(
                base.get("environment"), entry["environment"], where.key("environment"),
                "environment", ENVIRONMENT_ARRAYS, _contact_name)
        try:
            cases.append(replace(_case(merged, label, where), own=entry))
        except InputError as exc:
            raise _from_base(exc, where, entry) from None
    return Scenario(name=name, description=description, origin=origin, cases=tuple(cases),
                    table=table)


def _from_base(exc: InputError, where: Where, entry: Mapping) -> InputError:
    """``exc``, raised reading case ``where`` merged with the file's top-level tables, with
    its place in the file: the top-level key path when the value it names comes from
    there (the case does not set it), so that the message points at the line to change
    and not at a case that only inherits it. A message that names no key path of a
    case's tables is left as it is."""
    text = str(exc)
    for sep in (".", ": "):
        if text.startswith(f"{where}{sep}"):
            break
    else:
        return exc
    rest = text[len(f"{where}{sep}"):]
    path = _KEY_PATH.match(rest)
    if path is None:
        return exc
    keys = path.group().split(".")
    if sep == ": " and (len(keys) < 2 or keys[0] not in CASE_KEYS):
        return exc  # words, not a key path
    if _case_sets(entry, keys):
        return exc
    return InputError(f"{where.origin}: {path.group()} (read for {where.path})"
                      f"{rest[path.end():]}")


#: A key path of a scenario's tables: keys joined by dots, each with an array index or not.
_KEY_PATH = re.compile(r"[A-Za-z_][\w-]*(?:\[\d+\])?(?:\.[A-Za-z_][\w-]*(?:\[\d+\])?)*")


def _case_sets(entry: Mapping, keys: list[str]) -> bool:
    """Whether a [[cases]] entry sets the value at the key path ``keys`` itself, or may (an
    array on the way: its entries merge with the top level's by name)."""
    node = entry
    for key in keys:
        name = key.split("[", 1)[0]
        if not isinstance(node, Mapping) or name not in node:
            return False
        node = node[name]
        if name != key or isinstance(node, list):
            return True
    return True


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
    #: the case's [controller], closing the loop in the plan (`vsj.control.Controller`)
    controller: Controller | None = None
    #: what the set changes in vain for this network (`vsj.wrist.unread_changes`); each
    #: run's result carries them first among its warnings
    warnings: tuple[str, ...] = ()

    def run(self, *, duration: float | None = None, ports: bool = True, sink=None) -> Result:
        """Simulate the case (for ``duration`` instead of its own, if given; its samples
        to ``sink``, see `vsj.simulate.simulate`)."""
        if duration is None or duration == self.case.duration:
            result = run_plan(self.plan, ports=ports, sink=sink)
        else:
            result = simulate(self.structure, self.inputs, duration, options=self.case.options,
                              initial=self.case.initial, ports=ports, sink=sink,
                              controller=self.controller)
        result.warnings[:0] = self.warnings
        return result


def prepare_case(scenario: Scenario, case: Case, params: Parameters, *,
                 in_memory: bool = True) -> Prepared:
    """Everything a run of ``case`` needs, checked as far as it can be without
    running: what a run would refuse in its inputs is raised here, before
    anything is written, with the file and key. ``in_memory`` False: the run's
    samples go to a file (`vsj.output.TrajectoryFile`), so only a block of them
    has to fit in memory."""
    try:
        return _prepare_case(scenario, case, params, in_memory)
    except InputError as exc:
        raise _from_base(exc, case.where, case.own) if case.where.path else exc from None


def _prepare_case(scenario: Scenario, case: Case, params: Parameters,
                  in_memory: bool) -> Prepared:
    where = case.where
    resolved = scenario.resolved_params(case, params)
    with _context(where):
        net = case.build(resolved)
        structure = net.assemble()
    inputs = parse_inputs(case, structure)  # the network's parts as assembled: not again
    for key, named in (("angles", case.initial.angles), ("speeds", case.initial.speeds)):
        for name in named:
            if name not in structure.nodes:
                hint = did_you_mean(name, structure.nodes)
                raise InputError(f"{where.key('initial').key(key).key(name)}: no flange "
                                 f"{name!r} in the {case.network}{hint}; its flanges are "
                                 f"{', '.join(structure.nodes)}")
    pivot = structure.pivot
    if case.initial.q is not None and not pivot.q_min <= case.initial.q <= pivot.q_max:
        raise InputError(f"{where.key('initial').key('q')}: {case.initial.q * 100:g} cm is "
                         f"outside the pivot range [{pivot.q_min * 100:g}, "
                         f"{pivot.q_max * 100:g}] cm")
    options = case.options
    with _context(where.key("solver")):
        check_run_size(structure, case.duration, options, choose_solver(structure, options),
                       in_memory=in_memory)
    controller = controller_from_table(case, net, structure)
    try:  # the initial state against the network, and the compiled inputs
        plan = prepare(structure, inputs, case.duration, options, case.initial, controller)
    except InputError as exc:  # a contact that starts penetrated: its key in the file
        raise InputError(f"{_contact_where(case, str(exc)) or where}: {exc}") from None
    return Prepared(case=case, params=resolved, network=net, structure=structure,
                    inputs=inputs, plan=plan, controller=controller,
                    warnings=tuple(unread_changes(net, resolved)))


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

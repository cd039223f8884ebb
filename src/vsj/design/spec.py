"""The design file: what may change, within which bounds, what to optimise, what must hold.

A design file is TOML; every value carries its unit, as in sweep files::

    [design]
    params = "second_prototype"   # the base design: a bundled set or a file (default:
                                  # the bundled set, the report's second prototype)
    seed = 1
    population = 40               # designs per generation
    generations = 25
    algorithm = "nsga2"           # nsga2 | nsga3 (pymoo)
    q_points = 9                  # pivot positions over the pivot range (the datasheet's grid)
    elastic = "geometric"         # the elastic model the objectives use
    batch = 16                    # designs per chunk handed to a worker

    [parameters]                  # parameter keys ('vsj params' lists them) and bounds
    "elastic_element.spring_stiffness" = { min = "100 N/m", max = "400 N/m" }
    "elastic_element.anchor_y" = { min = "2 cm", max = "3.2 cm" }

    [objectives]                  # each with its natural sense, or sense = "min" | "max"
    stiffness_ratio = {}
    max_energy = {}
    tracking_lag = { stiffness = "0.3 N m/rad" }

    [constraints]
    spring_force = { max = "15 N" }
    no_slack = { deflection = "0.1 rad" }
    end_stop = { torque = "0.05 N m" }

`OBJECTIVES` and `CONSTRAINTS` list what can be asked for (`vsj.design.evaluate`
computes them). Every parameter set the optimiser builds must also satisfy the
relations between keys of `vsj.params.RELATIONS` (a constraint that is always there).
`load` checks everything before any evaluation; each message names the file, the key
and the value.
"""

from __future__ import annotations

import hashlib
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError, read_text
from ..params import SCHEMA, Spec
from ..springs import EXPONENTIAL_FIELDS, GEOMETRY_FIELDS, MODELS, ROW_FIELDS
from ..units import format_quantity, to_si
from ..wrist import ELASTIC_MODELS

TOP_KEYS = {"design", "parameters", "objectives", "constraints"}
DESIGN_KEYS = {"params", "seed", "population", "generations", "algorithm", "q_points",
               "elastic", "batch"}
ALGORITHMS = ("nsga2", "nsga3")
#: The elastic models with springs and an end stop (the linear one has neither).
ELASTIC = tuple(m for m in ELASTIC_MODELS if m != "linear")
SENSES = ("min", "max")
#: Most designs one optimisation evaluates (population x generations).
MAX_EVALUATIONS = 10_000_000


@dataclass(frozen=True)
class Kind:
    """An objective or constraint vsj can compute: its SI unit (to show: ``display``),
    natural sense, options (name -> SI unit), required options, and what it is."""

    unit: str
    display: str
    sense: str | None
    options: Mapping[str, str]
    required: frozenset
    description: str
    defaults: Mapping[str, float] = field(default_factory=dict)


_NONE: Mapping[str, str] = {}
#: The objectives, by name. Stiffnesses are about theta_x at zero deflection with both
#: motors held (as the datasheet gives them), over the grid of ``q_points`` pivot
#: positions across the pivot range.
OBJECTIVES: dict[str, Kind] = {
    "stiffness_ratio": Kind("1", "1", "max", _NONE, frozenset(),
                            "stiffness range K_max / K_min over the pivot range"),
    "min_stiffness": Kind("N*m", "N m/rad", "min", _NONE, frozenset(),
                          "smallest stiffness over the pivot range, K_min"),
    "max_stiffness": Kind("N*m", "N m/rad", "max", _NONE, frozenset(),
                          "largest stiffness over the pivot range, K_max"),
    "slack_free_range": Kind("m", "cm", "max", {"deflection": "rad"}, frozenset(),
                             "length of the pivot range where no spring goes slack up to "
                             "the output deflection 'deflection' (default 0 rad)",
                             {"deflection": 0.0}),
    "max_deflection": Kind("rad", "rad", "max", _NONE, frozenset(),
                           "largest elastic deflection held before the end stop (or the "
                           "torque peak) at the setting where it is smallest"),
    "max_energy": Kind("J", "J", "max", _NONE, frozenset(),
                       "largest elastic energy stored up to the largest deflection held"),
    "holding_torque": Kind("N*m", "mN m", "min", _NONE, frozenset(),
                           "largest torque of the stiffness motor's rotor that holds the "
                           "pivot against the springs, over the pivot range and the "
                           "deflections up to the end stop"),
    "tracking_lag": Kind("s", "ms", "min", {"stiffness": "N*m"}, frozenset({"stiffness"}),
                         "report fig 4.15's tracking lag of theta_x in closed loop, at the "
                         "pivot position where the stiffness is 'stiffness' "
                         "(vsj.safety.tradeoff)"),
    "impact_force": Kind("N", "N", "min", {"stiffness": "N*m"}, frozenset({"stiffness"}),
                         "peak contact force of the standard hand impact (ISO/TS 15066 hand "
                         "surrogate on fig 4.15's circle), at the pivot position where the "
                         "stiffness is 'stiffness' (vsj.safety.tradeoff)"),
}
#: The constraints, by name: each a margin that must be >= 0 (SI, the unit given).
CONSTRAINTS: dict[str, Kind] = {
    "spring_force": Kind("N", "N", None, {"max": "N"}, frozenset({"max"}),
                         "no spring pulls harder than 'max' at any setting and deflection "
                         "up to the end stop (margin: max - largest force)"),
    "no_slack": Kind("rad", "rad", None, {"deflection": "rad"}, frozenset(),
                     "no spring goes slack up to the output deflection 'deflection' "
                     "(default 0 rad) at any setting (margin: smallest deflection at which "
                     "one does - deflection)", {"deflection": 0.0}),
    "end_stop": Kind("N*m", "N m", None, {"torque": "N*m"}, frozenset({"torque"}),
                     "every setting holds the output torque 'torque' before the end stop "
                     "or the torque peak (margin: smallest torque held - torque)"),
}
#: The constraint every design has: `vsj.params.RELATIONS` (margin [m]: the smallest).
RELATIONS = "parameter_relations"


@dataclass(frozen=True)
class Variable:
    """A design parameter (``section.key``) with its bounds [lo, hi] (SI)."""

    name: str
    lo: float
    hi: float
    spec: Spec


@dataclass(frozen=True)
class Goal:
    """An objective or a constraint as the file asks for it: its ``kind`` (a key of
    `OBJECTIVES` or `CONSTRAINTS`), the sense (objectives), the options (SI)."""

    name: str
    kind: Kind
    sense: str | None
    options: Mapping[str, float]
    where: str

    @property
    def sign(self) -> float:
        """+1 if smaller is better, -1 if larger is (pymoo minimises)."""
        return 1.0 if self.sense == "min" else -1.0


@dataclass(frozen=True)
class DesignSpec:
    """A design file read and checked (SI values)."""

    origin: str
    text: str
    params: str | None
    seed: int
    population: int
    generations: int
    algorithm: str
    q_points: int
    elastic: str
    batch: int
    variables: tuple[Variable, ...]
    objectives: tuple[Goal, ...]
    constraints: tuple[Goal, ...]

    @property
    def names(self) -> list[str]:
        """The design parameters' keys, in the order of the design vectors."""
        return [v.name for v in self.variables]

    @property
    def evaluations(self) -> int:
        """Designs evaluated in all (population x generations)."""
        return self.population * self.generations

    def sha256(self) -> str:
        """Hash of the file's content (what a resumed optimisation must match)."""
        return hashlib.sha256(self.text.encode()).hexdigest()


def _where(origin: str, *keys: str) -> str:
    return f"{origin}: " + ".".join(keys)


def _keys(table: Mapping, allowed, where: str) -> None:
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: "
                         f"{', '.join(sorted(allowed))}")


def _table(table: Mapping, key: str, origin: str) -> Mapping:
    value = table.get(key, {})
    if not isinstance(value, Mapping):
        raise InputError(f"{_where(origin, key)}: expected a table, got {value!r}")
    return value


def _int(table: Mapping, key: str, where: str, default: int, lo: int, hi: int) -> int:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise InputError(f"{where}.{key} = {value!r}: expected a whole number in [{lo}, {hi}]")
    return value


def _choice(table: Mapping, key: str, where: str, default: str, choices) -> str:
    value = table.get(key, default)
    if value not in choices:
        raise InputError(f"{where}.{key} = {value!r}: expected one of {', '.join(choices)}")
    return value


def _quoted(name: str) -> str:
    return f'"{name}"' if "." in name else name


def _variable(name: str, entry, origin: str) -> Variable:
    where = _where(origin, "parameters", _quoted(name))
    section, _, key = name.partition(".")
    spec = SCHEMA.get(section, {}).get(key)
    if spec is None:
        raise InputError(f"{where}: unknown parameter {name!r}; give a parameter key "
                         f"'section.key' ({', '.join(SCHEMA)}; 'vsj params' lists them)")
    if not isinstance(entry, Mapping):
        raise InputError(f"{where}: expected {{ min = \"<value> <unit>\", max = \"<value> "
                         f"<unit>\" }}, got {entry!r}")
    _keys(entry, {"min", "max"}, where)
    bounds = []
    for bound in ("min", "max"):
        if bound not in entry:
            raise InputError(f"{where}: missing {bound!r} (bounds in {spec.display})")
        value = to_si(entry[bound], spec.unit, where=f"{where}.{bound}")
        why = spec.check(value)
        if why:
            raise InputError(f"{where}.{bound} = {entry[bound]!r}: {why} ({spec.description})")
        bounds.append(value)
    lo, hi = bounds
    if not lo < hi:
        raise InputError(f"{where}: min {entry['min']!r} must be below max {entry['max']!r}")
    return Variable(name, lo, hi, spec)


def _goal(name: str, entry, origin: str, section: str, kinds: Mapping[str, Kind]) -> Goal:
    where = _where(origin, section, name)
    kind = kinds.get(name)
    if kind is None:
        raise InputError(f"{where}: unknown {section[:-1]} {name!r}; {section}: "
                         f"{', '.join(kinds)}")
    if not isinstance(entry, Mapping):
        raise InputError(f"{where}: expected a table (such as {{}}), got {entry!r}")
    allowed = set(kind.options) | ({"sense"} if kind.sense else set())
    _keys(entry, allowed, where)
    sense = _choice(entry, "sense", where, kind.sense, SENSES) if kind.sense else None
    options = dict(kind.defaults)
    for key, unit in kind.options.items():
        if key in entry:
            value = to_si(entry[key], unit, where=f"{where}.{key}")
            if not value >= 0.0:
                raise InputError(f"{where}.{key} = {entry[key]!r}: must be >= 0")
            options[key] = value
    missing = sorted(kind.required - set(options))
    if missing:
        raise InputError(f"{where}: needs {', '.join(missing)} (with its unit)")
    if "stiffness" in options and not options["stiffness"] > 0.0:
        raise InputError(f"{where}.stiffness = {entry['stiffness']!r}: must be > 0 N m/rad")
    return Goal(name, kind, sense, options, where)


def _used_by(name: str, elastic: str, origin: str) -> None:
    """Refuse an elastic element's parameter that ``elastic``, the model the objectives
    use, does not read (the other model's row): every design would be the same."""
    section, _, key = name.partition(".")
    reads = ROW_FIELDS[MODELS[elastic]]
    if section == "elastic_element" and key in set(GEOMETRY_FIELDS + EXPONENTIAL_FIELDS) - set(
            reads):
        raise InputError(f"{_where(origin, 'parameters', _quoted(name))}: the {elastic!r} "
                         f"elastic model (design.elastic) does not read {name}: every design "
                         f"would be the same; it reads {', '.join(reads)} of "
                         "[elastic_element]")


def loads(text: str, origin: str, base: Path | None = None) -> DesignSpec:
    """Parse a design file's text (``base``: the directory relative paths start from)."""
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{origin}: not valid TOML: {exc}") from None
    _keys(table, TOP_KEYS, origin)
    head = _table(table, "design", origin)
    where = _where(origin, "design")
    _keys(head, DESIGN_KEYS, where)
    params = head.get("params")
    if params is not None:
        if not isinstance(params, str) or not params.strip():
            raise InputError(f"{where}.params = {params!r}: expected a bundled parameter set "
                             "or a file, in quotes")
        params = str((base or Path(".")) / params) if params.endswith(".toml") else params
    variables = tuple(_variable(name, entry, origin)
                      for name, entry in _table(table, "parameters", origin).items())
    if not variables:
        raise InputError(f"{origin}: [parameters] is empty: name the parameters to design, "
                         "each with min and max")
    objectives = tuple(_goal(name, entry, origin, "objectives", OBJECTIVES)
                       for name, entry in _table(table, "objectives", origin).items())
    if not objectives:
        raise InputError(f"{origin}: [objectives] is empty: pick at least one of "
                         f"{', '.join(OBJECTIVES)}")
    constraints = tuple(_goal(name, entry, origin, "constraints", CONSTRAINTS)
                        for name, entry in _table(table, "constraints", origin).items())
    algorithm = _choice(head, "algorithm", where, "nsga2", ALGORITHMS)
    population = _int(head, "population", where, 40, 4, 100_000)
    generations = _int(head, "generations", where, 25, 1, 1_000_000)
    if population * generations > MAX_EVALUATIONS:
        raise InputError(f"{where}: population x generations = {population * generations}; "
                         f"at most {MAX_EVALUATIONS} evaluations")
    elastic = _choice(head, "elastic", where, "geometric", ELASTIC)
    for variable in variables:
        _used_by(variable.name, elastic, origin)
    return DesignSpec(origin=origin, text=text, params=params,
                      seed=_int(head, "seed", where, 0, 0, 2 ** 32 - 1),
                      population=population, generations=generations, algorithm=algorithm,
                      q_points=_int(head, "q_points", where, 9, 2, 1000),
                      elastic=elastic,
                      batch=_int(head, "batch", where, 16, 1, 100_000),
                      variables=variables, objectives=objectives, constraints=constraints)


def load(path: str | Path) -> DesignSpec:
    """The design file at ``path``, read and checked (`loads`)."""
    path = Path(path)
    return loads(read_text(path, "design file"), str(path), path.parent)


def show(value: float, unit: str) -> str:
    """An SI ``value`` in the display ``unit`` (for pages and messages)."""
    if not math.isfinite(value):
        return str(value)
    return format_quantity(value, unit)

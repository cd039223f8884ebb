"""The sweep file: which scenario, what to vary, what to measure, what to keep.

A sweep file is TOML; every value carries its unit, as in scenarios::

    [sweep]
    scenario = "fig-4.15"        # a built-in scenario, or a file (relative to this one)
    case = "q=0.0cm"             # which of its cases (default: the first)
    params = "my-set.toml"       # parameter file (default: the bundled set)
    duration = "6 s"             # optional: shorter or longer than the scenario's
    seed = 1
    samples = 256                # draws of the sampled parameters
    design = "lhs"               # random | lhs | sobol (space filling, scipy.stats.qmc)
    # method = "sobol"           # sensitivity analysis (sobol | morris): distributions only

    [vary]                       # q is the initial pivot position; others are parameter keys
    q = { from = "-2 cm", to = "1 cm", count = 7 }             # a grid
    "elastic_element.a1" = { values = ["0.18 N m/rad", "0.2 N m/rad"] }   # a list
    "transmission.stiction" = { distribution = "normal", mean = "10 mN m", sd = "2 mN m" }
    "transmission.viscous" = { distribution = "uniform", low = "2 mN m s", high = "4 mN m s" }
    "differential.stiction" = { distribution = "lognormal", median = "2 mN m", sigma = 0.3 }

    [covariance]                 # a multivariate normal from an identification
    file = "fit.json"            # {"names": [...], "parameters": {...}, "covariance": [[...]]}

    [signals]                    # derived signals: expressions over the run's signals
    reference_x = "0.5 * planetary.sun_teeth / (planetary.sun_teeth + planetary.ring_teeth) / transmission.ratio * (motor_1 + motor_2)"
    target = "0.25 * pi"         # no signal and no t: a constant signal, that value at every sample

    [metrics]
    deflection = { kind = "peak", signal = "phi_1", start = "4 s" }
    lag = { kind = "lag", signal = "theta_x", reference = "reference_x", frequency = "0.5 Hz", start = "4 s" }
    spread = "max(phi_1) - min(phi_1)"                         # an expression

    [output]
    keep = ["theta_x", "phi_1"]  # signals stored per run in sweep.zarr
    every = "10 ms"              # their spacing, and that of the samples metrics see

Grids and lists make a full factorial; the sampled parameters (distributions
and the covariance) are drawn ``samples`` times for each of its points.
Distributions are truncated to the parameter's allowed range (`vsj.params.SCHEMA`,
and for ``q`` the parameter set's pivot range) and optionally to ``min`` and
``max``; a grid or list value, or a distribution's centre or bounds, outside that
range is refused (q's when the parameter set is loaded, before any run).
With a sensitivity ``method`` the design is SALib's: Saltelli's extension of
Sobol's sequence (``samples`` base points, ``samples * (D + 2)`` runs) or Morris
trajectories (``samples`` trajectories of ``D + 1`` runs); grids and covariances do
not combine with it (the indices assume independent inputs).

`load` reads and checks everything that can be checked before a run; every
message names the file, the key and the value.
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import InputError, read_text
from ..params import SCHEMA, Spec
from ..units import format_quantity, to_si
from .metrics import KINDS

TOP_KEYS = {"sweep", "vary", "covariance", "signals", "metrics", "output"}
SWEEP_KEYS = {"scenario", "case", "params", "duration", "seed", "samples", "design", "method"}
DESIGNS = ("random", "lhs", "sobol")
METHODS = ("sobol", "morris")
DISTRIBUTIONS = {"uniform": {"low", "high"}, "normal": {"mean", "sd"},
                 "lognormal": {"median", "sigma"}}
#: The initial pivot position, the one varied quantity that is not a parameter.
Q = "q"
Q_SPEC = Spec("m", "cm", "initial pivot position (bounded by pivot.q_min, pivot.q_max)", None)
#: Most runs one sweep may ask for (the store is allocated up front).
MAX_RUNS = 10_000_000


@dataclass(frozen=True)
class Fixed:
    """A grid or list: the values taken in turn (SI)."""

    name: str
    values: tuple[float, ...]


@dataclass(frozen=True)
class Distribution:
    """A sampled parameter: ``kind`` with its SI arguments, truncated to [lo, hi]."""

    name: str
    kind: str
    arguments: Mapping[str, float]
    lo: float
    hi: float


@dataclass(frozen=True)
class Covariance:
    """Jointly normal parameters (an identification's estimate and covariance, SI)."""

    names: tuple[str, ...]
    mean: tuple[float, ...]
    matrix: tuple[tuple[float, ...], ...]
    origin: str
    bounds: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Metric:
    """A number per run: a built-in ``kind`` with its options, or an ``expression``."""

    name: str
    kind: str
    options: Mapping[str, object]
    where: str


@dataclass(frozen=True)
class SweepSpec:
    """A sweep file read and checked (SI values): the scenario and case it runs, the
    parameters it fixes, samples or draws from a covariance, the design and method, the
    metrics it computes and the signals it keeps."""
    origin: str
    text: str
    scenario: str
    case: str | None
    params: str | None
    duration: float | None
    seed: int
    samples: int
    design: str
    method: str | None
    fixed: tuple[Fixed, ...]
    sampled: tuple[Distribution, ...]
    covariance: Covariance | None
    signals: Mapping[str, str]
    metrics: tuple[Metric, ...]
    keep: tuple[str, ...]
    every: float | None
    table: Mapping = field(repr=False, default_factory=dict)

    @property
    def varied(self) -> list[str]:
        """Names of the varied quantities, in the order of the run coordinates."""
        names = [f.name for f in self.fixed] + [d.name for d in self.sampled]
        return names + list(self.covariance.names if self.covariance else ())

    def sha256(self) -> str:
        """Hash of the file's content (with the method chosen on the command line)."""
        return hashlib.sha256(json.dumps([self.text, self.method]).encode()).hexdigest()


def _where(origin: str, *keys: str) -> str:
    return f"{origin}: " + ".".join(keys)


def _table(table: Mapping, key: str, origin: str) -> Mapping:
    value = table.get(key, {})
    if not isinstance(value, Mapping):
        raise InputError(f"{_where(origin, key)}: expected a table, got {value!r}")
    return value


def _keys(table: Mapping, allowed, where: str) -> None:
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise InputError(f"{where}: unknown key(s) {', '.join(unknown)}; allowed: "
                         f"{', '.join(sorted(allowed))}")


def _int(table: Mapping, key: str, where: str, default: int, lo: int, hi: int) -> int:
    value = table.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise InputError(f"{where}.{key} = {value!r}: expected a whole number in [{lo}, {hi}]")
    return value


def _text(table: Mapping, key: str, where: str, default=None, choices=None):
    value = table.get(key, default)
    if value is None:
        return None
    if not isinstance(value, str) or (choices and value not in choices):
        allowed = f"one of {', '.join(choices)}" if choices else "text in quotes"
        raise InputError(f"{where}.{key} = {value!r}: expected {allowed}")
    return value


def spec_of(name: str) -> Spec | None:
    """The `Spec` of a varied name (``q`` or ``section.key``), or None if there is none."""
    if name == Q:
        return Q_SPEC
    section, _, key = name.partition(".")
    return SCHEMA.get(section, {}).get(key)


def allowed_range(spec: Spec) -> tuple[float, float]:
    """``(minimum, maximum)`` of a schema entry, infinite where it has no bound."""
    lo = -math.inf if spec.minimum is None else spec.minimum
    hi = math.inf if spec.maximum is None else spec.maximum
    return lo, hi


def _quantity(text, spec: Spec, where: str) -> float:
    return to_si(text, spec.unit, where=where, infinite=False)


def _check_value(value: float, spec: Spec, where: str, text) -> None:
    why = spec.check(value)
    if why:
        raise InputError(f"{where} = {text!r}: {why} ({spec.description})")


def _vary(name: str, entry, origin: str, bounds: tuple[float, float] | None = None):
    """The `Fixed` or `Distribution` of ``[vary] name = entry``; ``bounds`` (SI) narrow
    the allowed range (q's: the parameter set's pivot range, known once it is loaded)."""
    where = _where(origin, "vary", json.dumps(name) if "." in name else name)
    spec = spec_of(name)
    if spec is None:
        sections = ", ".join(SCHEMA)
        raise InputError(f"{where}: unknown parameter {name!r}; vary 'q' (the initial pivot "
                         f"position) or a parameter 'section.key' ({sections}; 'vsj params' "
                         "lists them)")
    if not isinstance(entry, Mapping):
        raise InputError(f"{where}: expected a table such as {{ values = [...] }}, "
                         f"{{ from, to, count }} or {{ distribution = ... }}, got {entry!r}")
    if "values" in entry:
        _keys(entry, {"values"}, where)
        texts = entry["values"]
        if not isinstance(texts, list) or not texts:
            raise InputError(f"{where}.values: expected a non-empty list, got {texts!r}")
        values = []
        for i, text in enumerate(texts):
            value = _quantity(text, spec, f"{where}.values[{i}]")
            _check_value(value, spec, f"{where}.values[{i}]", text)
            _check_bounds(value, bounds, name, spec, f"{where}.values[{i}]", text)
            values.append(value)
        return Fixed(name, tuple(values))
    if "from" in entry or "to" in entry or "count" in entry:
        _keys(entry, {"from", "to", "count"}, where)
        for key in ("from", "to", "count"):
            if key not in entry:
                raise InputError(f"{where}: a grid needs 'from', 'to' and 'count'; "
                                 f"missing {key!r}")
        a = _quantity(entry["from"], spec, f"{where}.from")
        b = _quantity(entry["to"], spec, f"{where}.to")
        for value, key in ((a, "from"), (b, "to")):
            _check_value(value, spec, f"{where}.{key}", entry[key])
            _check_bounds(value, bounds, name, spec, f"{where}.{key}", entry[key])
        count = _int(entry, "count", where, 0, 1, 1_000_000)
        if count == 1:
            return Fixed(name, (a,))
        return Fixed(name, tuple(a + (b - a) * i / (count - 1) for i in range(count)))
    if "distribution" not in entry:
        raise InputError(f"{where}: give 'values', a grid ('from', 'to', 'count') or a "
                         f"'distribution' ({', '.join(DISTRIBUTIONS)})")
    kind = _text(entry, "distribution", where, choices=tuple(DISTRIBUTIONS))
    _keys(entry, DISTRIBUTIONS[kind] | {"distribution", "min", "max"}, where)
    lo, hi = allowed_range(spec)
    if bounds is not None:
        lo, hi = max(lo, bounds[0]), min(hi, bounds[1])
    for key, pick in (("min", max), ("max", min)):
        if key in entry:
            value = _quantity(entry[key], spec, f"{where}.{key}")
            _check_value(value, spec, f"{where}.{key}", entry[key])
            lo, hi = (pick(lo, value), hi) if key == "min" else (lo, pick(hi, value))
    if not lo < hi:
        raise InputError(f"{where}: min {entry.get('min')!r} is not below max "
                         f"{entry.get('max')!r}")
    args = {}
    for key in sorted(DISTRIBUTIONS[kind]):
        if key not in entry:
            raise InputError(f"{where}: a {kind} distribution needs "
                             f"{', '.join(sorted(DISTRIBUTIONS[kind]))}; missing {key!r}")
        unit = "1" if key == "sigma" else spec.unit
        args[key] = to_si(entry[key], unit, where=f"{where}.{key}")
    shown = f"[{_show(lo, spec)}, {_show(hi, spec)}]"
    if kind == "uniform":
        if not args["low"] < args["high"]:
            raise InputError(f"{where}: low {entry['low']!r} must be below high "
                             f"{entry['high']!r}")
        for key in ("low", "high"):
            if not lo <= args[key] <= hi:
                raise InputError(f"{where}.{key} = {entry[key]!r}: outside the range {shown} "
                                 f"allowed for {name} ({spec.description})")
    elif kind == "normal":
        if not lo < args["mean"] < hi:
            raise InputError(f"{where}.mean = {entry['mean']!r}: outside the range {shown} "
                             f"allowed for {name} ({spec.description})")
        if not args["sd"] > 0:
            raise InputError(f"{where}.sd = {entry['sd']!r}: must be > 0")
    else:
        if not (args["median"] > 0 and lo < args["median"] < hi):
            raise InputError(f"{where}.median = {entry['median']!r}: a lognormal median must "
                             f"be > 0 and inside the range {shown} allowed for {name}")
        if not args["sigma"] > 0:
            raise InputError(f"{where}.sigma = {entry['sigma']!r}: must be > 0 (the standard "
                             "deviation of the logarithm)")
        lo = max(lo, 0.0)
    return Distribution(name, kind, args, lo, hi)


def _check_bounds(value: float, bounds, name: str, spec: Spec, where: str, text) -> None:
    if bounds is not None and not bounds[0] <= value <= bounds[1]:
        raise InputError(f"{where} = {text!r}: outside the range [{_show(bounds[0], spec)}, "
                         f"{_show(bounds[1], spec)}] allowed for {name} ({spec.description})")


def within_pivot_range(spec: SweepSpec, q_min: float, q_max: float) -> SweepSpec:
    """``spec`` with q's values checked against, and its distribution truncated to, the
    pivot range [q_min, q_max] (m) of the parameter set the sweep runs with: a grid,
    list or distribution outside it is refused before any run (`InputError`)."""
    cov = spec.covariance
    if cov is not None and Q in cov.names:
        j = cov.names.index(Q)
        if not q_min < cov.mean[j] < q_max:
            raise InputError(f"{cov.origin}: parameters.q = {cov.mean[j]!r}: outside the "
                             f"pivot range [{q_min!r}, {q_max!r}] m of the parameter set")
        bounds = tuple((q_min, q_max) if k == j else b for k, b in enumerate(cov.bounds))
        spec = replace(spec, covariance=replace(cov, bounds=bounds))
    entry = spec.table.get("vary", {}).get(Q)
    if entry is None:
        return spec
    item = _vary(Q, entry, spec.origin, bounds=(q_min, q_max))
    if isinstance(item, Fixed):
        return spec
    return replace(spec, sampled=tuple(item if d.name == Q else d for d in spec.sampled))


def _show(value: float, spec: Spec) -> str:
    return format_quantity(value, spec.display) if math.isfinite(value) else \
        ("-inf" if value < 0 else "inf")


def read_covariance(path: Path, where: str) -> Covariance:
    """A covariance file: ``{"names": [...], "parameters": {name: value}, "covariance":
    [[...]]}`` with SI values (what ``vsj fit wrist --json`` is to report)."""
    try:
        text = read_text(path, "covariance file")
    except InputError as exc:
        raise InputError(f"{where} = {str(path)!r}: {exc}") from None
    try:
        record = json.loads(text)
    except ValueError as exc:
        raise InputError(f"{where} = {str(path)!r}: not JSON ({exc})") from None
    if not isinstance(record, Mapping):
        raise InputError(f"{path}: expected an object with names, parameters, covariance")
    names = record.get("names")
    values = record.get("parameters")
    matrix = record.get("covariance")
    if not (isinstance(names, list) and names and all(isinstance(n, str) for n in names)):
        raise InputError(f"{path}: names: expected a list of parameter keys, got {names!r}")
    if not isinstance(values, Mapping):
        raise InputError(f"{path}: parameters: expected an object {{name: value}}, got "
                         f"{values!r}")
    mean, bounds = [], []
    for name in names:
        spec = spec_of(name)
        if spec is None:
            raise InputError(f"{path}: names: unknown parameter {name!r} (in {where})")
        value = values.get(name)
        if isinstance(value, Mapping):  # a fit's {"value": ..., "stderr": ...}
            value = value.get("value")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{path}: parameters.{name}: expected a number (SI), got "
                             f"{value!r}")
        _check_value(float(value), spec, f"{path}: parameters.{name}", value)
        mean.append(float(value))
        bounds.append(allowed_range(spec))
    n = len(names)
    if not (isinstance(matrix, list) and len(matrix) == n and
            all(isinstance(r, list) and len(r) == n for r in matrix)):
        raise InputError(f"{path}: covariance: expected a {n} x {n} list of lists (one row "
                         "per name)")

    try:
        cov = np.array(matrix, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{path}: covariance: expected numbers") from None
    if not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T, rtol=1e-9, atol=0.0):
        raise InputError(f"{path}: covariance: must be finite and symmetric")
    if np.min(np.linalg.eigvalsh(cov)) < -1e-12 * max(1e-300, float(np.max(np.abs(cov)))):
        raise InputError(f"{path}: covariance: not positive semi-definite")
    return Covariance(tuple(names), tuple(mean), tuple(tuple(r) for r in cov.tolist()),
                      str(path), tuple(bounds))


def _metric(name: str, entry, origin: str) -> Metric:
    where = _where(origin, "metrics", name)
    if isinstance(entry, str):
        return Metric(name, "expression", {"expression": entry}, where)
    if not isinstance(entry, Mapping) or "kind" not in entry:
        raise InputError(f"{where}: expected an expression in quotes or a table with a "
                         f"'kind' ({', '.join(KINDS)}), got {entry!r}")
    kind = entry["kind"]
    if kind not in KINDS:
        raise InputError(f"{where}.kind = {kind!r}: unknown metric; built-in metrics are "
                         f"{', '.join(KINDS)} (or write an expression)")
    _keys(entry, KINDS[kind].keys | {"kind"}, where)
    options = {}
    for key in KINDS[kind].keys:
        if key in entry:
            unit = KINDS[kind].units.get(key)
            value = entry[key]
            if unit is not None:
                value = to_si(value, unit, where=f"{where}.{key}")
            elif not isinstance(value, str):
                raise InputError(f"{where}.{key} = {value!r}: expected a signal name or "
                                 "expression in quotes")
            options[key] = value
    missing = sorted(KINDS[kind].required - set(options))
    if missing:
        raise InputError(f"{where}: metric kind {kind!r} needs {', '.join(missing)}")
    _check_metric_options(options, entry, where)
    return Metric(name, kind, options, where)


def _check_metric_options(options: Mapping, entry: Mapping, where: str) -> None:
    """Refuse a window, frequency or tolerance no run can be measured with (the
    window's samples are checked against the run's when the scenario is known)."""
    for key in ("start", "stop"):
        if key in options and not (math.isfinite(options[key]) and options[key] >= 0.0):
            raise InputError(f"{where}.{key} = {entry[key]!r}: must be a finite time >= 0 s "
                             "(from the start of the run)")
    if "start" in options and "stop" in options and not options["stop"] > options["start"]:
        raise InputError(f"{where}.stop = {entry['stop']!r}: must be after start = "
                         f"{entry['start']!r}")
    if "frequency" in options and not (math.isfinite(options["frequency"])
                                       and options["frequency"] > 0.0):
        raise InputError(f"{where}.frequency = {entry['frequency']!r}: must be a finite "
                         "frequency > 0 Hz (the lag is the phase lag at it over 2 pi f)")
    if "tolerance" in options and not (math.isfinite(options["tolerance"])
                                       and 0.0 < options["tolerance"] < 1.0):
        raise InputError(f"{where}.tolerance = {entry['tolerance']!r}: must be a fraction "
                         "of the signal's change between 0 and 1")


def loads(text: str, origin: str, base: Path | None = None) -> SweepSpec:
    """Parse a sweep file's text (``base``: the directory relative paths start from)."""
    try:
        table = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{origin}: not valid TOML: {exc}") from None
    _keys(table, TOP_KEYS, origin)
    base = base or Path(".")
    head = _table(table, "sweep", origin)
    where = _where(origin, "sweep")
    _keys(head, SWEEP_KEYS, where)
    scenario = _text(head, "scenario", where)
    if scenario is None:
        raise InputError(f"{where}: missing 'scenario' (a built-in name or a file)")
    if scenario.endswith(".toml"):
        scenario = str(base / scenario)
    params = _text(head, "params", where)
    if params is not None:
        params = str(base / params)
    duration = None
    if "duration" in head:
        duration = to_si(head["duration"], "s", where=f"{where}.duration")
        if not duration > 0:
            raise InputError(f"{where}.duration = {head['duration']!r}: must be > 0 s")
    seed = _int(head, "seed", where, 0, 0, 2 ** 63 - 1)
    samples = _int(head, "samples", where, 1, 1, MAX_RUNS)
    design = _text(head, "design", where, "random", DESIGNS)
    method = _text(head, "method", where, None, METHODS)
    fixed, sampled = [], []
    for name, entry in _table(table, "vary", origin).items():
        item = _vary(name, entry, origin)
        (fixed if isinstance(item, Fixed) else sampled).append(item)
    covariance = None
    cov_table = _table(table, "covariance", origin)
    if cov_table:
        cw = _where(origin, "covariance")
        _keys(cov_table, {"file"}, cw)
        file = _text(cov_table, "file", cw)
        if file is None:
            raise InputError(f"{cw}: missing 'file' (a JSON file with names, parameters, "
                             "covariance)")
        covariance = read_covariance(base / file, f"{cw}.file")
        both = sorted(set(covariance.names) & {v.name for v in fixed + sampled})
        if both:
            raise InputError(f"{cw}.file = {file!r}: {', '.join(both)} also in [vary]; vary a "
                             "parameter in one place")
    signals = dict(_table(table, "signals", origin))
    for name, expression in signals.items():
        if not isinstance(expression, str):
            raise InputError(f"{_where(origin, 'signals', name)} = {expression!r}: expected "
                             "an expression in quotes")
    metrics = tuple(_metric(name, entry, origin)
                    for name, entry in _table(table, "metrics", origin).items())
    out = _table(table, "output", origin)
    ow = _where(origin, "output")
    _keys(out, {"keep", "every"}, ow)
    keep = out.get("keep", [])
    if not isinstance(keep, list) or not all(isinstance(k, str) for k in keep):
        raise InputError(f"{ow}.keep = {keep!r}: expected a list of signal names")
    every = None
    if "every" in out:
        every = to_si(out["every"], "s", where=f"{ow}.every")
        if not every > 0:
            raise InputError(f"{ow}.every = {out['every']!r}: must be > 0 s")
    spec = SweepSpec(origin=origin, text=text, scenario=scenario,
                     case=_text(head, "case", where), params=params, duration=duration,
                     seed=seed, samples=samples, design=design, method=method,
                     fixed=tuple(fixed), sampled=tuple(sampled), covariance=covariance,
                     signals=signals, metrics=metrics, keep=tuple(keep), every=every,
                     table=table)
    check_design(spec)
    return spec


def check_design(spec: SweepSpec) -> None:
    """Refuse what the design cannot do (a sensitivity method on grids or correlated
    inputs; a sweep that varies nothing; more runs than `MAX_RUNS`)."""
    where = _where(spec.origin, "sweep")
    if spec.method is not None:
        if spec.fixed or spec.covariance is not None:
            raise InputError(f"{where}.method = {spec.method!r}: sensitivity indices need "
                             "independent distributions only; move grids, lists and the "
                             "covariance out of this sweep")
        if not spec.sampled:
            raise InputError(f"{where}.method = {spec.method!r}: nothing to analyse; give "
                             "distributions in [vary]")
    if not (spec.fixed or spec.sampled or spec.covariance):
        raise InputError(f"{spec.origin}: [vary] is empty: name what to vary")
    if run_count(spec) > MAX_RUNS:
        raise InputError(f"{where}: {run_count(spec)} runs; at most {MAX_RUNS} per sweep")


def run_count(spec: SweepSpec) -> int:
    """Number of runs the sweep makes: the grid of fixed values times the samples its design
    needs."""
    factorial = math.prod(len(f.values) for f in spec.fixed)
    if not (spec.sampled or spec.covariance):
        return factorial
    d = len(spec.sampled)
    if spec.method == "sobol":
        return spec.samples * (d + 2)
    if spec.method == "morris":
        return spec.samples * (d + 1)
    return factorial * spec.samples


def with_method(spec: SweepSpec, method: str | None) -> SweepSpec:
    """``spec`` with the command line's ``--method`` (which wins over the file's)."""
    if method is None or method == spec.method:
        return spec
    out = replace(spec, method=method)
    check_design(out)
    return out


def load(path: str | Path) -> SweepSpec:
    """The sweep file at ``path``, read and checked (`loads`)."""
    path = Path(path)
    return loads(read_text(path, "sweep file"), str(path), path.parent)

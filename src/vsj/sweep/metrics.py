"""Numbers per run: built-in metrics and expressions over named signals.

Expressions are parsed with `ast` and only a small grammar is accepted: numbers,
``+ - * / **``, parentheses, names of signals (``theta_x``,
``spring.vsm_1.elastic.deflection``), of parameters (``planetary.sun_teeth``), ``t``
(time, s) and ``pi``, and calls of the functions in `ELEMENTWISE` and
`REDUCTIONS`. Nothing else is evaluated: no attribute of an object, no
subscript, no call of anything else. Names are resolved when the sweep file is
read, so an unknown one is refused before any run.

A metric is evaluated on a block of runs at once (`Context`: their samples every
``[output] every`` seconds, one row a run), each run's number from its own row
alone; ``start`` and ``stop`` limit it to a window of time.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

ELEMENTWISE: dict[str, tuple[int, Callable]] = {
    "abs": (1, np.abs), "sqrt": (1, np.sqrt), "exp": (1, np.exp), "log": (1, np.log),
    "sin": (1, np.sin), "cos": (1, np.cos), "tan": (1, np.tan), "arctan": (1, np.arctan),
    "sign": (1, np.sign), "arctan2": (2, np.arctan2), "minimum": (2, np.minimum),
    "maximum": (2, np.maximum),
}
#: Reductions over each run's samples (the last axis), one number a run, kept as a
#: column (runs x 1) so that it combines with signals (runs x samples) sample by sample.
REDUCTIONS: dict[str, Callable] = {
    "max": lambda v: np.max(v, axis=-1, keepdims=True),
    "min": lambda v: np.min(v, axis=-1, keepdims=True),
    "mean": lambda v: np.mean(v, axis=-1, keepdims=True),
    "std": lambda v: np.std(v, axis=-1, keepdims=True),
    "rms": lambda v: np.sqrt(np.mean(np.square(v), axis=-1, keepdims=True)),
    "peak": lambda v: np.max(np.abs(v), axis=-1, keepdims=True),
    "final": lambda v: v[..., -1:], "initial": lambda v: v[..., :1],
}
#: Reductions that need the sample times.
TIMED = {"integral"}
_BINARY = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
           ast.Div: np.true_divide, ast.Pow: np.power}


@dataclass
class Context:
    """A block of runs as metrics see them: their sample times (the same for every run),
    their signals on demand (runs x samples), their parameters (each a column, runs x
    1) and each run's count of stick-slip transitions."""

    time: np.ndarray
    signal: Callable[[str], np.ndarray]
    parameters: Mapping[str, np.ndarray]
    transitions: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        """``(runs, samples)``: the shape of a signal."""
        return (len(self.transitions), len(self.time))


def dotted(node) -> str | None:
    """``a.b.c`` from a chain of attribute nodes, or None if it is anything else."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    parts.append(node.id)
    return ".".join(reversed(parts))


class Expression:
    """A checked expression; `__call__` evaluates it on a `Context`."""

    def __init__(self, text: str, signals: set[str], parameters: set[str], where: str):
        self.text = text
        self.where = where
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as exc:
            raise InputError(f"{where} = {text!r}: not an expression ({exc.msg})") from None
        self.signals: set[str] = set()
        self._fn, self.per_sample = self._compile(tree.body, signals, parameters)

    def _fail(self, why: str):
        raise InputError(f"{self.where} = {self.text!r}: {why}")

    def _compile(self, node, signals, parameters) -> tuple[Callable, bool]:
        """``(function of a Context, whether it gives one value per sample)``."""
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            value = float(node.value)
            return (lambda c: value), False
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            inner, vector = self._compile(node.operand, signals, parameters)
            if isinstance(node.op, ast.UAdd):
                return inner, vector
            return (lambda c: np.negative(inner(c))), vector
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            op = _BINARY[type(node.op)]
            a, va = self._compile(node.left, signals, parameters)
            b, vb = self._compile(node.right, signals, parameters)
            return (lambda c: op(a(c), b(c))), va or vb
        if isinstance(node, (ast.Name, ast.Attribute)):
            return self._name(node, signals, parameters)
        if isinstance(node, ast.Call):
            name = node.func.id if isinstance(node.func, ast.Name) else None
            if node.keywords or name is None:
                self._fail("call functions by name with plain arguments, as max(theta_x)")
            compiled = [self._compile(a, signals, parameters) for a in node.args]
            args = [fn for fn, _ in compiled]
            if name in ELEMENTWISE:
                count, fn = ELEMENTWISE[name]
                if len(args) != count:
                    self._fail(f"{name} takes {count} argument(s), got {len(args)}")
                return (lambda c: fn(*(a(c) for a in args))), any(v for _, v in compiled)
            if name in REDUCTIONS or name in TIMED:
                if len(args) != 1:
                    self._fail(f"{name} takes 1 argument, got {len(args)}")
                (arg,) = args
                if name == "integral":
                    return (lambda c: _integral(runs_of(arg(c), c.shape), c.time)), False
                reduce = REDUCTIONS[name]
                return (lambda c: reduce(runs_of(arg(c), c.shape))), False
            self._fail(f"unknown function {name!r}; allowed: "
                       f"{', '.join(sorted([*ELEMENTWISE, *REDUCTIONS, *TIMED]))}")
        self._fail(f"{type(node).__name__} is not allowed; write arithmetic (+ - * / **) of "
                   "numbers, signals, parameters and functions")

    def _name(self, node, signals, parameters) -> tuple[Callable, bool]:
        name = dotted(node)
        if name is None:
            self._fail("only names of signals and parameters may be written with dots")
        if name == "t":
            return (lambda c: c.time), True
        if name == "pi":
            return (lambda c: math.pi), False
        if name in signals:
            self.signals.add(name)
            return (lambda c: c.signal(name)), True
        if name in parameters:
            return (lambda c: c.parameters[name]), False
        close = sorted(s for s in signals if s.split(".")[-1] == name.split(".")[-1])[:5]
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        self._fail(f"unknown name {name!r}: not a signal of this scenario, a [signals] "
                   f"entry, a parameter, t or pi{hint}")

    def __call__(self, context: Context):
        """The expression's value on ``context``: a number, a column (runs x 1) or an
        array of runs x samples."""
        return self._fn(context)


#: Functions whose value has the unit of their arguments (which must share one).
_SAME_UNIT = {"max", "min", "mean", "std", "rms", "peak", "final", "initial", "abs",
              "minimum", "maximum"}


def expression_unit(text: str, units: Mapping[str, str]) -> str:
    """The unit of a (checked) expression where it follows plainly from its signals'
    ``units``: sums and differences of one unit, a sign, and the functions that keep
    their arguments' unit (max, mean, rms, abs, ...), as ``max(phi_1) - min(phi_1)`` is
    in rad. Anything else gives "" (unknown): a product or a quotient, a parameter, a
    scale by a number (100 * q is in cm, not m), a function such as log."""
    class Unknown(Exception):
        pass

    def same(parts):
        known = {u for u in parts if u is not None}
        if len(known) > 1:
            raise Unknown
        return known.pop() if known else None

    def unit(node) -> str | None:  # None: a bare number, which takes the unit beside it
        if isinstance(node, ast.Constant):
            return None
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            return unit(node.operand)
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)):
            return same([unit(node.left), unit(node.right)])
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in _SAME_UNIT:
            return same([unit(a) for a in node.args])
        name = dotted(node) if isinstance(node, (ast.Name, ast.Attribute)) else None
        if name in units and units[name]:
            return units[name]
        raise Unknown

    try:
        return unit(ast.parse(text.strip(), mode="eval").body) or ""
    except (Unknown, SyntaxError):
        return ""


def sampled(value, shape: tuple) -> np.ndarray:
    """``value`` (an array or a number) as an array of ``shape``: itself if it is one
    already (read, never written), else broadcast (a read-only view)."""
    if isinstance(value, np.ndarray) and value.shape == shape:
        return value
    return np.broadcast_to(value, shape)


def runs_of(value, shape: tuple, window=slice(None)) -> np.ndarray:
    """``value`` as runs x samples (`sampled`), the samples in ``window`` only, each run
    one contiguous row: a reduction along a row then sums it in the order it sums a
    single run's samples, however many runs there are (along a strided axis, numpy
    sums in another order)."""
    return np.ascontiguousarray(sampled(value, shape)[:, window])


def _integral(values: np.ndarray, time: np.ndarray) -> np.ndarray:
    """Trapezoidal integral of each run's samples (a column, runs x 1)."""
    if len(time) < 2:
        return np.zeros(values.shape[:-1] + (1,))
    steps = (values[..., 1:] + values[..., :-1]) * np.diff(time)
    return np.sum(steps, axis=-1, keepdims=True) / 2.0


@dataclass(frozen=True)
class Kind:
    """A built-in metric: its option keys (SI unit, or None for a signal expression)."""

    keys: frozenset
    required: frozenset
    units: Mapping[str, str | None]
    unit: str | None  # the metric's unit; None: that of its signal
    description: str


def _kind(description, unit, required=(), **options) -> Kind:
    units = {**{r: None for r in required}, "start": "s", "stop": "s", **options}
    return Kind(frozenset(units), frozenset(required), units, unit, description)


KINDS: dict[str, Kind] = {
    "peak": _kind("largest magnitude of the signal", None, ("signal",)),
    "rms": _kind("root mean square of the signal", None, ("signal",)),
    "mean": _kind("mean of the signal", None, ("signal",)),
    "final": _kind("the signal's last value", None, ("signal",)),
    "tracking_rms": _kind("root mean square of signal - reference", None,
                          ("signal", "reference")),
    "tracking_peak": _kind("largest magnitude of signal - reference", None,
                           ("signal", "reference")),
    "lag": _kind("time the signal lags the reference at a frequency (phase lag / 2 pi f)",
                 "s", ("signal", "reference", "frequency"), frequency="Hz"),
    "settling_time": _kind("time from the window's start until the signal stays within "
                           "tolerance x its change of its final value", "s", ("signal",),
                           tolerance="1"),
    "energy_dissipated": _kind("energy dissipated by friction (trapezoidal integral of the "
                               "friction powers)", "J"),
    "stick_slip_transitions": _kind("stick/slip transitions counted by the time-stepper "
                                    "(0 with smooth friction laws, which never stick)", "1"),
}


class Evaluator:
    """A metric made ready: its expressions checked against the available names."""

    def __init__(self, metric, signals: set[str], parameters: set[str],
                 units: Mapping[str, str], friction_powers: list[str]):
        self.name = metric.name
        self.kind = metric.kind
        self.options = dict(metric.options)
        where = metric.where
        self.expressions = {}
        for key, value in metric.options.items():
            if key in ("signal", "reference", "expression"):
                self.expressions[key] = Expression(value, signals, parameters, f"{where}.{key}")
        if metric.kind == "expression" and self.expressions["expression"].per_sample:
            raise InputError(f"{where} = {metric.options['expression']!r}: gives one value per "
                             "sample; reduce it to one number per run with max, min, mean, rms, "
                             "peak, final, initial, std or integral")
        if metric.kind == "energy_dissipated":
            if not friction_powers:
                raise InputError(f"{where}: energy_dissipated needs the friction powers, which "
                                 "this solver does not sample (stiction: use the time-stepper's "
                                 "ledger through vsj simulate)")
            self.expressions["signal"] = Expression(
                " + ".join(friction_powers), signals, parameters, where)
        self._times = None  # (sample times, window, projection) cached for them
        signal = metric.options.get("signal")
        kind = KINDS.get(metric.kind)
        self.unit = (expression_unit(metric.options["expression"], units) if kind is None
                     else kind.unit if kind.unit is not None
                     else units.get(signal) or expression_unit(signal, units))

    def _window(self, time: np.ndarray) -> np.ndarray:
        """The samples inside [start, stop] (every run of a sweep has the same times)."""
        seen = None if self._times is None else self._times[0]
        if seen is None or not (seen is time or np.array_equal(seen, time)):
            start = self.options.get("start", -math.inf)
            stop = self.options.get("stop", math.inf)
            # an array that cannot change is kept as it is: the next run's is the same
            # object (`vsj.sweep.runner.Prepared.t_out`), known equal without a comparison
            fixed = not time.flags.writeable and time.base is None
            self._times = (time if fixed else time.copy(),
                           (time >= start - 1e-12) & (time <= stop + 1e-12), None)
        return self._times[1]

    def _projection(self, t: np.ndarray) -> np.ndarray:
        """The least-squares projection on sine and cosine at the frequency over the
        window's times ``t`` (2 x samples), made once."""
        if self._times[2] is None:
            self._times = (*self._times[:2], sine_projection(t, self.options["frequency"]))
        return self._times[2]

    @property
    def signals(self) -> set[str]:
        """Names of the signals the metric's expressions read."""
        return set().union(*(e.signals for e in self.expressions.values()))

    def __call__(self, c: Context) -> np.ndarray:
        """The metric of every run of ``c`` (one number a run)."""
        return np.broadcast_to(self._value(c), (c.shape[0], 1))[:, 0].astype(float)

    def _value(self, c: Context):
        kind = self.kind
        if kind == "stick_slip_transitions":
            return c.transitions[:, None]
        if kind == "expression":
            return self.expressions["expression"](c)
        window = self._window(c.time)
        t = c.time[window]
        if len(t) == 0:
            return math.nan
        s = runs_of(self.expressions["signal"](c), c.shape, window)
        if kind == "energy_dissipated":
            return -_integral(s, t)
        if kind in ("tracking_rms", "tracking_peak", "lag"):
            r = runs_of(self.expressions["reference"](c), c.shape, window)
            if kind == "lag":
                return _lag(s, r, self._projection(t))[:, None]
            s = s - r
        if kind in ("peak", "tracking_peak"):
            return REDUCTIONS["peak"](s)
        if kind in ("rms", "tracking_rms"):
            return REDUCTIONS["rms"](s)
        if kind == "mean":
            return REDUCTIONS["mean"](s)
        if kind == "final":
            return s[:, -1:]
        tolerance = self.options.get("tolerance", 0.02)
        return np.array([[_settling(row, t, tolerance)] for row in s])


def sine_projection(t: np.ndarray, frequency: float) -> tuple[np.ndarray, float]:
    """The least-squares projection on sine and cosine at ``frequency`` [Hz] over the
    times ``t``: (its pseudo-inverse, 2 x samples; the angular frequency)."""
    w = 2.0 * math.pi * frequency
    return np.linalg.pinv(np.column_stack([np.sin(w * t), np.cos(w * t)])), w


def phase_lag(t: np.ndarray, signal: np.ndarray, reference: np.ndarray,
              frequency: float) -> float:
    """The time [s] ``signal`` lags ``reference`` at ``frequency`` [Hz] over the samples at
    ``t`` (their phase difference at that frequency over 2 pi f, in (-1/2f, 1/2f])."""
    return float(_lag(signal, reference, sine_projection(t, frequency)))


def _lag(signal, reference, projection) -> np.ndarray:
    """Phase lag [s] of ``signal`` behind ``reference`` at a frequency, for each run
    (the leading axes; samples along the last): both projected (least squares) on sine
    and cosine at it over the window; ``projection`` is (the pseudo-inverse of that
    basis, the angular frequency). Each projection is a sum over the run's own samples
    (not a matrix product, whose sums a BLAS may order by the number of runs)."""
    pinv, w = projection
    a_s, b_s = (np.sum(signal * row, axis=-1) for row in pinv)
    a_r, b_r = (np.sum(reference * row, axis=-1) for row in pinv)
    delta = np.arctan2(b_r, a_r) - np.arctan2(b_s, a_s)
    delta = (delta + math.pi) % (2.0 * math.pi) - math.pi
    return delta / w


def _settling(s, t, tolerance: float) -> float:
    final = s[-1]
    change = abs(final - s[0]) or float(np.ptp(s))
    outside = np.flatnonzero(np.abs(s - final) > tolerance * change)
    if not len(outside):
        return 0.0
    k = min(int(outside[-1]) + 1, len(t) - 1)
    return float(t[k] - t[0])

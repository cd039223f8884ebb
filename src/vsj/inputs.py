"""Input signals: what drives the motors, the loads and the pivot over time.

Every input channel of a network (a velocity source's speed [rad/s], a load
torque [N m], a motor voltage [V]) is given one `Input`. The engine evaluates
each as a piecewise cubic polynomial, which gives the value, its derivative and
its integral exactly and cheaply in compiled code; analytic inputs are turned
into such a spline on a grid fine enough that the difference is below 1e-9 of
their amplitude.

A velocity source may also be driven by its *angle*: wrap the angle signal in
`Position`; its speed is then the spline's derivative and its initial angle the
signal's value at time zero.

A sampled signal's size is checked before anything is allocated: `Input.knots`
counts the knots a duration needs, and more than `MAX_KNOTS` raise `InputError`
(a 1 GHz sine over seconds would need billions).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from . import _core
from .errors import InputError, is_number

#: Coefficient rows are (c0, c1, c2, c3) of c0 + c1 tau + c2 tau^2 + c3 tau^3, tau = t - knot.
Pieces = tuple[np.ndarray, np.ndarray]
#: Most knots a sampled signal may have, and the memory one knot takes while its spline is
#: built (measured peak of `spline_pieces`, inputs included): 0.3 GB at most.
MAX_KNOTS = 2_000_000
BYTES_PER_KNOT = 150


class Input:
    """Base class of input signals."""

    #: True if the signal is an angle whose derivative drives a velocity source.
    is_position = False

    def value(self, t):
        """The signal's value at the times ``t`` [s] (scalar or array), in the unit of the
        channel it drives (rad/s, N m or V).

        Subclasses implement this; the engine evaluates `pieces` instead."""
        raise NotImplementedError

    def pieces(self, t_end: float) -> Pieces:
        """Knots and cubic coefficients covering ``[0, t_end]``."""
        raise NotImplementedError

    def knots(self, t_end: float) -> int:
        """Number of knots `pieces` would make, counted without making them; `InputError`
        if a sampled signal would need more than `MAX_KNOTS`."""
        raise NotImplementedError

    def repeats(self) -> tuple[float, float] | None:
        """``(t0, period)`` if the signal repeats with ``period`` [s] from ``t0`` on, and
        ``pieces(t0 + period)`` ends with one period that starts on a knot (the engine
        then repeats it instead of splining the whole run); None otherwise."""
        return None

    def describe(self) -> str:
        """The signal in one line of words (here its repr; subclasses say it in words)."""
        return repr(self)


def as_inputs(inputs, channels) -> dict[str, Input]:
    """``inputs`` checked as a run's inputs: a mapping from channel names (of
    ``channels``) to `Input` signals, where a plain number stands for a `Constant`.
    Anything else (an array of samples, a function) is refused with what to write
    instead."""
    if not isinstance(inputs, Mapping):
        raise InputError(f"inputs must be a mapping of channel names to signals, got "
                         f"{type(inputs).__name__}")
    out = {}
    for name, signal in inputs.items():
        if not isinstance(name, str):
            raise InputError(f"input channel names are strings, got {name!r}")
        if name not in channels:
            raise InputError(f"unknown input channel {name!r}; the network has "
                             f"{', '.join(channels) or 'none'}")
        if isinstance(signal, Input):
            out[name] = signal
        elif isinstance(signal, (int, float, np.integer, np.floating)) \
                and not isinstance(signal, bool):
            out[name] = Constant(float(signal))
        else:
            hint = (" (samples: Table(times, values), or Hold(times, values) to hold each)"
                    if isinstance(signal, (np.ndarray, list, tuple)) else "")
            raise InputError(f"input {name!r} must be a vsj.inputs signal (Constant, Sine, "
                             f"Step, Table, Hold, Position, ...) or a number, got "
                             f"{type(signal).__name__}{hint}")
    return out


def engine_pieces(signal: Input, t_end: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The pieces the engine holds of ``signal`` over ``[0, t_end]``, and the period it
    repeats them with (0: none): a signal that repeats (`Input.repeats`) within
    ``t_end`` is splined up to the end of its first whole period only."""
    repeats = signal.repeats()
    period = 0.0
    if repeats is not None and repeats[0] + repeats[1] < t_end:
        knots, coef = signal.pieces(repeats[0] + repeats[1])
        period = repeats[1]
    else:
        knots, coef = signal.pieces(t_end)
    knots, coef = from_zero(np.asarray(knots, dtype=float),
                            np.asarray(coef, dtype=float).reshape(-1, 4))
    return knots, coef, period


def from_zero(knots: np.ndarray, coef: np.ndarray) -> Pieces:
    """The same signal on ``[0, knots[-1]]`` as pieces whose first knot is t = 0 (a run's
    start): the engine integrates a source's speed from the first knot, so a table that
    starts later gains a piece holding its first value from 0, and one that starts
    earlier loses what lies before 0 (the piece across 0 re-expanded about it). Pieces
    that start at 0, and a signal that ends before 0 (held at its last value), keep or
    become one piece from 0."""
    if knots[0] == 0.0:
        return knots, coef
    if knots[0] > 0.0:  # its first value held from 0
        first = np.array([[coef[0, 0], 0.0, 0.0, 0.0]])
        return np.concatenate([[0.0], knots]), np.vstack([first, coef])
    if knots[-1] <= 0.0:  # over before the run starts: its last value
        c = coef[-1]
        tau = knots[-1] - knots[-2]
        last = c[0] + tau * (c[1] + tau * (c[2] + tau * c[3]))
        return np.array([0.0, 1.0]), np.array([[last, 0.0, 0.0, 0.0]])  # held past 1 s
    j = int(np.searchsorted(knots, 0.0, side="right")) - 1  # the piece that holds t = 0
    c0, c1, c2, c3 = coef[j]
    tau = -knots[j]  # 0 in the piece's own time
    shifted = [c0 + tau * (c1 + tau * (c2 + tau * c3)), c1 + tau * (2.0 * c2 + 3.0 * c3 * tau),
               c2 + 3.0 * c3 * tau, c3]
    return (np.concatenate([[0.0], knots[j + 1:]]),
            np.vstack([np.array([shifted]), coef[j + 1:]]))


def evaluate_repeating(knots, coef, period: float, t):
    """Value and slope of the pieces at the times ``t``, the last ``period`` seconds
    repeated after the last knot (as the engine evaluates a channel)."""
    t = np.array(t, dtype=float, ndmin=1)
    last = knots[-1]
    if period > 0.0:
        late = t >= last
        t[late] -= (np.floor((t[late] - last) / period) + 1.0) * period
        t[late] = np.maximum(t[late], last - period)
    k = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(coef) - 1)
    tau = np.clip(t, knots[0], last) - knots[k]
    c = coef[k]
    value = c[:, 0] + tau * (c[:, 1] + tau * (c[:, 2] + tau * c[:, 3]))
    slope = c[:, 1] + tau * (2 * c[:, 2] + 3 * c[:, 3] * tau)
    return value, np.where((t >= knots[0]) & (t <= last), slope, 0.0)


def spline_pieces(t, y) -> Pieces:
    """The not-a-knot cubic spline through ``(t, y)`` (``t`` strictly increasing, two
    points or more), as the engine's pieces: the curve `scipy.interpolate.CubicSpline`
    draws with its default ends, to rounding.

    It is built here from its slopes, solved by the engine's tridiagonal solver
    (Gaussian elimination with partial pivoting, `vsj_solve_tridiagonal`), because
    importing ``scipy.interpolate`` or ``scipy.linalg`` would cost a short run more than
    its whole simulation. The slopes ``m`` make the first and second derivatives
    continuous at inner knots; at each end the third derivative is continuous across
    the first inner knot. Three points give one parabola and two a line.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    h = np.diff(t)
    secant = np.diff(y) / h
    if len(t) == 2:
        m = np.array([secant[0], secant[0]])
    elif len(t) == 3:
        middle = (h[1] * secant[0] + h[0] * secant[1]) / (h[0] + h[1])
        m = np.array([2.0 * secant[0] - middle, middle, 2.0 * secant[1] - middle])
    else:
        # the tridiagonal system of the slopes: inner rows from the continuity of the
        # second derivative, end rows from the not-a-knot conditions
        n = len(t)
        lower, diagonal, upper, m = np.empty(n - 1), np.empty(n), np.empty(n - 1), np.empty(n)
        diagonal[1:-1] = 2.0 * (h[:-1] + h[1:])
        upper[1:] = h[:-1]
        lower[:-1] = h[1:]
        m[1:-1] = 3.0 * (h[1:] * secant[:-1] + h[:-1] * secant[1:])
        first, last = h[0] + h[1], h[-1] + h[-2]
        diagonal[0], upper[0] = h[1], first
        m[0] = ((h[0] + 2.0 * first) * h[1] * secant[0] + h[0] ** 2 * secant[1]) / first
        diagonal[-1], lower[-1] = h[-2], last
        m[-1] = (h[-1] ** 2 * secant[-2] + (2.0 * last + h[-1]) * h[-2] * secant[-1]) / last
        if _core.solve_tridiagonal(lower, diagonal, upper, m) != 0:
            raise InputError("spline knots too close together: the slopes' system is singular")
    curvature = (m[:-1] + m[1:] - 2.0 * secant) / h
    coef = np.column_stack([y[:-1], m[:-1], (secant - m[:-1]) / h - curvature, curvature / h])
    return t, coef


def evaluate(pieces: Pieces, t):
    """The piecewise cubic ``pieces`` at times ``t`` (each piece extended past its
    interval at the ends)."""
    knots, coef = pieces
    t = np.asarray(t, dtype=float)
    i = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(coef) - 1)
    tau = t - knots[i]
    c = coef[i]
    return c[..., 0] + tau * (c[..., 1] + tau * (c[..., 2] + tau * c[..., 3]))


def _intervals(t_end: float, step: float) -> int:
    """Sampling intervals of ``step`` over ``[0, t_end]``, refused above `MAX_KNOTS`."""
    n = t_end / step if step > 0.0 else math.inf
    if not n <= MAX_KNOTS:
        raise InputError(f"sampling every {step:.3g} s over {t_end:.6g} s needs {n:.3g} spline "
                         f"knots, {n * BYTES_PER_KNOT / 1e9:.3g} GB; at most {MAX_KNOTS:.3g} "
                         f"({MAX_KNOTS * BYTES_PER_KNOT / 1e9:.2g} GB) are allowed: shorten the "
                         "duration or slow the signal")
    return max(int(math.ceil(n)), 4)


def _sampled(fun, t_end: float, step: float) -> Pieces:
    n = _intervals(t_end, step)
    t = np.linspace(0.0, max(t_end, 1e-9), n + 1)
    return spline_pieces(t, fun(t))


@dataclass(frozen=True)
class Constant(Input):
    """A constant value."""

    level: float = 0.0

    def __post_init__(self):
        _real_fields(self, "constant", ("level",))
        if not math.isfinite(self.level):
            raise InputError(f"constant input: value must be finite, got {self.level!r}")

    def value(self, t):
        """``level`` at every time of ``t`` [s], shaped as ``t``."""
        return np.full_like(np.asarray(t, dtype=float), self.level)

    def pieces(self, t_end: float) -> Pieces:
        """One constant piece over ``[0, t_end]`` [s] (at least 1 ns long)."""
        return np.array([0.0, max(t_end, 1e-9)]), np.array([[self.level, 0.0, 0.0, 0.0]])

    def knots(self, t_end: float) -> int:
        """Always 2: a constant is one piece."""
        return 2

    def describe(self) -> str:
        """The signal in one line of words."""
        return f"constant {self.level:g}"


@dataclass(frozen=True)
class Sine(Input):
    """``offset + amplitude * envelope(t) * sin(2 pi f (t - start) + phase)`` from
    ``start`` until ``stop``.

    Outside ``[start, stop)`` only ``offset`` remains (``stop`` defaults to
    never). ``fade_in`` [s] raises the envelope smoothly (a quintic
    smoothstep) from 0 to 1, so a velocity source can start from rest without a
    jump in speed or acceleration.
    """

    amplitude: float
    frequency: float
    phase: float = 0.0
    offset: float = 0.0
    start: float = 0.0
    fade_in: float = 0.0
    stop: float = math.inf

    def __post_init__(self):
        _real_fields(self, "sine", ("amplitude", "frequency", "phase", "offset", "start",
                                    "fade_in", "stop"))
        for name in ("amplitude", "phase", "offset", "start"):
            if not math.isfinite(getattr(self, name)):
                raise InputError(f"sine input: {name} must be finite, got "
                                 f"{getattr(self, name)!r}")
        if not (math.isfinite(self.frequency) and self.frequency > 0.0):
            raise InputError(f"sine input: frequency must be > 0 Hz, got {self.frequency!r}")
        if not (math.isfinite(self.fade_in) and self.fade_in >= 0.0):
            raise InputError(f"sine input: fade_in must be >= 0 s, got {self.fade_in!r}")
        if math.isnan(self.stop) or not self.stop > self.start:
            raise InputError(f"sine input: stop must be after start ({self.start!r} s), got "
                             f"{self.stop!r}")

    def _wave(self, t):
        """The sine from ``start`` on, ignoring ``stop``."""
        tau = np.asarray(t, dtype=float) - self.start
        env = np.ones_like(tau)
        if self.fade_in > 0.0:
            z = np.clip(tau / self.fade_in, 0.0, 1.0)
            env = z ** 3 * (10.0 - 15.0 * z + 6.0 * z * z)
        return self.offset + self.amplitude * env * np.sin(2 * np.pi * self.frequency * tau
                                                           + self.phase)

    def value(self, t):
        """The signal's value at the times ``t`` [s] (scalar or array), in the unit of the
        channel it drives (rad/s, N m or V). ``offset`` outside ``[start, stop)``."""
        t = np.asarray(t, dtype=float)
        return np.where((t >= self.start) & (t < self.stop), self._wave(t), self.offset)

    def _step(self) -> float:
        step = 1.0 / (400.0 * self.frequency)
        return min(step, self.fade_in / 100.0) if self.fade_in > 0.0 else step

    def _segments(self, t_end: float) -> list[tuple[float, float, bool]]:
        """(from, to, waving) over ``[0, t_end]``: the onset and the stop on knots, so
        that the spline does not smear them."""
        on, off = max(self.start, 0.0), min(self.stop, t_end)
        if not on < off:
            return [(0.0, t_end, False)]
        segments = [(0.0, on, False)] if on > 0.0 else []
        segments.append((on, off, True))
        if off < t_end:
            segments.append((off, t_end, False))
        return segments

    def _periodic_grid(self) -> tuple[float, int] | None:
        """For a sine that never stops: the step that divides its period (its knots from
        its onset on), and the number of steps from the onset until the fade-in ends
        (rounded up), after which the sine repeats."""
        if math.isfinite(self.stop):
            return None
        step = 1.0 / (self.frequency * max(4, math.ceil(1.0 / (self.frequency * self._step()))))
        on = max(self.start, 0.0)
        return step, math.ceil(max(self.start + self.fade_in - on, 0.0) / step - 1e-9)

    def repeats(self) -> tuple[float, float] | None:
        """``(t0, period)`` [s] for a sine that never stops: it repeats from the end of its
        fade-in (rounded up to a knot) with period ``1 / frequency``; None for one that
        stops."""
        grid = self._periodic_grid()
        if grid is None:
            return None
        step, fade_steps = grid
        return max(self.start, 0.0) + fade_steps * step, 1.0 / self.frequency

    def pieces(self, t_end: float) -> Pieces:
        """Knots [s] and cubic coefficients covering ``[0, t_end]``: the sine splined on a
        grid fine enough for its frequency and fade-in, with knots at its start and stop
        and on the period's grid when it repeats."""
        knots, coefs = [], []
        grid = self._periodic_grid()
        for a, b, waving in self._segments(t_end):
            if waving and grid is not None:
                step = grid[0]  # knots on the period's grid, so that a period starts on one
                n = max(4, math.ceil((b - a) / step - 1e-9))
                _intervals(n * step, step)
                k = a + np.arange(n + 1) * step
                k, c = spline_pieces(k, self._wave(k))
            elif waving:
                k, c = _sampled(lambda t, a=a: self._wave(t + a), b - a, self._step())
                k = k + a
            else:
                k, c = np.array([a, max(b, a + 1e-9)]), np.array([[self.offset, 0, 0, 0]])
            knots.append(k if not knots else k[1:])
            coefs.append(c)
        return np.concatenate(knots), np.vstack(coefs).astype(float)

    def knots(self, t_end: float) -> int:
        """Number of knots `pieces` makes for ``[0, t_end]`` [s], counted without making
        them. `InputError` if more than `MAX_KNOTS` would be needed."""
        return 1 + sum(_intervals(b - a, self._step()) if waving else 1
                       for a, b, waving in self._segments(t_end))

    def describe(self) -> str:
        """The signal in one line of words."""
        until = f", stop {self.stop:g} s" if math.isfinite(self.stop) else ""
        return (f"sine amplitude {self.amplitude:g}, {self.frequency:g} Hz, phase "
                f"{self.phase:g} rad, offset {self.offset:g}, start {self.start:g} s{until}, "
                f"fade-in {self.fade_in:g} s")


@dataclass(frozen=True)
class Step(Input):
    """``offset`` before ``start``, ``offset + height`` from then on (as Modelica's
    ``Blocks.Sources.Step``): a clutch or brake engaged or released at an instant."""

    height: float = 1.0
    start: float = 0.0
    offset: float = 0.0

    def __post_init__(self):
        _real_fields(self, "step", ("height", "start", "offset"))
        for name in ("height", "start", "offset"):
            if not math.isfinite(getattr(self, name)):
                raise InputError(f"step input: {name} must be finite, got "
                                 f"{getattr(self, name)!r}")

    def value(self, t):
        """``offset`` before ``start`` [s], ``offset + height`` from then on, at the times
        ``t`` [s]."""
        t = np.asarray(t, dtype=float)
        return np.where(t >= self.start, self.offset + self.height, self.offset)

    def pieces(self, t_end: float) -> Pieces:
        """Knots [s] and coefficients covering ``[0, t_end]``: two constant pieces with a
        knot at ``start``, or one if the step lies outside ``(0, t_end)``."""
        if 0.0 < self.start < t_end:
            return (np.array([0.0, self.start, t_end]),
                    np.array([[self.offset, 0, 0, 0], [self.offset + self.height, 0, 0, 0]],
                             dtype=float))
        level = self.offset + (self.height if self.start <= 0.0 else 0.0)
        return Constant(level).pieces(t_end)

    def knots(self, t_end: float) -> int:
        """3 if the step falls inside ``(0, t_end)`` [s], else 2."""
        return 3 if 0.0 < self.start < t_end else 2

    def describe(self) -> str:
        """The signal in one line of words."""
        return f"step of {self.height:g} at {self.start:g} s from {self.offset:g}"


def _real_fields(signal, kind: str, names) -> None:
    """`InputError` naming the field unless each of ``names`` of ``signal`` is a real
    number (a string such as "1 rad", or True, is not: units belong to scenario files)."""
    for name in names:
        value = getattr(signal, name)
        if not is_number(value):
            raise InputError(f"{kind} input: {name} must be a number (SI units), got "
                             f"{value!r}")


def _own_series(signal, kind: str, shortest: int) -> None:
    """Check ``signal``'s times and values (`_check_series`) and keep them as tuples: a
    list or array the caller changes later must not change the signal it validated (and
    a signal of tuples compares and hashes as a value)."""
    _check_series(kind, signal.times, signal.values, shortest)
    for name in ("times", "values"):
        given = getattr(signal, name)
        if not isinstance(given, tuple):
            object.__setattr__(signal, name, tuple(np.asarray(given, dtype=float).tolist()))


def _check_series(kind: str, times, values, shortest: int) -> None:
    """`InputError` unless ``times`` and ``values`` are finite lists of one length (at
    least ``shortest``) with strictly increasing times."""
    t = np.asarray(times, dtype=float)
    v = np.asarray(values, dtype=float)
    if t.ndim != 1 or t.shape != v.shape or t.size < shortest:
        raise InputError(f"{kind} input: times and values must be two lists of the same "
                         f"length >= {shortest} (got {t.size} and {v.size})")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
        raise InputError(f"{kind} input: times and values must be finite numbers")
    if np.any(np.diff(t) <= 0.0):
        i = int(np.flatnonzero(np.diff(t) <= 0.0)[0])
        raise InputError(f"{kind} input: times must increase strictly (entry {i + 1}: "
                         f"{t[i]} then {t[i + 1]})")


@dataclass(frozen=True)
class Table(Input):
    """Values at given times, interpolated linearly or with a cubic spline.

    Outside the table the first and last values are held.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]
    interpolation: str = "linear"

    def __post_init__(self):
        _own_series(self, "table", 2)
        if self.interpolation not in ("linear", "cubic"):
            raise InputError(f"table input: interpolation must be 'linear' or 'cubic', got "
                             f"{self.interpolation!r}")

    def value(self, t):
        """The table interpolated (linearly or by the cubic spline) at the times ``t`` [s],
        first and last values held outside it."""
        if self.interpolation == "linear":
            return np.interp(t, self.times, self.values)
        t = np.clip(np.asarray(t, dtype=float), self.times[0], self.times[-1])
        return evaluate(spline_pieces(self.times, self.values), t)

    def pieces(self, t_end: float) -> Pieces:
        """The table's own times as knots [s] with linear or not-a-knot cubic spline
        coefficients (``t_end`` is not used: the engine holds the ends)."""
        t = np.asarray(self.times, dtype=float)
        v = np.asarray(self.values, dtype=float)
        if self.interpolation == "cubic":
            knots, coef = spline_pieces(t, v)
        else:
            slope = np.diff(v) / np.diff(t)
            coef = np.column_stack([v[:-1], slope, np.zeros_like(slope), np.zeros_like(slope)])
            knots = t
        return knots, coef

    def knots(self, t_end: float) -> int:
        """Number of table points (independent of ``t_end``)."""
        return len(self.times)

    def describe(self) -> str:
        """The signal in one line of words."""
        return f"table of {len(self.times)} points ({self.interpolation})"


@dataclass(frozen=True)
class Hold(Input):
    """Values held from one time to the next (zero-order hold): what a digital
    controller applies, and what an FMU does with its inputs over a communication
    step.

    ``values[i]`` acts over ``(times[i], times[i + 1]]``: a step of the solver that
    ends at ``times[i + 1]`` still sees it, the step that starts there sees the next
    value. Before ``times[1]`` the first value, after the last time the last value.
    Driving a velocity source, a Hold changes its speed in jumps; the time-stepper
    gives the free flanges the matching impulse (their momentum is continuous), the
    adaptive solver does not: run a Hold on a velocity source with ``timestep``.

    The engine's spline is right-continuous at its knots, so each change sits
    `KNOT_OFFSET` of the shortest interval after its time; the integral (a source's
    angle) moves by that fraction of an interval times the jump.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]

    #: where a change sits after its time, as a fraction of the shortest interval
    KNOT_OFFSET = 1e-9

    def __post_init__(self):
        _own_series(self, "hold", 1)

    def value(self, t):
        """The held value at the times ``t`` [s]: ``values[i]`` over ``(times[i], times[i +
        1]]``."""
        t = np.asarray(t, dtype=float)
        index = np.searchsorted(np.asarray(self.times, dtype=float), t, side="left") - 1
        return np.asarray(self.values, dtype=float)[np.clip(index, 0, len(self.values) - 1)]

    def _offset(self) -> float:
        t = np.asarray(self.times, dtype=float)
        shortest = float(np.min(np.diff(t))) if t.size > 1 else 1.0
        # and far above the rounding of the solver's step times
        return max(self.KNOT_OFFSET * shortest, 64 * np.spacing(max(abs(t).max(), 1.0)))

    def pieces(self, t_end: float) -> Pieces:
        """Constant pieces, each change `KNOT_OFFSET` of the shortest interval after its
        time, the last one extended to ``t_end`` [s]."""
        t = np.asarray(self.times, dtype=float)
        v = np.asarray(self.values, dtype=float)
        delta = self._offset()
        start = min(0.0, float(t[0]))
        knots = np.concatenate([[start], t[1:] + delta])
        knots = np.append(knots, max(t_end, float(knots[-1]) + delta))
        coef = np.zeros((v.size, 4))
        coef[:, 0] = v
        return knots, coef

    def knots(self, t_end: float) -> int:
        """Number of knots `pieces` makes (one per value plus the end); `InputError` above
        `MAX_KNOTS`."""
        if len(self.times) + 1 > MAX_KNOTS:
            raise InputError(f"hold input: {len(self.times)} values; at most {MAX_KNOTS - 1} "
                             "are allowed")
        return len(self.times) + 1

    def describe(self) -> str:
        """The signal in one line of words."""
        return f"hold of {len(self.times)} values (zero-order)"


@dataclass(frozen=True)
class Position(Input):
    """Drive a velocity source by its angle: the speed is ``d angle / dt``."""

    angle: Input
    is_position = True

    def __post_init__(self):
        if not isinstance(self.angle, Input) or self.angle.is_position:
            raise InputError(f"position input: its angle must be a vsj.inputs signal of the "
                             f"angle [rad] (Sine, Table, ...; not a Position), got "
                             f"{self.angle!r}")

    def value(self, t):
        """The angle [rad] at the times ``t`` [s] (the wrapped signal's value)."""
        return self.angle.value(t)

    def initial_angle(self) -> float:
        """The angle [rad] at time zero: the velocity source's initial angle."""
        return float(self.angle.value(np.array([0.0]))[0])

    def pieces(self, t_end: float) -> Pieces:
        """The angle's spline differentiated: knots [s] and cubic coefficients of the speed
        [rad/s]."""
        knots, coef = self.angle.pieces(t_end)
        derivative = np.column_stack([coef[:, 1], 2 * coef[:, 2], 3 * coef[:, 3],
                                      np.zeros(len(coef))])
        return knots, derivative

    def knots(self, t_end: float) -> int:
        """Number of knots of the angle's spline over ``[0, t_end]`` [s]."""
        return self.angle.knots(t_end)

    def repeats(self) -> tuple[float, float] | None:
        """Whether the angle repeats, as `Input.repeats` (its derivative repeats with it).
        """
        return self.angle.repeats()

    def describe(self) -> str:
        """The signal in one line of words."""
        return f"angle given by {self.angle.describe()}"


def circle(radius: float, period: float, *, fade_in: float, cos_axis: bool) -> Input:
    """One coordinate of a circle of ``radius`` traversed with ``period`` [s].

    The radius grows smoothly over ``fade_in`` (a spiral out from the centre),
    so a motion started from rest has continuous speed and acceleration.
    ``cos_axis`` selects ``r cos`` (else ``r sin``). Returned as a `Position`.
    """
    if not (math.isfinite(radius) and math.isfinite(period) and period > 0.0):
        raise InputError(f"circle input: radius must be finite and period > 0 s, got radius "
                         f"{radius!r}, period {period!r}")
    if not (math.isfinite(fade_in) and fade_in >= 0.0):
        raise InputError(f"circle input: fade_in must be >= 0 s, got {fade_in!r}")
    omega = 2 * np.pi / period

    def angle(t):
        t = np.asarray(t, dtype=float)
        z = np.clip(t / fade_in, 0.0, 1.0) if fade_in > 0 else np.ones_like(t)
        env = z ** 3 * (10.0 - 15.0 * z + 6.0 * z * z)
        trig = np.cos if cos_axis else np.sin
        return radius * env * trig(omega * t)

    step = period / 400.0  # divides the period: the circle repeats after its fade-in
    return Position(_Sampled(angle, step, f"circle radius {radius:g}, period {period:g} s",
                             (math.ceil(fade_in / step - 1e-9) * step, period)))


@dataclass(frozen=True)
class _Sampled(Input):
    """A function of time splined at knots ``step`` apart from t = 0 (or, if it repeats
    with ``period`` from ``t0`` on, ``(t0, period)``, at knots of a step that divides
    the period)."""

    fun: object
    step: float
    label: str
    period: tuple[float, float] | None = None

    def value(self, t):
        return self.fun(np.asarray(t, dtype=float))

    def repeats(self) -> tuple[float, float] | None:
        return self.period

    def pieces(self, t_end: float) -> Pieces:
        if self.period is not None:
            n = max(4, math.ceil(t_end / self.step - 1e-9))
            _intervals(n * self.step, self.step)
            t = np.arange(n + 1) * self.step
            return spline_pieces(t, self.fun(t))
        return _sampled(self.fun, t_end, self.step)

    def knots(self, t_end: float) -> int:
        return 1 + _intervals(t_end, self.step)

    def describe(self) -> str:
        return self.label

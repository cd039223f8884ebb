"""The assembled wrist as a function of its free parameters, over windows of a log.

Output-error identification compares the model's outputs with measured ones.
This module turns logs and a choice of free parameters into that function:
``residuals(P)`` evaluates many parameter vectors at once (the rows of ``P``),
as one batch of the C engine's runs, and returns the noise-weighted
differences between simulated and measured signals.

**Windows.** A long log is cut into windows (default 5 s). Each starts from
the *measured* state at its start, so that a model error or noise does not
drift through the whole log: the measured angles (end-effector encoders,
motor encoders, pivot) and their slopes (a local parabola fitted over
`SLOPE_HALF_WIDTH`) fix every generalised coordinate they can; the ones they
cannot (a parasitic compliance's twist, a ring angle nobody measured) are set
quasi-statically, to the minimum of the springs' energy under the measured
ones, and their speeds by the same rule a moment later. That guess is not
the wrist's state: the twist it sets holds no friction torque, and the
slopes of noisy angles are noisy; the transient it starts dies out with the
wrist's slowest modes, over a few tenths of a second. The first `lead`
seconds of each window (default 0.5 s) are therefore simulated but not
compared. Consecutive windows overlap by ``lead``, so every sample after the
first lead is compared once; the last window takes in a remainder too short
for a window of its own. A signal recorded behind the inputs (see **Delays**)
is read that much later for the start state (`WristModel.set_state_delays`).

**Batch.** Each window has one compiled model (its inputs shifted to start at
zero), and each parameter set its mass matrix, inverse and element parameters,
compiled once; a run is that window's plan (`vsj.engine.plan.Plan`) retuned with
them and its quasi-static initial state. Every (window, parameter chunk) pair is
one call of `vsj.engine.plan.run_batch` on one thread, and a pool of threads runs
all of them (the C engine releases the GIL).

A free parameter may change what a retuned plan takes per run (inertias, every
friction level, spring stiffnesses, compliances that start nonzero, motor
constants, the elastic element's constants); one that changes the kinematic
rows (a gear ratio, a tooth count) or the topology (a compliance or damping
that is zero in the base set) is refused with a message that says so.

**Delays.** A recorder's channels need not be simultaneous: an end-effector
encoder read a fraction of a millisecond after the motor commands makes its
signal lead or lag the model's, and a fit that cannot shift it bends the
damping to explain the phase (on synthetic logs, a 0.2 ms offset moved the
viscous friction by seven standard errors). With ``Setup.delays`` each compared
signal therefore gets its own delay behind the inputs, a nuisance parameter of
the fit: the model's signal is read at ``t - delay`` (linear interpolation on
the simulation's grid), which needs no extra run, so a Jacobian column of a
delay costs no simulation. The start states, read from the same signals, are
read at the delays the fit has found so far (`WristModel.set_state_delays`,
updated between the fit's stages).

**Noisy inputs.** A measured external torque drives the model as if exact;
`perturbed_residuals` simulates what its noise does, for the covariance
(`vsj.identification.wrist`).

Outputs compared: angles and speeds of any named signal that moves with the
generalised coordinates (``theta_x``, ``theta_y``, ``phi_1``, ``motor_1``
with DC motors, ...), the pivot position ``q`` when it does, and DC motor
currents ``motor.<name>.current``. Signals fixed by the inputs alone (a motor
angle under a velocity source) carry no information and are left out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from .. import params as params_module
from ..engine import Engine, compile_model, core
from ..engine.model import Layout
from ..engine.plan import Plan, Scheme, run_batch
from ..errors import InputError
from ..inputs import Position, Table
from ..measurements import Measurement
from ..params import SCHEMA, Parameters
from ..wrist import WristOptions, build_wrist

#: Half-width [s] of the parabola fit that gives a measured angle and its slope at a
#: window's start: long enough to average encoder quantisation and noise over about 40
#: samples at 1 kHz, short against the wrist's motion (its fastest modes are near 10 Hz).
SLOPE_HALF_WIDTH = 0.02
#: An interval of more than this many sample periods (the median interval) is a gap in
#: a log: at least one sample is missing (a log's jitter moves a sample by less than
#: half a period).
GAP_PERIODS = 1.5
#: Width [s] of the smoothing of measured external torques: shorter than their edges
#: (a pulse of `vsj.identification.wrist_experiment` rises in 50 ms).
TORQUE_SMOOTHING = 0.015
#: Polynomial order of that smoothing (Savitzky-Golay): a quintic follows a pulse's edge
#: over the smoothing width where a cubic rounds it off, and the break-away of a stuck
#: joint, which the stiction levels are read from, happens on those edges.
SMOOTHING_ORDER = 5
#: Residual of a run that failed (per compared sample, in noise units): large against any
#: fit, finite so that the optimiser steps back.
FAILED_RESIDUAL = 1e3
#: A compared signal's noise is never taken below this fraction of its range: a signal
#: measured without noise would otherwise get an infinite weight.
NOISE_FLOOR = 1e-6
#: Relative tolerance (of the arrays' largest entry) of the affinity check of
#: `WristModel._affine`: round-off of the network's assembly, far below any step.
AFFINE_TOLERANCE = 1e-12
#: Parameters whose change moves the kinematic rows or the topology: not free.
_KINEMATIC = ("planetary.sun_teeth", "planetary.ring_teeth", "transmission.ratio",
              "motor.gear_ratio", "pivot.ratio", "pivot.amplitude", "pivot.q_min",
              "pivot.q_max", "elastic_element.end_stop", "motor.voltage_limit")


@dataclass(frozen=True)
class Setup:
    """What the fit compares, drives and frees, and its numerical knobs (SI).

    ``inputs``/``outputs``: log column names (None: every input channel found, and
    every measured signal that the model's states determine). ``window`` and
    ``lead`` [s]: window length and the part of each not compared; ``step`` [s]:
    the time-stepper's step with true stiction, ``smooth_step`` [s] with a smooth
    friction law (the stages that only find the basin: a coarser step costs less,
    and its discretisation error, which biases estimates by about a standard
    error at 1 ms against a 0.5 ms truth, does not reach the final fit); ``threads``:
    engine threads (None: every core); ``delays``: estimate each compared signal's
    delay behind the inputs (see `WristModel`); ``input_draws``: draws of the
    measured inputs' noise for the covariance (`WristModel.perturbed_residuals`; 0:
    none). The relative spread of a variance from ``K`` draws is about
    ``sqrt(2 / K)``: 32 draws give its standard error to about 12 %.
    """

    free: tuple[str, ...]
    wrist: WristOptions = field(default_factory=WristOptions)
    inputs: tuple[str, ...] | None = None
    outputs: tuple[str, ...] | None = None
    window: float = 5.0
    lead: float = 0.5
    step: float = 5e-4
    smooth_step: float = 1e-3
    slope_width: float = 0.01
    threads: int | None = None
    delays: bool = True
    input_draws: int = 32


def known_columns(structure) -> dict[str, str]:
    """Every column name a wrist log may hold, with its SI unit."""
    out = {}
    for s in structure.signals:
        out[s.name] = "rad"
        out[f"{s.name}.speed"] = "rad/s"
    out["q"], out["q.rate"] = "m", "m/s"
    for src in structure.sources:
        out[f"source.{src.name}.speed"] = "rad/s"
        out[f"source.{src.name}.torque"] = "N*m"
    for ld in structure.loads:
        out[ld.channel] = "N*m"
        out[f"load.{ld.name}.torque"] = "N*m"
    for m in structure.motors:
        out[m.channel] = "V"
        out[f"motor.{m.name}.voltage"] = "V"
        out[f"motor.{m.name}.current"] = "A"
    return out


def all_known_columns() -> dict[str, str]:
    """Columns of a wrist log under either motor model (for reading before choosing)."""
    base = params_module.default()
    out = {}
    for motors in ("velocity", "dc"):
        out.update(known_columns(build_wrist(base, WristOptions(motors=motors)).assemble()))
    return out


def _signals_of(structure, flange: str) -> list[str]:
    """Named signals that move exactly as ``flange`` (rigidly connected to it)."""
    rx, ru = structure.rows(flange)
    out = []
    for s in structure.signals:
        sx, su = structure.rows(s.flange)
        if np.array_equal(sx, rx) and np.array_equal(su, ru):
            out.append(s.name)
    return out


def _input_columns(structure, channel: str) -> list[tuple[str, str]]:
    """Log columns that can drive ``channel``: (column, how) in order of preference;
    how is ``value`` (the channel's own quantity) or ``angle`` (a velocity source
    driven by its measured angle)."""
    for src in structure.sources:
        if src.channel == channel:
            names = _signals_of(structure, src.flange)
            return ([(f"{n}.speed", "value") for n in names]
                    + [(f"source.{src.name}.speed", "value")]
                    + [(n, "angle") for n in names])
    for ld in structure.loads:
        if ld.channel == channel:
            return [(channel, "value"), (f"load.{ld.name}.torque", "value")]
    for m in structure.motors:
        if m.channel == channel:
            return [(channel, "value"), (f"motor.{m.name}.voltage", "value")]
    return []


@dataclass
class Output:
    """A compared signal: how to get it from the states of a batch."""

    name: str
    kind: str            # angle, speed, q, current
    rx: np.ndarray | None = None
    ru: np.ndarray | None = None
    index: int = 0       # state column of a current


@dataclass
class Window:
    """One stretch of one log, simulated from its measured start."""

    log: int
    start: float                   # s, absolute time of the log
    duration: float
    samples: np.ndarray            # indices into the log of the compared samples
    offsets: np.ndarray            # their times from the window's start [s]
    engines: dict = field(default_factory=dict)   # law -> Engine
    sigma0: np.ndarray | None = None
    x0: np.ndarray | None = None
    v0: np.ndarray | None = None
    null: np.ndarray | None = None  # basis of the unmeasured position directions
    later: tuple | None = None      # (dt, x0, sigma) a moment later, for null-space speeds
    currents: np.ndarray | None = None
    grids: dict = field(default_factory=dict)  # step -> (t_out, source angles, speeds)
    quasi_static: dict = field(default_factory=dict)  # spring parameters -> (x0, v0)


def _added_to_tables(model, span, channels, extra: Mapping[str, np.ndarray]):
    """An engine model whose linear-table inputs ``channels`` ((index among the
    network's channels, log column)) have ``extra[column]`` (over the whole log) added,
    sampled as `WristModel._inputs` samples the column (``span``: its ``i0, i1``, the
    window's start and the log's times). The input bank (`vsj.engine.model.input_bank`) holds, per
    channel in order, ``count + 1`` knots and running integrals and ``count`` pieces
    ``(value, slope, 0, 0)``: only this channel's are changed, not rebuilt."""
    knots, coef, cum = model.knots.copy(), model.coef.copy(), model.cum.copy()
    i0, i1, start, times = span
    for index, column in channels:
        first, count = int(model.first[index]), int(model.count[index])
        at = first + index  # each earlier channel has one knot more than pieces
        k = knots[at:at + count + 1]
        add = extra[column]
        delta = np.concatenate([[np.interp(start, times, add)], add[i0:i1]])
        if len(delta) != count + 1:
            raise ValueError(f"input {column}: {len(delta)} values for {count} pieces")
        dt = np.diff(k)
        coef[first:first + count, 0] += delta[:-1]
        coef[first:first + count, 1] += np.diff(delta) / dt
        cum[at + 1:at + count + 1] += np.cumsum(0.5 * (delta[:-1] + delta[1:]) * dt)
    return model._replace(knots=knots, coef=coef, cum=cum)


def gap_indices(t: np.ndarray) -> np.ndarray:
    """Indices k of a log's gaps: samples k and k + 1 are more than `GAP_PERIODS`
    sample periods (the median interval) apart."""
    dt = np.diff(t)
    return np.flatnonzero(dt > GAP_PERIODS * float(np.median(dt))) if dt.size else dt.astype(int)


def _smoothing_points(t: np.ndarray) -> int:
    """Odd number of samples that span `TORQUE_SMOOTHING` at the log's median period."""
    return int(TORQUE_SMOOTHING / float(np.median(np.diff(t)))) | 1


def with_values(params: Parameters, values: Mapping[str, float]) -> Parameters:
    """``params`` with SI ``values`` replaced (no text round trip: the fit's inner loop)."""
    merged = dict(params.values)
    merged.update(values)
    return replace(params, values=merged)


def check_free(names: Sequence[str], params: Parameters) -> None:
    """`InputError` unless every name is a parameter that may be free."""
    if not names:
        raise InputError("--free: name at least one parameter to identify")
    seen = set()
    for name in names:
        if name in seen:
            raise InputError(f"--free {name}: named twice")
        seen.add(name)
        if name not in params.values:
            hint = params_module.did_you_mean(name, params.values)
            sections = ", ".join(SCHEMA)
            raise InputError(f"--free {name}: no such parameter{hint} (write section.key as "
                             f"in the parameter file; sections: {sections})")
        if name in _KINEMATIC:
            raise InputError(f"--free {name}: it changes the kinematics of the network (a "
                             "ratio, the pivot's reach or an end stop), which one batch of "
                             "the engine cannot vary; fix it from its bench test")
        if name.startswith("friction."):
            continue
        if params[name] == 0.0 and (name.startswith("transmission.series_")):
            raise InputError(f"--free {name}: it is 0 in {params.origin}, which makes the "
                             "element rigid (another topology); start it from a nonzero value "
                             "in --params")


class WristModel:
    """Logs, free parameters and windows: ``residuals(values)`` for many parameter sets.

    ``values`` are rows of SI values of ``setup.free``. `noise` (per compared
    signal, SI) weights the residuals; `set_noise` changes it.
    """

    def __init__(self, logs: Sequence[Measurement], params: Parameters, setup: Setup):
        if not logs:
            raise InputError("no log to fit")
        check_free(setup.free, params)
        coarse, fine = max(setup.step, setup.smooth_step), min(setup.step, setup.smooth_step)
        if not (fine > 0 and abs(coarse / fine - round(coarse / fine)) < 1e-9):
            raise InputError(f"steps {setup.step:g} s (true stiction) and {setup.smooth_step:g}"
                             " s (smooth law): each must be > 0 and the larger a whole "
                             "multiple of the smaller")
        self.logs = list(logs)
        self.params = params
        self.setup = setup
        wrist = setup.wrist
        if wrist.pivot_drive != "fixed" and not any(
                c in self.logs[0].columns for c, _ in _input_columns(
                    build_wrist(params, wrist).assemble(), "motor_s")):
            q = self.logs[0].columns.get("q")
            if q is None:
                raise InputError(f"{self.logs[0].path}: no column drives the pivot motor "
                                 "(motor_s.speed or motor_s) and no q column to hold it at")
            spread = float(np.ptp(q))
            if spread > 1e-3:
                raise InputError(f"{self.logs[0].path}: q moves by {spread * 1e3:.3g} mm but "
                                 "no column drives the pivot motor (motor_s.speed or motor_s)")
            wrist = replace(wrist, pivot_drive="fixed", fixed_q=float(np.median(q)))
        self.wrist = wrist
        self.structure = build_wrist(params, wrist).assemble()
        self.known = known_columns(self.structure)
        for log in self.logs:
            unknown = [c for c in log.columns if c != "time" and c not in self.known]
            if unknown:
                raise InputError(f"{log.path}: column {unknown[0]!r} is neither an input nor "
                                 f"a signal of the wrist with {wrist.motors} motors")
        self.channels = self._channels()
        self.outputs = self._outputs()
        self.names = list(setup.free)
        self.base = np.array([params[n] for n in self.names])
        self.delay_names = ([f"delay.{o.name}" for o in self.outputs] if setup.delays
                            else [])
        self.n_state = 2 * self.structure.n + len(self.structure.motors)
        #: Per compared signal, how late [s] its samples are read for a window's start
        #: state (`set_state_delays`).
        self.state_delays = np.zeros(len(self.outputs))
        #: Gaps in the logs' sampling, one message each (`segments`).
        self.gaps: list[str] = []
        self.windows = [w for i in range(len(self.logs)) for w in self._windows(i)]
        if not self.windows:
            raise InputError(f"{self.logs[0].path}: too short for a window of "
                             f"{setup.lead:g} s lead and compared samples")
        self.noise = {o.name: self.estimate_noise(o.name) for o in self.outputs}
        self.runs = 0             # window runs done
        self.simulated = 0.0      # seconds of log simulated
        self._compiled: dict[tuple, tuple] = {}
        self._base_model = None

    # -- set-up ---------------------------------------------------------------------

    def _channels(self) -> dict[str, tuple[str, str]]:
        """Input channel -> (column, how), checked against ``setup.inputs``."""
        log = self.logs[0]
        wanted = self.setup.inputs
        out = {}
        for channel in self.structure.channels():
            choice = None
            for column, how in _input_columns(self.structure, channel):
                if all(column in lg.columns for lg in self.logs) and (
                        wanted is None or column in wanted):
                    choice = (column, how)
                    break
            if choice is None:
                if channel.startswith("tau_"):
                    continue  # no external torque logged: none applied
                if channel == "motor_s" and self.structure.pivot.flange is None:
                    continue
                options = ", ".join(c for c, _ in _input_columns(self.structure, channel))
                raise InputError(f"{log.path}: no column drives input {channel!r} (one of "
                                 f"{options}{' among --inputs' if wanted else ''})")
            out[channel] = choice
        if wanted is not None:
            used = {c for c, _ in out.values()}
            extra = [c for c in wanted if c not in used]
            if extra:
                raise InputError(f"--inputs {extra[0]}: not an input channel of the wrist with "
                                 f"{self.wrist.motors} motors, or not in every log")
        return out

    def _outputs(self) -> list[Output]:
        st = self.structure
        n = st.n
        inputs = {c for c, _ in self.channels.values()}
        candidates = []
        for s in st.signals:
            rx, ru = st.rows(s.flange)
            candidates.append(Output(s.name, "angle", rx, ru))
            candidates.append(Output(f"{s.name}.speed", "speed", rx, ru))
        if st.pivot.flange is not None:
            rx, ru = st.rows(st.pivot.flange)
            candidates.append(Output("q", "q", rx, ru))
        for j, m in enumerate(st.motors):
            candidates.append(Output(f"motor.{m.name}.current", "current", index=2 * n + j))
        by_name = {o.name: o for o in candidates}
        wanted = self.setup.outputs
        if wanted is not None:
            out = []
            for name in wanted:
                if name not in by_name:
                    raise InputError(f"--outputs {name}: not a signal the wrist's states "
                                     f"determine; those are {', '.join(by_name)}")
                if name in inputs:
                    raise InputError(f"--outputs {name}: it drives the model (an input)")
                for log in self.logs:
                    if name not in log.columns:
                        raise InputError(f"--outputs {name}: {log.path} has no such column")
                o = by_name[name]
                if o.kind != "current" and not np.any(o.rx):
                    raise InputError(f"--outputs {name}: the inputs alone fix it; it tells "
                                     "nothing about the parameters")
                out.append(o)
            return out
        out = [o for o in candidates if o.name not in inputs
               and all(o.name in lg.columns for lg in self.logs)
               and (o.kind == "current" or np.any(o.rx))]
        if not out:
            raise InputError(f"{self.logs[0].path}: no measured signal that the model's "
                             "states determine (theta_x, theta_y, motor currents, ...)")
        return out

    def segments(self, i: int) -> list[tuple[float, float]]:
        """The stretches of log ``i`` sampled without a gap: an interval of more than
        `GAP_PERIODS` sample periods (the median interval) means samples are missing (a
        logger's dropout), and no window may run its inputs across them. Each gap is
        noted in `gaps` with the file's line."""
        log = self.logs[i]
        t = log["time"]
        dt = np.diff(t)
        gaps = gap_indices(t)
        bounds = [float(t[0])] + [x for k in gaps for x in (float(t[k]), float(t[k + 1]))] \
            + [float(t[-1])]
        for k in gaps:
            line = f", line {log.lines[k + 1]}" if log.lines is not None else ""
            self.gaps.append(f"{log.path}{line}: no samples for {dt[k]:.4g} s (from "
                             f"t = {t[k]:.6g} s to {t[k + 1]:.6g} s, {dt[k] / np.median(dt):.3g} "
                             f"sample periods); the stretches either side are fitted apart")
        return list(zip(bounds[0::2], bounds[1::2]))

    def _windows(self, i: int) -> list[Window]:
        # windows last a whole number of either step
        W, lead, h = self.setup.window, self.setup.lead, max(self.setup.step,
                                                              self.setup.smooth_step)
        if not (W > lead + 10 * h):
            raise InputError(f"window {W:g} s must exceed lead {lead:g} s by 10 steps")
        return [w for first, last in self.segments(i)
                for w in self._segment_windows(i, first, last, W, lead, h)]

    def _segment_windows(self, i: int, first: float, last: float, W: float, lead: float,
                         h: float) -> list[Window]:
        t = self.logs[i]["time"]
        out = []
        start = first + SLOPE_HALF_WIDTH
        end = last - SLOPE_HALF_WIDTH
        while start + lead + 10 * h <= end:
            # the last window takes in a remainder shorter than half a window's compared
            # part: a short window alone would be mostly the transient after its start
            duration = end - start if end - start < W + 0.5 * (W - lead) else W
            if duration < lead + 10 * h:
                break
            n_out = math.floor(duration / h + 1e-9) + 1
            duration = (n_out - 1) * h
            samples = np.flatnonzero((t >= start + lead) & (t <= start + duration))
            if samples.size:
                out.append(Window(i, start, duration, samples, t[samples] - start))
            start += duration - lead
        return out

    def estimate_noise(self, name: str) -> float:
        """Noise [SI] of a compared signal from the data alone: the spread of its second
        differences (white noise of sd s gives sd s sqrt(6); the signal's own curvature
        at the sampling rate is far smaller), robustly (median absolute deviation), and
        never below a quantisation step's rms (step / sqrt 12) or `NOISE_FLOOR`."""
        values = np.concatenate([lg[name] for lg in self.logs])
        d2 = np.diff(values, 2)
        mad = 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)
        steps = np.abs(np.diff(values))
        steps = steps[steps > 0]
        quantum = float(np.min(steps)) / math.sqrt(12.0) if steps.size else 0.0
        return max(mad, quantum, NOISE_FLOOR * max(float(np.ptp(values)), 1e-12))

    def set_noise(self, noise: Mapping[str, float]) -> None:
        """Replace the noise level of each output (its unit, by output name) that weights
        the residuals."""
        self.noise = dict(noise)

    # -- engines and initial states ---------------------------------------------------

    @staticmethod
    def _span(log: Measurement, start: float, duration: float) -> tuple[int, int]:
        """Samples ``i0:i1`` of the log that a window's input tables take, after the
        value interpolated at its start."""
        t = log["time"]
        return (int(np.searchsorted(t, start, side="right")),
                min(int(np.searchsorted(t, start + duration)) + 2, len(t)))

    def _table_times(self, w: Window):
        """``(i0, i1, start, log times)`` of a window's input tables (see `_inputs`)."""
        log = self.logs[w.log]
        return (*self._span(log, w.start, w.duration), w.start, log["time"])

    def _inputs(self, log: Measurement, start: float, duration: float):
        # the tables start at the window's start: a source's angle is the integral of its
        # speed from the first knot, which must be the window's time zero
        t = log["time"]
        i0, i1 = self._span(log, start, duration)
        tau = (0.0,) + tuple(t[i0:i1] - start)
        out = {}
        for channel, (column, how) in self.channels.items():
            data = self._smoothed(log, column) if channel.startswith("tau_") else log[column]
            values = (float(np.interp(start, t, data)),) + tuple(data[i0:i1])
            table = Table(tau, values)
            out[channel] = Position(table) if how == "angle" else table
        return out

    def noisy_inputs(self) -> dict[str, float]:
        """Input columns that are measurements with noise, which the model takes as
        exact: the external torques (`_smoothed`), with their noise [SI] estimated from
        the data as a compared signal's is (`estimate_noise`); those without noise
        (a torque computed, not measured) are left out."""
        out = {}
        for channel, (column, _) in self.channels.items():
            if channel.startswith("tau_"):
                sd = self.estimate_noise(column)
                span = max(float(np.ptp(np.concatenate([lg[column] for lg in self.logs]))),
                           1e-300)
                if sd > NOISE_FLOOR * span:
                    out[column] = sd
        return out

    def perturbed_residuals(self, values: np.ndarray, law: str, draws: int, seed: int = 0,
                            noise: Mapping[str, float] | None = None
                            ) -> tuple[np.ndarray, np.ndarray]:
        """Residuals (draws, compared values) of one parameter set (free parameters,
        then delays) when each noisy input column gets fresh white noise of its own
        level, smoothed as the column is; and which draws ran. ``noise``: the levels
        [SI] by column, where they are known (an experiment's design); by default
        `noisy_inputs` estimates them from the logs.

        What these residuals differ by from `residuals` at the same parameters is what
        the inputs' noise does to the simulated signals: the model, fed a measured
        torque, follows its noise where the wrist did not (with stiction, a slip a
        noise excursion starts or stops early), an error the compared signals'
        noise does not describe. The start states and the compared samples are the
        log's own."""
        # lazy: heavy; only logs with a measured torque input are smoothed
        from scipy.signal import savgol_filter

        values = np.asarray(values, dtype=float).reshape(-1)
        n_phys = len(self.names)
        noisy = self.noisy_inputs() if noise is None else dict(noise)
        rng = np.random.default_rng(seed)
        extras = []
        for _ in range(draws):
            per_log = []
            for log in self.logs:
                t = log["time"]
                n = _smoothing_points(t)
                extra = {}
                for column, sd in noisy.items():
                    e = rng.normal(0.0, sd, len(t))
                    extra[column] = savgol_filter(e, n, SMOOTHING_ORDER) if \
                        SMOOTHING_ORDER + 2 <= n < len(t) else e
                per_log.append(extra)
            extras.append(per_log)
        for k in range(len(self.windows)):
            if law not in self.windows[k].engines:
                self._prepare(self.windows[k], law)
        mass, Minv, par = self._compiled_for(values[:n_phys], law)
        delays = np.zeros((1, len(self.outputs)))
        if len(values) > n_phys:
            delays[0] = values[n_phys:]
        h = self.step_of(law)
        wts = self.weights()[:, None]
        out = np.empty((draws, self.compared))
        ok = np.ones(draws, dtype=bool)
        offsets = np.cumsum([0] + [len(w.samples) * len(self.outputs) for w in self.windows])

        channels = self.structure.channels()
        noisy_channels = [(channels.index(ch), col) for ch, (col, _) in self.channels.items()
                          if col in noisy]

        def work(task):
            d, k = task
            w = self.windows[k]
            noisy = _added_to_tables(w.engines[law].model, self._table_times(w),
                                     noisy_channels, extras[d][w.log])
            # the window's plan retuned (its checked model shares all but these arrays)
            plan = self._window_plan(k, law, h).retuned(
                y0=self._initial(w, law, mass, Minv, par), mass=mass, Minv=Minv, par=par,
                knots=noisy.knots, coef=noisy.coef, cum=noisy.cum)
            batch = run_batch([plan], w.grids[h][0], threads=1)
            sim = self._sample(w, self._signals(w, batch.states, h), delays, h)[0]
            r = ((sim - self.measured(k)) * wts).reshape(-1)
            return d, k, r, bool(batch.status[0] == core.OK)

        tasks = [(d, k) for d in range(draws) for k in range(len(self.windows))]
        threads = max(1, self.setup.threads or core.available_cores())
        if threads == 1 or len(tasks) == 1:
            done = [work(t) for t in tasks]
        else:
            with ThreadPoolExecutor(max_workers=threads) as pool:
                done = list(pool.map(work, tasks))
        for d, k, r, good in done:
            out[d, offsets[k]:offsets[k + 1]] = r
            ok[d] &= good
        self.runs += len(tasks)
        self.simulated += draws * sum(w.duration for w in self.windows)
        out[~ok] = FAILED_RESIDUAL
        return out, ok

    def _smoothed(self, log: Measurement, column: str) -> np.ndarray:
        """A measured external torque, its sensor noise smoothed (Savitzky-Golay of order
        `SMOOTHING_ORDER` over `TORQUE_SMOOTHING`): output error assumes exact inputs,
        and white torque noise fed to the model moves it where the real wrist was not
        moved. The noise within the wrist's own band stays; `perturbed_residuals`
        measures what it does."""
        # lazy: heavy; only logs with a measured torque input are smoothed
        from scipy.signal import savgol_filter

        key = (id(log), column)
        cache = self.__dict__.setdefault("_smooth_cache", {})
        if key not in cache:
            n = _smoothing_points(log["time"])
            cache[key] = (savgol_filter(log[column], n, SMOOTHING_ORDER)
                          if SMOOTHING_ORDER + 2 <= n < len(log["time"]) else log[column])
        return cache[key]

    def _prepare(self, w: Window, law: str) -> None:
        log = self.logs[w.log]
        inputs = self._inputs(log, w.start, w.duration)
        model, _ = compile_model(self.structure, inputs, w.duration, friction=law,
                                 slope_width=self.setup.slope_width)
        engine = Engine(model)
        w.engines[law] = engine
        self.__dict__.pop("_window_plans", None)  # made from the engines and start angles
        for h in {self.setup.step, self.setup.smooth_step}:
            if h not in w.grids:
                t_out = np.arange(round(w.duration / h) + 1) * h
                w.grids[h] = (t_out, *engine.source_signals(t_out))
        if w.sigma0 is None:
            self._measure(w, engine)

    def _measure(self, w: Window, engine: Engine) -> None:
        """The window's start state from the measurements (see `set_state_delays`)."""
        log = self.logs[w.log]
        w.sigma0, w.x0, w.v0, w.null, w.later = self._measured_state(log, w.start, engine)
        self.__dict__.pop("_window_plans", None)  # their sources start at sigma0
        w.quasi_static.clear()
        delay = dict(zip((o.name for o in self.outputs), self.state_delays))
        w.currents = np.array([
            self._local(log, f"motor.{m.name}.current",
                        w.start + delay.get(f"motor.{m.name}.current", 0.0))[0]
            if f"motor.{m.name}.current" in log.columns else 0.0
            for m in self.structure.motors])

    def set_state_delays(self, delays: Sequence[float]) -> bool:
        """Read each compared signal ``delays`` [s] (in the order of `outputs`) late
        when a window's start state is taken from it; returns whether any changed.

        A signal recorded ``d`` behind the inputs shows at ``start + d`` the state
        the model has at ``start``: read at ``start`` instead, a window would start
        where the wrist was ``d`` earlier, an error of the speed times ``d`` that the
        fitted delay cannot undo (it shifts the compared signal, not the start) and
        that the fit then explains with the inertias and the damping."""
        d = np.asarray(delays, dtype=float).reshape(-1)
        if d.shape != self.state_delays.shape:
            raise ValueError(f"{len(d)} delays for {len(self.outputs)} compared signals")
        if np.array_equal(d, self.state_delays):
            return False
        self.state_delays = d.copy()
        for w in self.windows:
            engine = next(iter(w.engines.values()), None)
            if engine is None:
                w.sigma0 = None  # measured when the window is first prepared
            else:
                self._measure(w, engine)
        return True

    @staticmethod
    def _local(log: Measurement, column: str, at: float) -> tuple[float, float]:
        """Value and slope of a column at ``at`` from a parabola through the samples
        within `SLOPE_HALF_WIDTH` (least squares)."""
        t = log["time"]
        i0 = int(np.searchsorted(t, at - SLOPE_HALF_WIDTH))
        i1 = max(int(np.searchsorted(t, at + SLOPE_HALF_WIDTH)), i0 + 2)
        tt, yy = t[i0:i1] - at, log[column][i0:i1]
        if len(tt) < 2:
            return float(np.interp(at, t, log[column])), 0.0
        if len(tt) < 5:
            slope, value = np.polyfit(tt, yy, 1)
            return float(value), float(slope)
        # a parabola: a straight line's value at the centre would be biased by the
        # signal's curvature (about 0.3 mrad for a 1 Hz swing of 0.5 rad over 10 ms)
        _, slope, value = np.polyfit(tt, yy, 2)
        return float(value), float(slope)

    def _angles_at(self, log: Measurement, at: float):
        """Named flange angles and speeds of the model at ``at``: measured outputs
        (each read its state delay later) and sources."""
        st = self.structure
        angles, speeds = {}, {}
        for o, delay in zip(self.outputs, self.state_delays):
            if o.kind == "angle":
                flange = next(s.flange for s in st.signals if s.name == o.name)
                angles[flange], speeds[flange] = self._local(log, o.name, at + delay)
        for j, src in enumerate(st.sources):
            column, how = self.channels.get(src.channel, (None, None))
            if how == "angle":
                angles[src.flange] = self._local(log, column, at)[0]
            else:
                angles[src.flange] = self._source_angle(log, j, src, at)
        return angles, speeds

    def _source_angle(self, log: Measurement, j: int, src, at: float) -> float:
        """A velocity source's angle at ``at``: the integral of its speed column from the
        log's start, anchored to its measured angle when the log has one (the pivot
        motor's through q)."""
        key = (id(log), j)
        cache = getattr(self, "_source_cache", None)
        if cache is None:
            cache = self._source_cache = {}
        if key not in cache:
            t = log["time"]
            column, _ = self.channels.get(src.channel, (None, None))
            speed = log[column] if column is not None else np.zeros_like(t)
            step = 0.5 * (speed[1:] + speed[:-1]) * np.diff(t)
            step[gap_indices(t)] = 0.0  # never integrated across a gap (anchored below)
            angle = np.concatenate([[0.0], np.cumsum(step)])
            names = _signals_of(self.structure, src.flange)
            measured = [n for n in names if n in log.columns]
            anchor = None
            if measured:
                anchor = log[measured[0]]
            elif src.channel == "motor_s" and "q" in log.columns and \
                    self.structure.pivot.flange is not None:
                _, ru = self.structure.rows(self.structure.pivot.flange)
                amp = self.structure.pivot.amplitude
                if ru[j]:
                    anchor = np.arcsin(np.clip(log["q"] / amp, -1, 1)) / ru[j]
            if anchor is not None:  # each stretch between gaps anchored on its own
                bounds = [0, *(int(k) + 1 for k in gap_indices(t)), len(t)]
                for a, b in zip(bounds[:-1], bounds[1:]):
                    angle[a:b] += float(np.mean(anchor[a:b] - angle[a:b]))
            cache[key] = (t, angle)
        t, angle = cache[key]
        return float(np.interp(at, t, angle))

    def _measured_state(self, log, start, engine):
        st = self.structure
        n = st.n
        angles, speeds = self._angles_at(log, start)
        x0, sigma0 = st.initial_positions(angles)
        u0 = engine.source_speeds(0.0)
        v0 = st.initial_speeds(speeds, u0) if speeds else np.zeros(n)
        measured = [st.rows(f)[0] for f in speeds]
        if measured:
            _, sv, Vt = np.linalg.svd(np.array(measured))
            rank = int(np.sum(sv > 1e-9 * max(sv[0], 1e-300)))
            null = Vt[rank:].T
        else:
            null = np.eye(n)
        later = None
        if null.shape[1]:
            dt = 0.01
            a2, _ = self._angles_at(log, start + dt)
            x2, s2 = st.initial_positions(a2)
            later = (dt, x2, s2)
        return sigma0, x0, v0, null, later

    # -- parameter sets ----------------------------------------------------------------

    def _compiled_for(self, values: np.ndarray, law: str):
        """``(mass, Minv, par)`` of the engine for one parameter set: from the affine
        map of `_affine` added to the arrays of the set with the affine parameters at
        the start (the start itself, or, where parameters that act otherwise differ and
        the affine ones' effect does not depend on them, that set compiled), else by
        building and compiling the wrist."""
        key = tuple(float(v) for v in values)
        hit = self._compiled.get(key)
        if hit is not None:
            return hit
        affine = self._affine(law)
        change = np.asarray(key) - self.base
        moved = change != 0.0
        if affine is not None and not np.any(moved & ~affine[5]):
            mask, mass0, par0, dmass, dpar, _ = affine
            if np.any(moved & ~mask):  # the others' arrays, compiled once for them all
                anchor = tuple(float(v) for v in np.where(mask, self.base, key))
                mass0, _, par0 = self._compiled.get(anchor) or self._kept(
                    anchor, self._compile(anchor, law))
            step = np.where(mask, change, 0.0)
            mass = mass0 + np.tensordot(step, dmass, axes=1)
            par = par0 + np.tensordot(step, dpar, axes=1)
            n = self.structure.n
            hit = (mass, np.linalg.inv(mass[:n, :n]) if n else np.zeros((0, 0)), par)
        else:
            hit = self._compile(key, law)
        return self._kept(key, hit)

    def _kept(self, key: tuple, hit: tuple) -> tuple:
        """``hit``, kept as the arrays of the parameter set ``key`` (a bounded cache)."""
        if len(self._compiled) > 512:
            self._compiled.clear()
        self._compiled[key] = hit
        return hit

    def _compile(self, key: tuple, law: str):
        params = with_values(self.params, dict(zip(self.names, key)))
        structure = build_wrist(params, self.wrist).assemble()
        w = self.windows[0]
        if law not in w.engines:
            self._prepare(w, law)
        base = w.engines[law].model
        # only the mass matrix and the element parameters are taken from this model: its
        # inputs are left at zero (each window's engine has the log's own)
        model, _ = compile_model(structure, {}, 1.0, friction=law,
                                 slope_width=self.setup.slope_width)
        if model.rows.shape != base.rows.shape or not np.allclose(
                model.rows, base.rows, rtol=0.0, atol=1e-9 * max(np.max(np.abs(base.rows)), 1.0)):
            changed = [n for n, v, b in zip(self.names, key, self.base) if v != b]
            raise InputError(f"free parameter(s) {', '.join(changed)} change the network's "
                             "kinematic rows; they cannot be identified in one batch")
        return model.mass, model.Minv, model.par

    def _affine(self, law: str):
        """Which free parameters the mass matrix and the element parameters depend on
        affinely (inertias, friction levels: most of them), with that map, and which of
        the others leave the affine ones' effect as it is:
        ``(affine, mass0, par0, dmass, dpar, separate)``; None if none is affine.

        Building the wrist for every parameter set of every Jacobian costs more than
        its runs on a short window; an affine parameter's effect is a sum instead.
        Affinity is checked, not assumed: two steps of each parameter must change
        the arrays by the same amount, and all of them together by the sum of their
        own changes (to `AFFINE_TOLERANCE`). A parameter that fails (a compliance
        turned into a stiffness) is compiled each time it differs from the start;
        it is ``separate`` when, stepped, all affine ones together still change the
        arrays by that sum: then the sets of a Jacobian that differ from its value
        in affine parameters only share one compile."""
        cache = self.__dict__.setdefault("_affine_cache", {})
        if law in cache:
            return cache[law]
        base = tuple(float(v) for v in self.base)
        mass0, _, par0 = self._compile(base, law)
        size = max(float(np.max(np.abs(mass0))), float(np.max(np.abs(par0))), 1e-300)
        n_par = len(base)
        affine = np.zeros(n_par, dtype=bool)
        dmass = np.zeros((n_par,) + mass0.shape)
        dpar = np.zeros((n_par,) + par0.shape)
        steps = np.where(self.base != 0, 0.1 * np.abs(self.base), 1e-3)
        stepped = {}
        tol = AFFINE_TOLERANCE * size
        for i in range(n_par):
            one, two = list(base), list(base)
            one[i] += steps[i]
            two[i] += 2 * steps[i]
            m1, _, p1 = stepped[i] = self._compile(tuple(one), law)
            m2, _, p2 = self._compile(tuple(two), law)
            if (np.max(np.abs((m2 - m1) - (m1 - mass0))) <= tol
                    and np.max(np.abs((p2 - p1) - (p1 - par0))) <= tol):
                affine[i] = True
                dmass[i] = (m1 - mass0) / steps[i]
                dpar[i] = (p1 - par0) / steps[i]

        def sums(at: np.ndarray, mass, par) -> bool:
            """Whether the affine parameters stepped together from ``at`` (whose arrays
            are ``mass``, ``par``) change the arrays by the sum of their effects."""
            together = np.where(affine, at + steps, at)
            m, _, p = self._compile(tuple(float(v) for v in together), law)
            change = together - at
            return bool(np.max(np.abs(m - mass - np.tensordot(change, dmass, axes=1))) <= tol
                        and np.max(np.abs(p - par - np.tensordot(change, dpar, axes=1))) <= tol)

        result = None
        if affine.any() and sums(self.base, mass0, par0):
            separate = affine.copy()
            for j in np.flatnonzero(~affine):
                at = self.base.copy()
                at[j] += steps[j]
                separate[j] = sums(at, stepped[j][0], stepped[j][2])
            result = (affine, mass0, par0, dmass, dpar, separate)
        cache[law] = result
        return result

    def _window_plan(self, k: int, law: str, h: float) -> Plan:
        """`_plan` of window ``k`` with its own model, made once: the runs of every
        evaluation retune it, and their checked models share its input tables."""
        plans = self.__dict__.setdefault("_window_plans", {})
        key = (k, law, h)
        if key not in plans:
            w = self.windows[k]
            plans[key] = self._plan(w, law, h, w.engines[law].model)
        return plans[key]

    def _plan(self, w: Window, law: str, h: float, model) -> Plan:
        """The plan of a window's run (the time-stepper at step ``h``, no ledger) with
        ``model``, its sources starting at the window's measured angles; runs retune
        its inertias and element parameters."""
        layout = Layout(*(int(v) for v in model.dims[:6]))
        scheme = Scheme("timestep", step=h, max_steps=int(w.duration / h) + 10)
        return Plan(self.structure, model._replace(src_pos0=w.sigma0), layout, scheme,
                    w.duration, np.zeros(layout.n_state))

    def _initial(self, w: Window, law: str, mass, Minv, par) -> np.ndarray:
        """Initial state of a window for one parameter set (quasi-static in the
        directions the measurements leave open)."""
        n = self.structure.n
        x0, v0 = w.x0.copy(), w.v0.copy()
        if w.null.shape[1]:
            # the springs' energy depends on the spring and pivot rows of the parameters
            # only: parameter sets that share them (every column of a Jacobian but the
            # springs' own) share the quasi-static guess
            n_fr, n_sp = (int(v) for v in w.engines[law].model.dims[2:4])
            key = (par[n_fr:n_fr + n_sp].tobytes(), par[-1].tobytes())
            cached = w.quasi_static.get(key)
            if cached is not None:
                x0, v0 = cached
                y = np.zeros(n * 2 + len(w.currents))
                y[:n], y[n:2 * n], y[2 * n:] = x0, v0, w.currents
                return y
            dt, x2, s2 = w.later
            x0 = self._quasi_static(self._retuned(w, law, mass, Minv, par, w.sigma0), x0, w.null)
            x2 = self._quasi_static(self._retuned(w, law, mass, Minv, par, s2), x2, w.null)
            v0 = v0 + w.null @ (w.null.T @ ((x2 - x0) / dt - v0))
            if len(w.quasi_static) > 256:
                w.quasi_static.clear()
            w.quasi_static[key] = (x0, v0)
        y = np.zeros(n * 2 + len(w.currents))
        y[:n], y[n:2 * n], y[2 * n:] = x0, v0, w.currents
        return y

    @staticmethod
    def _retuned(w: Window, law: str, mass, Minv, par, src_pos0) -> Engine:
        """The window's engine with another parameter set and start angles of the sources:
        its checked model retuned, sharing the input tables (checking and copying them
        again for every parameter set cost more than the quasi-static search)."""
        engine = w.engines[law]
        arrays = {name: np.ascontiguousarray(value, dtype=float) for name, value in
                  (("mass", mass), ("Minv", Minv), ("par", par), ("src_pos0", src_pos0))}
        return Engine(engine.model._replace(**arrays), engine.c.retuned(arrays))

    def _quasi_static(self, engine: Engine, x: np.ndarray, null: np.ndarray) -> np.ndarray:
        """Minimise the springs' energy over the unmeasured directions (Newton, central
        differences): the state a slow motion would leave them in."""
        n = self.structure.n
        d = null.shape[1]
        y = np.zeros(self.n_state)

        def energy(z):
            y[:n] = x + null @ z
            return engine.stored_energy(0.0, y)[0][1]

        z = np.zeros(d)
        e = 1e-4
        for _ in range(4):
            f0 = energy(z)
            g, H = np.zeros(d), np.zeros((d, d))
            for i in range(d):
                ei = np.zeros(d)
                ei[i] = e
                fp, fm = energy(z + ei), energy(z - ei)
                g[i] = (fp - fm) / (2 * e)
                H[i, i] = (fp - 2 * f0 + fm) / e ** 2
                for k in range(i):
                    ek = np.zeros(d)
                    ek[k] = e
                    H[i, k] = H[k, i] = (energy(z + ei + ek) - energy(z + ei - ek)
                                         - energy(z - ei + ek) + energy(z - ei - ek)) / (4 * e * e)
            try:
                dz = -np.linalg.solve(H, g) if np.all(np.diag(H) > 0) else np.zeros(d)
            except np.linalg.LinAlgError:
                break
            z = z + np.clip(dz, -0.5, 0.5)
            if np.max(np.abs(dz)) < 1e-9:
                break
        return x + null @ z

    # -- evaluation --------------------------------------------------------------------

    def simulate(self, values: np.ndarray, law: str, windows: Sequence[int] | None = None):
        """Simulated compared signals of every parameter set (rows of ``values``: the
        free parameters, then, with delays, each compared signal's delay [s]): a list
        over windows of arrays (sets, outputs, compared samples); and per set whether
        every window ran. Sets that differ in their delays only share one run."""
        values = np.atleast_2d(np.asarray(values, dtype=float))
        n_phys = len(self.names)
        physical, row_of = np.unique(values[:, :n_phys], axis=0, return_inverse=True)
        row_of = row_of.reshape(-1)
        delays = np.zeros((len(values), len(self.outputs)))
        if values.shape[1] > n_phys:
            delays[:] = values[:, n_phys:]
        chosen = range(len(self.windows)) if windows is None else windows
        for k in chosen:
            if law not in self.windows[k].engines:
                self._prepare(self.windows[k], law)
        compiled = [self._compiled_for(v, law) for v in physical]
        h = self.step_of(law)
        runs = len(physical)
        tasks = []
        threads = max(1, self.setup.threads or core.available_cores())
        chunks = max(1, min(runs, -(-threads * 3 // max(len(chosen), 1))))
        size = -(-runs // chunks)
        for k in chosen:
            for lo in range(0, runs, size):
                tasks.append((k, lo, min(runs, lo + size)))
        ok = np.ones(runs, dtype=bool)
        outs = {k: np.empty((len(values), len(self.outputs), len(self.windows[k].samples)))
                for k in chosen}

        def work(task):
            k, lo, hi = task
            w = self.windows[k]
            base = self._window_plan(k, law, h)
            plans = [base.retuned(y0=self._initial(w, law, *compiled[r]), mass=compiled[r][0],
                                  Minv=compiled[r][1], par=compiled[r][2])
                     for r in range(lo, hi)]
            batch = run_batch(plans, w.grids[h][0], threads=1)
            status = batch.status
            signals = self._signals(w, batch.states, h)
            sets = np.flatnonzero((row_of >= lo) & (row_of < hi))
            outs[k][sets] = self._sample(w, signals[row_of[sets] - lo], delays[sets], h)
            return lo, hi, status

        if threads == 1 or len(tasks) == 1:
            done = [work(t) for t in tasks]
        else:
            with ThreadPoolExecutor(max_workers=threads) as pool:
                done = list(pool.map(work, tasks))
        for lo, hi, status in done:
            ok[lo:hi] &= status == core.OK
        self.runs += runs * len(chosen)
        self.simulated += runs * sum(self.windows[k].duration for k in chosen)
        return [outs[k] for k in chosen], ok[row_of]

    def step_of(self, law: str) -> float:
        """The time-stepper's step [s] with ``law``."""
        return self.setup.step if law == "stiction" else self.setup.smooth_step

    def _signals(self, w: Window, states: np.ndarray, h: float) -> np.ndarray:
        """Compared signals on the simulation's time grid of step ``h`` (runs, outputs,
        grid)."""
        n = self.structure.n
        out = np.empty((states.shape[0], len(self.outputs), states.shape[1]))
        _, source_angles, source_speeds = w.grids[h]
        sigma = source_angles + w.sigma0[None, :]
        for c, o in enumerate(self.outputs):
            if o.kind == "current":
                out[:, c] = states[:, :, o.index]
            elif o.kind == "speed":
                out[:, c] = states[:, :, n:2 * n] @ o.rx + (source_speeds @ o.ru)[None]
            else:
                s = states[:, :, :n] @ o.rx + (sigma @ o.ru)[None]
                out[:, c] = self.structure.pivot.amplitude * np.sin(s) if o.kind == "q" else s
        return out

    def _sample(self, w: Window, signals: np.ndarray, delays: np.ndarray, h: float
                ) -> np.ndarray:
        """The signals (sets, outputs, grid of step ``h``) at the compared samples,
        each output ``delays`` [s] (sets, outputs) behind the inputs: linear
        interpolation on the grid."""
        grid = signals.shape[2]
        tau = (w.offsets[None, None, :] - delays[:, :, None]) / h
        idx = np.clip(np.floor(tau).astype(np.int64), 0, grid - 2)
        frac = tau - idx
        left = np.take_along_axis(signals, idx, axis=2)
        right = np.take_along_axis(signals, idx + 1, axis=2)
        out = left * (1.0 - frac) + right * frac
        return np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0)

    def measured(self, k: int) -> np.ndarray:
        """The measured outputs of window ``k``, one row per output, at the window's
        compared samples."""
        w = self.windows[k]
        log = self.logs[w.log]
        return np.array([log[o.name][w.samples] for o in self.outputs])

    def weights(self) -> np.ndarray:
        """One weight per output: 1 / its noise level."""
        return np.array([1.0 / self.noise[o.name] for o in self.outputs])

    def residuals(self, values: np.ndarray, law: str, windows: Sequence[int] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Noise-weighted residuals (sets, compared values) and which sets ran."""
        chosen = list(range(len(self.windows)) if windows is None else windows)
        sims, ok = self.simulate(values, law, chosen)
        wts = self.weights()[:, None]
        parts = []
        for k, sim in zip(chosen, sims):
            parts.append(((sim - self.measured(k)[None]) * wts[None]).reshape(len(sim), -1))
        r = np.concatenate(parts, axis=1)
        r[~ok] = FAILED_RESIDUAL
        return r, ok

    @property
    def compared(self) -> int:
        """Number of measured values compared (samples times outputs over all windows)."""
        return sum(len(w.samples) for w in self.windows) * len(self.outputs)

    @property
    def log_seconds(self) -> float:
        """Total duration [s] of the logs."""
        return float(sum(lg["time"][-1] - lg["time"][0] for lg in self.logs))

"""A controller written in Python, for prototyping: a function called every period.

The C controllers (`vsj.control.Controller`) run inside the engine; a Python function
cannot, so `run_callback` closes the loop around the step function instead
(`vsj.stepper.Stepper`, whose period is the controller's): at each sample it reads
the state as named signals, calls the function, holds what it returns over the next
period. Each call costs what the function costs plus the Python around it (naming the
signals, building the input vector), which `CallbackRun.per_call` measures; `make
bench` prints it beside the C controller's cost. Port a prototype to `PID` and
`Linear` blocks to run it at the engine's speed, in batches and sweeps.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from collections.abc import Callable, Mapping

import numpy as np

from ..errors import InputError, SimulationError
from ..inputs import Input, as_inputs
from ..simulate import InitialState
from ..stepper import Stepper


@dataclass
class CallbackRun:
    """A run closed by a Python function: the sample ``time`` [s], every signal the
    stepper names (`Stepper.signals`) at each sample, the ``commands`` the function
    returned (held over the period that follows), the ``state`` at the end, and the
    measured cost: ``wall_time`` of the whole run and ``per_call``, the seconds per
    sample spent outside the engine's step (the function and the Python around it)."""

    time: np.ndarray
    signals: dict
    commands: dict
    state: np.ndarray
    wall_time: float
    per_call: float
    success: bool
    message: str

    def __getitem__(self, name: str) -> np.ndarray:
        """A signal or a command by name."""
        if name in self.commands:
            return self.commands[name]
        return self.signals[name]


def run_callback(stepper: Stepper, callback: Callable[[float, Mapping[str, float]],
                                                      Mapping[str, float]],
                 duration: float, *, initial: InitialState | None = None,
                 inputs: Mapping[str, object] | None = None) -> CallbackRun:
    """Run ``stepper`` for ``duration`` [s], its inputs set every period by ``callback(t,
    signals)``: ``t`` the sample's time [s], ``signals`` the state by name (``theta_x``,
    ``motor_1.speed``, ``q``, ...); it returns the input channels it drives (a mapping of
    channel names to values in their units: V, N m, rad/s). The other channels follow
    ``inputs`` (numbers or `vsj.inputs.Input` signals, sampled at each period's start;
    default zero). A step that fails ends the run with ``success`` False and the reason
    in ``message``."""
    if not isinstance(stepper, Stepper):
        raise InputError(f"run_callback: stepper must be a vsj.stepper.Stepper, got "
                         f"{type(stepper).__name__}")
    if not callable(callback):
        raise InputError(f"run_callback: callback must be callable, got "
                         f"{type(callback).__name__}")
    if not (isinstance(duration, (int, float)) and math.isfinite(duration)
            and duration >= stepper.period):
        raise InputError(f"run_callback: duration must be at least one period "
                         f"({stepper.period:g} s), got {duration!r}")
    channels = stepper.input_names
    given = as_inputs(dict(inputs or {}), channels)
    n = int(math.floor(duration / stepper.period + 1e-9))
    times = np.arange(n + 1) * stepper.period
    base = np.zeros((n + 1, len(channels)))
    for j, ch in enumerate(channels):
        if ch in given:
            signal: Input = given[ch]
            base[:, j] = np.broadcast_to(signal.value(times), (n + 1,))
    state = stepper.initial_state(initial or InitialState(), base[0])
    index = {ch: j for j, ch in enumerate(channels)}
    signals: dict[str, np.ndarray] = {}
    commands: dict[str, np.ndarray] = {}
    u = base[0].copy()
    outside = 0.0
    success, message, reached = True, f"ran {n} periods of {stepper.period:g} s", n + 1
    began = _time.perf_counter()
    for k in range(n + 1):
        mark = _time.perf_counter()
        seen = stepper.signals(state, u)
        command = callback(float(times[k]), seen)
        u = base[k].copy()
        for name, value in _checked(command, index, k).items():
            u[index[name]] = value
            commands.setdefault(name, np.full(n + 1, np.nan))[k] = value
        for name, value in seen.items():
            signals.setdefault(name, np.full(n + 1, np.nan))[k] = value
        outside += _time.perf_counter() - mark
        if k == n:
            break
        try:
            stepper.step(state, u, out=state)
        except SimulationError as exc:
            success, message, reached = False, f"at t = {times[k]:.6g} s: {exc}", k + 1
            break
    wall = _time.perf_counter() - began
    return CallbackRun(time=times[:reached], signals={k: v[:reached] for k, v in signals.items()},
                       commands={k: v[:reached] for k, v in commands.items()}, state=state,
                       wall_time=wall, per_call=outside / reached, success=success,
                       message=message)


def _checked(command, index: Mapping[str, int], k: int) -> dict[str, float]:
    """The callback's return value as finite floats per known channel."""
    if not isinstance(command, Mapping):
        raise InputError(f"run_callback: the callback must return a mapping of input channels "
                         f"to values, got {type(command).__name__} at sample {k}")
    out = {}
    for name, value in command.items():
        if name not in index:
            raise InputError(f"run_callback: the callback drives unknown channel {name!r}; "
                             f"channels: {', '.join(index)}")
        v = float(value)
        if not math.isfinite(v):
            raise InputError(f"run_callback: the callback returned {name} = {value!r} at "
                             f"sample {k}; values must be finite")
        out[name] = v
    return out

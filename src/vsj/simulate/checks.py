"""Whether a run that ended can be trusted (`judge`), and where it left what the
parameter set describes (`warnings_of`)."""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..network import Structure
from ..springs import end_stop
from .options import SimulationOptions

#: A spring pressed this far [rad] into its end stop has left what the parameter set
#: describes (a warning); ten turns past it, a run has diverged (a failure).
INTO_STOP = 0.1
DIVERGED = 20 * math.pi


def _stop_angles(structure: Structure) -> dict[str, float]:
    angles = {}
    for sp in structure.springs:
        stop = end_stop(sp.law, sp.parameters)
        if stop is not None and stop[0] > 0.0:
            angles[sp.name] = stop[0]
    return angles


def finer_setting(solver: str, residual: float, options: SimulationOptions) -> str:
    """What to run instead when the ledger's residual exceeds its tolerance: for the
    time-stepper a step that divides the output step and, were the residual of second
    order in the step (the trapezoidal rule's; the laws' linearisation about each
    step's predicted end leaves less, falling faster), would bring it to a quarter of
    the tolerance; for dopri and rosenbrock an rtol that would bring it to a
    hundredth if
    it followed rtol in proportion (it does only roughly: another rtol takes other
    steps, whose errors need not cancel alike)."""
    excess = residual / options.ledger_tolerance
    if solver == "timestep":
        need = 2.0 * math.sqrt(excess)  # h/k: excess / k^2 <= 1/4
        # the smallest divisor of the form (1, 2, 4, 5, 8) 10^j: the step stays a short
        # decimal that divides the output step
        k = min(m * 10 ** j for j in range(12) for m in (1, 2, 4, 5, 8) if m * 10 ** j >= need)
        return f"step = \"{options.step / k:.6g} s\" (1/{k} of the step)"
    return f"rtol = {options.rtol / (100.0 * excess):.2g}"


class Watch:
    """What `judge` and `warnings_of` look for, gathered block by block as a run is
    sampled (so that a run streamed to disk is judged without holding its samples):
    the first time a spring is `DIVERGED` past its end stop, and the farthest each
    spring went into its stop and each DC motor past its voltage limit."""

    def __init__(self, structure: Structure):
        self.stops = _stop_angles(structure)
        self.limits = {mo.name: mo.voltage_limit for mo in structure.motors
                       if math.isfinite(mo.voltage_limit)}
        self.diverged: tuple[float, str] | None = None
        #: the state row at the sample where a spring diverged (if `see` had states)
        self.state: np.ndarray | None = None
        self.deepest: dict[str, tuple[float, float]] = {}  # spring: (deflection, time)
        self.highest: dict[str, tuple[float, float]] = {}  # motor: (voltage, time)

    def see(self, time: np.ndarray, signals: Mapping[str, np.ndarray],
            states: np.ndarray | None = None) -> None:
        """Take in a block of samples (and the state rows they come from)."""
        if not len(time):
            return
        for name, stop in self.stops.items():
            deflection = signals.get(f"spring.{name}.deflection")
            if deflection is None:
                continue
            past = np.abs(deflection) - stop
            over = np.flatnonzero(past > DIVERGED)
            if over.size and self.diverged is None:
                k = int(over[0])
                self.diverged = (float(time[k]), (
                    f"spring {name} deflected {past[k] + stop:.4g} rad, ten turns past its "
                    f"{stop:.4g} rad end stop: the run diverged"))
                self.state = None if states is None else np.array(states[k])
            k = int(np.argmax(np.abs(deflection)))
            if name not in self.deepest or abs(deflection[k]) > abs(self.deepest[name][0]):
                self.deepest[name] = (float(deflection[k]), float(time[k]))
        for name in self.limits:
            voltage = signals.get(f"motor.{name}.voltage")
            if voltage is None:
                continue
            k = int(np.argmax(np.abs(voltage)))
            if name not in self.highest or abs(voltage[k]) > abs(self.highest[name][0]):
                self.highest[name] = (float(voltage[k]), float(time[k]))

    def judge(self, ledger: Mapping, options: SimulationOptions, solver: str,
              end: float) -> tuple[float, str] | None:
        """Why the run cannot be trusted, with the time it shows: a spring `DIVERGED`
        past its end stop, or an energy ledger that does not close (the message names a
        finer setting, `finer_setting`); None if neither."""
        if self.diverged is not None:
            return self.diverged
        residual = ledger.get("relative_residual", 0.0)
        if not residual <= options.ledger_tolerance:
            return end, (
                f"the energy ledger does not close: its residual is {residual:.3g} of the "
                f"energy in play, above the ledger tolerance {options.ledger_tolerance:g}: the "
                f"numerical settings are too coarse for this run; try "
                f"{finer_setting(solver, residual, options)}")
        return None

    def warnings(self) -> list[str]:
        """Where the run left what the parameter set describes: a spring pressed more
        than `INTO_STOP` into its end stop, a DC motor above its voltage limit."""
        out = []
        for name, (deflection, when) in self.deepest.items():
            stop = self.stops[name]
            if abs(deflection) - stop > INTO_STOP:
                out.append(f"spring {name} was driven to {deflection:.4g} rad at t = {when:.4g} "
                           f"s, {abs(deflection) - stop:.3g} rad past its {stop:.4g} rad end "
                           f"stop: the loads exceed what the mechanism takes")
        for name, (voltage, when) in self.highest.items():
            if abs(voltage) > self.limits[name]:
                out.append(f"motor {name} was driven at {voltage:.4g} V at t = {when:.4g} s, "
                           f"beyond its {self.limits[name]:g} V limit")
        return out


def judge(structure: Structure, time: np.ndarray, signals: Mapping[str, np.ndarray],
          ledger: Mapping, options: SimulationOptions,
          solver: str = "dopri") -> tuple[float, str] | None:
    """`Watch.judge` of a run whose samples are all at hand."""
    watch = Watch(structure)
    watch.see(time, signals)
    return watch.judge(ledger, options, solver, float(time[-1]) if len(time) else 0.0)


def warnings_of(structure: Structure, time: np.ndarray,
                signals: Mapping[str, np.ndarray]) -> list[str]:
    """`Watch.warnings` of a run whose samples are all at hand."""
    watch = Watch(structure)
    watch.see(time, signals)
    return watch.warnings()

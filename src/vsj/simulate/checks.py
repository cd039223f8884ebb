"""Whether a run that ended can be trusted (`judge`), and where it left what the
parameter set describes (`warnings_of`)."""

from __future__ import annotations

import math
from typing import Mapping

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
    time-stepper a step that divides the output step and, at the residual's second
    order in the step (its springs, integrated by the trapezoidal rule), brings it to
    a quarter of the tolerance; for dopri an rtol that, at the residual's first order
    in rtol, brings it to a tenth."""
    excess = residual / options.ledger_tolerance
    if solver == "timestep":
        need = 2.0 * math.sqrt(excess)  # h/k: excess / k^2 <= 1/4
        # the smallest divisor of the form (1, 2, 4, 5, 8) 10^j: the step stays a short
        # decimal that divides the output step
        k = min(m * 10 ** j for j in range(12) for m in (1, 2, 4, 5, 8) if m * 10 ** j >= need)
        return f"step = \"{options.step / k:.6g} s\" (1/{k} of the step)"
    return f"rtol = {options.rtol / (10.0 * excess):.2g}"


def judge(structure: Structure, time: np.ndarray, signals: Mapping[str, np.ndarray],
          ledger: Mapping, options: SimulationOptions,
          solver: str = "dopri") -> tuple[float, str] | None:
    """Why a run that ended cannot be trusted, with the time it shows: an energy
    ledger that does not close (the message names a finer setting, `finer_setting`),
    or a spring `DIVERGED` past its end stop; None if neither."""
    for name, stop in _stop_angles(structure).items():
        past = np.abs(signals[f"spring.{name}.deflection"]) - stop
        over = np.flatnonzero(past > DIVERGED)
        if over.size:
            k = int(over[0])
            return float(time[k]), (
                f"spring {name} deflected {past[k] + stop:.4g} rad, ten turns past its "
                f"{stop:.4g} rad end stop: the run diverged")
    residual = ledger.get("relative_residual", 0.0)
    if not residual <= options.ledger_tolerance:
        return float(time[-1]), (
            f"the energy ledger does not close: its residual is {residual:.3g} of the energy "
            f"in play, above the ledger tolerance {options.ledger_tolerance:g}: the numerical "
            f"settings are too coarse for this run; try "
            f"{finer_setting(solver, residual, options)}")
    return None


def warnings_of(structure: Structure, time: np.ndarray,
                signals: Mapping[str, np.ndarray]) -> list[str]:
    """Where a run left what the parameter set describes: a spring pressed more than
    `INTO_STOP` into its end stop, a DC motor above its voltage limit."""
    out = []
    for name, stop in _stop_angles(structure).items():
        deflection = signals.get(f"spring.{name}.deflection")
        if deflection is None or not len(deflection):
            continue
        k = int(np.argmax(np.abs(deflection)))
        if abs(deflection[k]) - stop > INTO_STOP:
            out.append(f"spring {name} was driven to {deflection[k]:.4g} rad at t = "
                       f"{time[k]:.4g} s, {abs(deflection[k]) - stop:.3g} rad past its "
                       f"{stop:.4g} rad end stop: the loads exceed what the mechanism takes")
    for mo in structure.motors:
        voltage = signals.get(f"motor.{mo.name}.voltage")
        if voltage is None or not len(voltage) or not math.isfinite(mo.voltage_limit):
            continue
        k = int(np.argmax(np.abs(voltage)))
        if abs(voltage[k]) > mo.voltage_limit:
            out.append(f"motor {mo.name} was driven at {voltage[k]:.4g} V at t = "
                       f"{time[k]:.4g} s, beyond its {mo.voltage_limit:g} V limit")
    return out

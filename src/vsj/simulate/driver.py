"""The single-run driver: compile, check, integrate, then judge (`simulate`)."""

from __future__ import annotations

import math
import time as _time
from dataclasses import asdict
from typing import Mapping

import numpy as np

from ..engine import STATUS_TEXT, Engine, compile_model, core
from ..engine.model import friction_laws_for
from ..errors import InputError
from ..inputs import Input, as_inputs
from ..network import Structure
from ..springs import end_stop
from .checks import judge, warnings_of
from .ledger import ledger
from .options import InitialState, SimulationOptions
from .result import Result
from .signals import collect, state_names


def _initial(structure: Structure, inputs: Mapping[str, Input], initial: InitialState,
             model_inputs_u0: np.ndarray):
    angles = dict(initial.angles)
    for src in structure.sources:
        signal = inputs.get(src.channel)
        if signal is not None and signal.is_position:
            angles.setdefault(src.flange, signal.initial_angle())
    if initial.q is not None:
        if structure.pivot.flange is None:
            if abs(initial.q - structure.pivot.fixed) > 1e-12:
                raise InputError(f"initial q = {initial.q} m, but network {structure.name!r} has "
                                 f"a fixed pivot at {structure.pivot.fixed} m")
        else:
            angles[structure.pivot.flange] = structure.pivot_angle_for(initial.q)
    x0, sigma0 = structure.initial_positions(angles)
    v0 = structure.initial_speeds(initial.speeds, model_inputs_u0)
    motor_names = [m.name for m in structure.motors]
    unknown = sorted(set(initial.currents) - set(motor_names))
    if unknown:
        raise InputError(f"initial current given for unknown motor(s) {', '.join(unknown)}")
    currents = np.array([initial.currents.get(name, 0.0) for name in motor_names])
    return x0, v0, sigma0, currents


def check_arguments(structure, inputs, duration, options, initial):
    """The arguments of a run, checked before anything is compiled: ``(inputs, options,
    initial)`` with numbers as constant inputs and the defaults filled in. Raises
    `InputError` naming the argument and what it must be."""
    if not isinstance(structure, Structure):
        raise InputError(f"simulate: the model must be an assembled network (a Structure: "
                         f"Network.assemble(), or vsj.build_wrist(params).assemble()), got "
                         f"{type(structure).__name__}")
    if isinstance(duration, bool) or not isinstance(duration, (int, float, np.integer,
                                                                np.floating)):
        raise InputError(f"simulate: duration must be a number of seconds, got "
                         f"{type(duration).__name__}")
    options = SimulationOptions() if options is None else options
    if not isinstance(options, SimulationOptions):
        raise InputError(f"simulate: options must be a SimulationOptions, got "
                         f"{type(options).__name__}")
    initial = InitialState() if initial is None else initial
    if not isinstance(initial, InitialState):
        raise InputError(f"simulate: initial must be an InitialState, got "
                         f"{type(initial).__name__}")
    return as_inputs(inputs, structure.channels()), options, initial


def rigid_stops(structure: Structure) -> list[str]:
    """Springs of ``structure`` whose end stop is rigid (infinite stiffness)."""
    return [sp.name for sp in structure.springs
            if (stop := end_stop(sp.law, sp.parameters)) is not None and math.isinf(stop[1])]


def choose_solver(structure: Structure, options: SimulationOptions) -> str:
    """The solver a run uses: ``timestep`` where true stiction or a rigid end stop
    needs it (with ``solver="auto"``), else ``dopri``."""
    laws = friction_laws_for(structure, options.friction, options.friction_overrides)
    sticky = "stiction" in laws
    rigid = rigid_stops(structure)
    if options.solver == "dopri" and sticky:
        raise InputError("the stiction law needs the time-stepping solver (solver = "
                         "'timestep' or 'auto'); dopri integrates smooth laws only")
    if options.solver == "dopri" and rigid:
        raise InputError(f"a rigid end stop ({', '.join(rigid)}) is a constraint that only the "
                         "time-stepping solver handles (solver = 'timestep' or 'auto'); dopri "
                         "needs a finite elastic_element.end_stop_stiffness")
    if options.solver == "auto":
        return "timestep" if sticky or rigid else "dopri"
    return options.solver


def prepare(structure: Structure, inputs: Mapping[str, Input], duration: float,
            options: SimulationOptions, initial: InitialState):
    """Compile the model and build the initial state vector."""
    if not (math.isfinite(duration) and duration > 0.0):
        raise InputError(f"duration must be > 0 s, got {duration!r}")
    options.validate()
    model, layout = compile_model(structure, inputs, duration, friction=options.friction,
                                  friction_overrides=options.friction_overrides,
                                  slope_width=options.slope_width)
    u0 = Engine(model).source_speeds(0.0)
    x0, v0, sigma0, currents = _initial(structure, inputs, initial, u0)
    model = model._replace(src_pos0=np.ascontiguousarray(sigma0, dtype=float))
    y0 = np.concatenate([x0, v0, currents, np.zeros(layout.n_acc)])
    return model, layout, y0


def simulate(structure: Structure, inputs: Mapping[str, Input], duration: float, *,
             options: SimulationOptions | None = None, initial: InitialState | None = None,
             ports: bool = True) -> Result:
    """Simulate ``structure`` for ``duration`` seconds.

    ``inputs`` maps channel names to `vsj.inputs.Input` (missing channels are
    zero). A run fails if the pivot leaves the range its mechanism allows
    (`vsj.network.Pivot`). ``ports`` adds the torque and power of every connection.
    A failed run returns ``success=False`` with the time and state of the
    failure in ``message``; its samples up to the failure are kept.
    """
    inputs, options, initial = check_arguments(structure, inputs, duration, options, initial)
    solver = choose_solver(structure, options)
    check_run_size(structure, duration, options, solver)
    model, layout, y0 = prepare(structure, inputs, duration, options, initial)
    n_out = int(math.floor(duration / options.output_step + 1e-9)) + 1
    t_out = np.arange(n_out) * options.output_step
    started = _time.perf_counter()
    engine = Engine(model)
    out = np.full((n_out, y0.shape[0]), np.nan)
    coulomb = np.zeros((n_out, layout.n_frictions))
    stuck = np.zeros((n_out, layout.n_frictions), dtype=bool)
    y_end = y0.copy()
    if solver == "dopri":
        n_err = layout.n_state if layout.n_state else y0.shape[0]
        status, t_stop, steps, rejected = engine.dopri(
            y_end, 0.0, duration, t_out, options.rtol, options.atol, options.max_step,
            options.max_steps, n_err, out)
        flips = np.zeros(layout.n_frictions, dtype=np.int64)
        report = {"name": "dopri", "steps": int(steps), "rejected": int(rejected)}
    else:
        status, t_stop, steps, flips = engine.timestep(
            y_end, duration, options.step, t_out, options.max_steps, True, out, coulomb, stuck)
        report = {"name": "timestep", "steps": int(steps), "step": options.step}
    wall = _time.perf_counter() - started
    report.update(wall_time=wall, options={k: v for k, v in asdict(options).items()})
    valid = ~np.isnan(out[:, 0]) if out.shape[1] else np.ones(n_out, bool)
    if status != core.OK:
        last = int(np.flatnonzero(valid)[-1]) + 1 if valid.any() else 0
        t_out, out, coulomb, stuck = t_out[:last], out[:last], coulomb[:last], stuck[:last]
    signals, units = collect(structure, engine, layout, t_out, out, coulomb, stuck, ports=ports)
    transitions = {fr.name: int(flips[e]) for e, fr in enumerate(structure.frictions)
                   if flips[e]}
    n_state = 2 * layout.n + layout.n_motors

    def state_at(y) -> str:
        return ", ".join(f"{name}={value:.6g}"
                         for name, value in zip(state_names(structure), y[:n_state]))

    balance: dict = {}
    if status == core.OK:
        balance = ledger(structure, engine, layout, y0, y_end, duration)
        problem = judge(structure, t_out, signals, balance, options, solver)
        if problem is None:
            success, message = True, f"simulated {duration:g} s"
        else:  # the run ended, but its result cannot be trusted
            when, reason = problem
            k = min(int(np.searchsorted(t_out, when)), len(out) - 1)
            success, message = False, f"{reason} at t = {when:.6g} s; state: {state_at(out[k])}"
    else:
        success = False
        message = f"{STATUS_TEXT[status]} at t = {t_stop:.6g} s; state: {state_at(y_end)}"
    return Result(time=t_out, signals=signals, units=units, ledger=balance, success=success,
                  message=message, solver=report, transitions=transitions,
                  warnings=warnings_of(structure, t_out, signals))


def _available_memory() -> float:
    """Bytes this machine can still give a process (MemAvailable on Linux)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except OSError:
        pass
    return 8.0 * 2 ** 30


def check_run_size(structure: Structure, duration: float, options: SimulationOptions,
                   solver: str) -> None:
    """`InputError` before anything is allocated when a run's samples would not fit
    in memory, or its steps exceed ``max_steps`` or do not land on the samples."""
    if not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0.0):
        raise InputError(f"duration must be a finite time > 0 s, got {duration!r}")
    options.validate()
    if solver == "timestep":
        if options.step > duration:
            raise InputError(f"option step ({options.step:g} s) is longer than the duration "
                             f"({duration:g} s)")
        ratio = options.output_step / options.step
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise InputError(f"output_step ({options.output_step:g} s) must be a whole multiple "
                             f"of the time step ({options.step:g} s)")
        if duration / options.step > options.max_steps:
            raise InputError(f"{duration:g} s in steps of {options.step:g} s are "
                             f"{duration / options.step:.3g} steps, more than max_steps "
                             f"({options.max_steps})")
    samples = math.floor(duration / options.output_step + 1e-9) + 1
    n, s = structure.n, len(structure.sources)
    f, k = len(structure.frictions), len(structure.springs)
    # state and ledger rows, every internal signal, the named signals (about as many)
    # and the friction samples, in float64
    width = 2 * (4 * n + 4 * s + 4 * f + 8 * k + 8 * len(structure.motors) + 4) + f
    need = samples * width * 8.0
    available = _available_memory()
    if need > 0.5 * available:
        raise InputError(
            f"{duration:g} s sampled every {options.output_step:g} s are {samples:.3g} "
            f"samples of about {width} values: {need / 2 ** 30:.3g} GiB, more than half the "
            f"memory available ({available / 2 ** 30:.3g} GiB); raise output_step or shorten "
            f"the duration")

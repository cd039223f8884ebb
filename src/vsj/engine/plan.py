"""One plan of what to run, made once and run by every driver.

A `Plan` is the compiled, immutable description of a run: the network's arrays
(`vsj.engine.model`, checked by the engine as `native`), the inputs they carry, the
scheme and its settings (`Scheme`), the duration and the initial state. Every
driver runs plans and nothing else: a single run samples one block by block
(`Plan.start`, `Run.advance`; `vsj.simulate.run`), batches, sweeps and the
identification run many (`run_batch`), the step function advances one by held
periods (`vsj.stepper`), and the exports write one's model (`native.to_bytes`). All of
them reach the engine through one binding function, ``vsj._core.run``.
"""

from __future__ import annotations

import itertools
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from functools import cached_property
from collections.abc import Mapping, Sequence

import numpy as np

from .. import _core
from ..control.controller import compile_controller
from ..errors import InputError
from ..inputs import Input
from ..network import Structure
from .core import OK, Engine, available_cores, native
from .model import EngineModel, Layout, compile_model

#: Codes of the schemes in ``vsj._core.run`` (engine/c/run.c).
METHODS = {"dopri": 0, "timestep": 1, "rk4": 2, "rosenbrock": 3}
#: The adaptive schemes' default relative and absolute tolerances (rad, rad/s, A): every
#: run, scenario, FMU and command that sets none. The global error they leave in the
#: report's runs is orders of magnitude below what a plot or a fit can see, at less than
#: half the steps of a tolerance a hundred times tighter.
RTOL, ATOL = 1e-6, 1e-8


@dataclass(frozen=True)
class Scheme:
    """An integration scheme and its settings (SI): ``dopri`` (adaptive Dormand-Prince
    5(4): ``rtol``, ``atol``, ``max_step``), ``rosenbrock`` (adaptive linearly
    implicit Rosenbrock 4(3) with the model's Jacobian, the same settings), ``timestep`` (the time-stepper with true
    stiction, step ``step``) or ``rk4`` (held periods of the step function only,
    ``substeps`` a period); ``max_steps`` bounds a run's steps."""

    name: str
    rtol: float = RTOL
    atol: float = ATOL
    max_step: float = math.inf
    step: float = 1e-3
    max_steps: int = 20_000_000
    substeps: int = 4

    @classmethod
    def of(cls, solver: str, options) -> "Scheme":
        """The scheme ``solver`` with the settings of `vsj.simulate.SimulationOptions`."""
        return cls(solver, rtol=options.rtol, atol=options.atol, max_step=options.max_step,
                   step=options.step, max_steps=options.max_steps)

    def code(self, n_err: int, ledger: bool) -> tuple:
        """The tuple ``vsj._core.run`` takes."""
        return (METHODS[self.name], self.rtol, self.atol,
                self.max_step if math.isfinite(self.max_step) else 1e300, int(n_err),
                self.step, int(self.max_steps), bool(ledger), int(self.substeps))


def initial_state(structure: Structure, inputs: Mapping[str, Input], initial,
                  source_speeds: np.ndarray):
    """``(x0, v0, sigma0, currents)``: the generalised angles and speeds, source angles
    and motor currents at t = 0 of a run of ``structure`` from ``initial``
    (`vsj.simulate.InitialState`: angles, pivot position q, speeds, currents), the
    position sources starting where their inputs do. Raises `InputError` for a state
    the network cannot take."""
    angles = dict(initial.angles)
    for src in structure.sources:
        signal = inputs.get(src.channel)
        if signal is not None and signal.is_position:
            start = signal.initial_angle()
            given = angles.setdefault(src.flange, start)
            if given != start:
                raise InputError(f"initial angle of {src.flange} ({given:g} rad) contradicts "
                                 f"its input {src.channel!r}, an angle that starts at "
                                 f"{start:g} rad: leave the initial angle out (the input sets "
                                 "it) or give the same")
    if initial.q is not None:
        if structure.pivot.flange is None:
            if abs(initial.q - structure.pivot.fixed) > 1e-12:
                raise InputError(f"initial q = {initial.q} m, but network {structure.name!r} has "
                                 f"a fixed pivot at {structure.pivot.fixed} m")
        else:
            angles[structure.pivot.flange] = structure.pivot_angle_for(initial.q)
    x0, sigma0 = structure.initial_positions(angles)
    for e, element in enumerate(structure.frictions):  # contacts start apart or touching
        if element.contact is not None:
            row = structure.friction_rows[e]
            depth = float(row @ structure.A @ x0 + row @ structure.B @ sigma0
                          - element.contact[3])
            if depth > 1e-12 * max(1.0, abs(element.contact[3])):
                raise InputError(f"contact {element.name!r} starts penetrated by {depth:.6g} m "
                                 "(its surface lies inside the start's position: move it, "
                                 "or start the run elsewhere)")
    v0 = structure.initial_speeds(initial.speeds, source_speeds)
    motor_names = [m.name for m in structure.motors]
    unknown = sorted(set(initial.currents) - set(motor_names))
    if unknown:
        raise InputError(f"initial current given for unknown motor(s) {', '.join(unknown)}")
    currents = np.array([initial.currents.get(name, 0.0) for name in motor_names])
    return x0, v0, sigma0, currents



def check_period(period: float, scheme: Scheme, duration: float, *, held: bool = False) -> None:
    """`InputError` unless a controller of ``period`` [s] can run with ``scheme``: the
    time-stepper's steps must fit a whole number of times into it; and in the step
    function (``held``, periods of ``duration``) it must fit a whole number of times into
    each period (rk4's: once)."""
    if held:
        ratio = duration / period
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise InputError(f"controller period {period:g} s: the step function's period "
                             f"{duration:g} s must be a whole number of controller periods")
        if scheme.name == "rk4" and abs(ratio - 1.0) > 1e-9:
            raise InputError(f"controller period {period:g} s: rk4 steps hold one controller "
                             f"sample a period; use a step function period of {period:g} s")
    if scheme.name == "timestep":
        ratio = period / scheme.step
        if ratio < 1.0 - 1e-9 or abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise InputError(f"controller period {period:g} s: the time-stepper's step "
                             f"{scheme.step:g} s must divide it a whole number of times (a "
                             "controller cannot sample faster than the plant steps)")
    if period > duration and not held:
        raise InputError(f"controller period {period:g} s is longer than the run "
                         f"({duration:g} s): it would sample once")


@dataclass(frozen=True)
class Plan:
    """What to run: a compiled model, its scheme, duration and initial state.

    ``y0`` is the initial state followed by the energy ledger's accumulators (zeros).
    `native` is the engine's checked copy of ``model``; `retuned` gives a
    plan of the same network with other per-run arrays (inertias, element parameters,
    source angles, initial state), as batches and sweeps need.
    """

    structure: Structure
    model: EngineModel
    layout: Layout
    scheme: Scheme
    duration: float
    y0: np.ndarray
    inputs: Mapping[str, Input] = field(default_factory=dict, repr=False)
    #: the `vsj.simulate.SimulationOptions` it was compiled with (sampling, checks)
    options: object = field(default=None, repr=False)
    #: a retuned plan: the plan it was retuned from and the real arrays it replaced,
    #: so that its checked model shares the others with that plan's (`checked`)
    base: tuple | None = field(default=None, repr=False, compare=False)
    #: the sampled controller the model carries (`vsj.control.CompiledController`), if any
    controller: object = field(default=None, repr=False)

    @cached_property
    def native(self) -> _core.Model:
        """The engine's checked copy of the model, made on first use and kept."""
        return self.checked()

    def checked(self) -> _core.Model:
        """`native` if made already, else a checked copy that is not kept (batches make
        one per run, so that a long list of plans holds no copies). A retuned plan's
        shares the arrays it did not replace with its origin's."""
        made = self.__dict__.get("native")
        if made is not None:
            return made
        if self.base is not None:
            origin, changed = self.base
            return origin.native.retuned(changed)
        return native(self.model)

    @classmethod
    def compile(cls, structure: Structure, inputs: Mapping[str, Input], duration: float,
                options, initial, scheme: "Scheme | str", *, held: bool = False,
                controller=None) -> "Plan":
        """The plan of a run of ``structure`` (inputs, duration, `SimulationOptions`,
        `InitialState`; ``scheme`` a `Scheme` or the name of one, whose settings then
        come from ``options``), closed by ``controller`` (a `vsj.control.Controller`) if
        given. With ``held`` the plan is the step function's (`vsj.stepper`): inputs held
        over periods of ``duration``, no initial state."""
        if not (math.isfinite(duration) and duration > 0.0):
            raise InputError(f"duration must be > 0 s, got {duration!r}")
        options.validate()
        if isinstance(scheme, str):
            scheme = Scheme.of(scheme, options)
        compiled = None
        if controller is not None:
            compiled = compile_controller(controller, structure, structure.channels())
            check_period(compiled.period, scheme, duration, held=held)
            driven = set(compiled.channels) & set(inputs)
            if driven and not held:  # held: every channel is an input, driven ones ignored
                raise InputError(f"input(s) {', '.join(sorted(driven))} are driven by the "
                                 "controller; remove them from the inputs")
        model, layout = compile_model(structure, inputs, duration, friction=options.friction,
                                      friction_overrides=options.friction_overrides,
                                      slope_width=options.slope_width, controller=compiled)
        plan = cls(structure, model, layout, scheme, float(duration),
                   np.zeros(layout.n_state + layout.n_acc), inputs, options,
                   controller=compiled)
        return plan if held else plan.started(initial)

    def started(self, initial, source_speeds: np.ndarray | None = None, *,
                structure: Structure | None = None, **arrays) -> "Plan":
        """This plan run from ``initial`` (`InitialState`): the initial state built and
        checked against the network (``structure``, default the plan's: another of the
        same topology for a batch over parameter sets), the position sources starting
        where their inputs do; ``arrays`` replace those of the model as in `retuned`, so
        the checked model shares the rest with this plan's. ``source_speeds`` at t = 0,
        if known, saves evaluating them."""
        structure = self.structure if structure is None else structure
        if source_speeds is None:
            source_speeds = self.engine().source_speeds(0.0)
        x0, v0, sigma0, currents = initial_state(structure, self.inputs, initial,
                                                 source_speeds)
        y0 = np.concatenate([x0, v0, currents, np.zeros(self.layout.n_acc)])
        plan = self.retuned(y0=y0, src_pos0=np.asarray(sigma0, dtype=float), **arrays)
        return plan if structure is self.structure else replace(plan, structure=structure)

    def retuned(self, *, y0=None, **arrays) -> "Plan":
        """This plan with some arrays of its model replaced (same sizes) and, if given,
        another initial state."""
        arrays = {k: np.ascontiguousarray(v) for k, v in arrays.items()}
        model = self.model._replace(**arrays)
        origin, changed = self.base if self.base is not None else (self, {})
        changed = {**changed, **arrays}
        shared = all(v.dtype == np.float64 for v in changed.values())
        y0 = self.y0 if y0 is None else np.asarray(y0, dtype=float)
        return replace(self, model=model, y0=y0, base=(origin, changed) if shared else None)

    def with_scheme(self, **settings) -> "Plan":
        """This plan with other scheme settings (``rtol``, ``step``, ...; `Scheme`)."""
        return replace(self, scheme=replace(self.scheme, **settings))

    def sample(self, times: np.ndarray, *, ledger: bool = True):
        """Run the whole plan, sampled at ``times``: ``(run, states, coulomb, stuck)``
        (`Run.advance`); ``run.status`` and ``run.y`` tell how and where it ended."""
        times = np.ascontiguousarray(times, dtype=float)
        run = self.start(ledger=ledger, until=float(times[-1]) if len(times) else None)
        return (run, *run.advance(times, finish=True))

    def engine(self) -> Engine:
        """An `Engine` (evaluations: observation, energies) on this plan's model."""
        return Engine(self.model, self.native)

    def hold(self, work: _core.Work, state: np.ndarray, inputs: np.ndarray) -> int:
        """Advance the step function's ``state`` (in place) by one period (the plan's
        duration) with ``inputs`` held; the engine's status."""
        return _run(self.native, work, state, self._held_code, self.duration, held=inputs)[0]

    @cached_property
    def _held_code(self) -> tuple:
        return self.scheme.code(self.layout.n_state, False)

    def start(self, *, ledger: bool = True, until: float | None = None) -> "Run":
        """Begin a run (its own work), sampled by `Run.advance`. Without ``ledger`` only
        the state is integrated (no energy accumulators). ``until`` ends it later than
        the duration (the last sample of a grid may lie past it by round-off)."""
        return Run(self, ledger=ledger, end=max(self.duration, until or 0.0))


class Run:
    """A plan being run: each `advance` samples the next times (the engine's steps do not
    depend on how the samples are split). ``y`` is the state (and accumulators) where
    the run stands, ``status`` the engine's status, ``t`` the time reached."""

    def __init__(self, plan: Plan, *, ledger: bool, end: float, work=None, checked=None):
        self.plan, self.end = plan, float(end)
        self.native = plan.native if checked is None else checked
        layout = plan.layout
        self.y = np.array(plan.y0 if ledger else plan.y0[:layout.n_state], dtype=float)
        self.n_err = layout.n_state if layout.n_state else len(self.y)
        self.scheme = plan.scheme.code(self.n_err, ledger)
        self.work = work if work is not None else _core.Work(self.native)
        self.t, self.steps, self.rejected = 0.0, 0, 0
        #: columns a sample row gains with a controller (its bus and actuators)
        self.extra = plan.controller.width if plan.controller is not None else 0
        self.status = _run(self.native, self.work, self.y, self.scheme, 0.0,
                           begin=(0.0, self.end))[0]

    def advance(self, times: np.ndarray, *, finish: bool):
        """The samples at ``times`` (after those of earlier calls): ``(states, coulomb,
        stuck)``, the state rows (NaN where the run did not reach), and for the
        time-stepper each friction element's Coulomb torque and whether it held. With
        ``finish`` the run goes on to its end (the ledger's)."""
        times = np.ascontiguousarray(times, dtype=float)
        f = self.plan.layout.n_frictions
        out = np.full((len(times), len(self.y) + self.extra), np.nan)
        coulomb = np.zeros((len(times), f))
        stuck = np.zeros((len(times), f), dtype=bool)
        if self.status != OK:
            return out, coulomb, stuck
        until = self.end if finish or not len(times) else float(times[-1])
        timestep = self.plan.scheme.name == "timestep"
        status, t, steps, rejected = _run(
            self.native, self.work, self.y, self.scheme, until, finish=finish,
            t_out=times, out=out, coulomb=coulomb if timestep else None,
            stuck=stuck if timestep else None)
        self.status, self.t, self.steps, self.rejected = status, t, steps, rejected
        return out, coulomb, stuck

    def transitions(self) -> np.ndarray:
        """Starts and ends of stick phases per friction element (0 for dopri)."""
        counts = np.zeros(self.plan.layout.n_frictions, dtype=np.int64)
        if self.plan.scheme.name == "timestep":
            _core.transitions(self.native, self.work, counts)
        return counts


def _run(model, work, y, scheme, until, **kwargs):
    """``vsj._core.run``, the engine's one entry point (counted by the tests)."""
    return _core.run(model, work, y, scheme, until, **kwargs)


@dataclass
class Batch:
    """The states of many runs of plans of one network on one sample grid."""

    time: np.ndarray
    #: (runs, samples, n_state + a controller's columns), NaN where a run did not reach
    states: np.ndarray
    y_end: np.ndarray           # (runs, n_state)
    status: np.ndarray          # engine status per run
    stop_time: np.ndarray
    steps: np.ndarray
    transitions: np.ndarray     # stick-phase counts per run (summed over elements)


def run_batch(plans: Sequence[Plan], times: np.ndarray, *, threads: int | None = None,
              progress=None) -> Batch:
    """Run ``plans`` (one network's sizes and controller; no ledger), sampled at ``times``
    (the states, then a controller's bus and actuators), on
    ``threads`` threads (default: every core), one plan at a time as they free up; the
    results do not depend on the number of threads. ``progress``, if given, is called
    with the number of runs finished after each."""
    runs = len(plans)
    if not runs:
        raise InputError("run_batch: no plans to run")
    times = np.ascontiguousarray(times, dtype=float)
    n_state = plans[0].layout.n_state
    extra = plans[0].controller.width if plans[0].controller is not None else 0
    if any((p.controller.width if p.controller is not None else 0) != extra for p in plans):
        raise InputError("run_batch: the plans carry controllers of different sizes (or some "
                         "none); a batch runs plans of one network and one controller")
    states = np.full((runs, len(times), n_state + extra), np.nan)
    y_end = np.zeros((runs, n_state))
    status = np.zeros(runs, dtype=np.int64)
    stop = np.zeros(runs)
    steps = np.zeros(runs, dtype=np.int64)
    flips = np.zeros(runs, dtype=np.int64)
    counter, finished = itertools.count(), itertools.count(1)

    def worker():
        work = None
        while (r := next(counter)) < runs:
            plan = plans[r]
            checked = plan.checked()
            if work is None:
                work = _core.Work(checked)
            run = Run(plan, ledger=False, end=max(plan.duration, float(times[-1])), work=work,
                      checked=checked)
            out, _, _ = run.advance(times, finish=True)
            states[r] = out if not extra else np.hstack([out[:, :n_state], out[:, -extra:]])
            y_end[r] = run.y[:n_state]
            status[r], stop[r], steps[r] = run.status, run.t, run.steps
            flips[r] = int(run.transitions().sum())
            done = next(finished)
            if progress is not None:
                progress(done)

    threads = max(1, min(threads or available_cores(), runs))
    if threads == 1:
        worker()
    else:
        with ThreadPoolExecutor(max_workers=threads) as pool:
            for future in [pool.submit(worker) for _ in range(threads)]:
                future.result()
    return Batch(times, states, y_end, status, stop, steps, flips)

"""The single-run driver: compile, check, integrate, then judge (`simulate`)."""

from __future__ import annotations

import math
import time as _time
from dataclasses import asdict
from collections.abc import Mapping

import numpy as np

from ..engine import STATUS_TEXT, core
from ..engine.model import friction_laws_for
from ..engine.plan import Plan
from ..errors import InputError, is_number
from ..inputs import Input, as_inputs
from ..network import Structure
from ..springs import end_stop
from .checks import Watch
from .ledger import ledger
from .options import InitialState, SimulationOptions
from .result import Result
from .signals import catalogue, collect, state_names


def check_arguments(structure, inputs, duration, options, initial):
    """The arguments of a run, checked before anything is compiled: ``(inputs, options,
    initial)`` with numbers as constant inputs and the defaults filled in. Raises
    `InputError` naming the argument and what it must be."""
    if not isinstance(structure, Structure):
        raise InputError(f"simulate: the model must be an assembled network (a Structure: "
                         f"Network.assemble(), or vsj.build_wrist(params).assemble()), got "
                         f"{type(structure).__name__}")
    if not is_number(duration):
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
    smooth_only = options.solver in ("dopri", "rosenbrock")
    if smooth_only and sticky:
        raise InputError("the stiction law needs the time-stepping solver (solver = "
                         f"'timestep' or 'auto'); {options.solver} integrates smooth laws only")
    if smooth_only and rigid:
        raise InputError(f"a rigid end stop ({', '.join(rigid)}) is a constraint that only the "
                         "time-stepping solver handles (solver = 'timestep' or 'auto'); "
                         f"{options.solver} needs a finite elastic_element.end_stop_stiffness")
    if options.solver == "auto":
        return "timestep" if sticky or rigid else "dopri"
    return options.solver


def prepare(structure: Structure, inputs: Mapping[str, Input], duration: float,
            options: SimulationOptions, initial: InitialState, controller=None) -> Plan:
    """The plan of a run (`vsj.engine.plan.Plan`): the model compiled (with
    ``controller``, a `vsj.control.Controller`, in the loop), its initial state built and
    checked against the network."""
    return Plan.compile(structure, inputs, duration, options, initial,
                        choose_solver(structure, options), controller=controller)


#: Memory the samples of one block may take while they are observed and named [bytes]:
#: a run is sampled block by block, so that a long one streamed to a file needs no more.
BLOCK_BYTES = 32 * 2 ** 20


def sample_count(duration: float, output_step: float) -> int:
    """How many samples `sample_times` gives, without making them."""
    return int(math.floor(duration / output_step + 1e-9)) + 1


def sample_times(duration: float, output_step: float) -> np.ndarray:
    """The sample grid of a run: every ``output_step`` from 0 to ``duration``."""
    return np.arange(sample_count(duration, output_step)) * output_step


class MemorySink:
    """Where `simulate` puts a run's samples by default: arrays in memory, returned in
    its `Result`. A sink takes the signal table and the sample times (`begin`), each
    block of named samples as it comes (`write`), and the number of samples the run
    reached (`end`); `vsj.output.TrajectoryFile` gives sinks that write to a file."""

    keeps_samples = True

    def begin(self, table, time: np.ndarray) -> None:
        """Make room for every signal of ``table`` at the sample times ``time`` [s] (NaN
        until written)."""
        self.time = time
        self.signals = {s.name: np.full(len(time), np.nan) for s in table}
        self.units = {s.name: s.unit for s in table}

    def write(self, start: int, signals: Mapping[str, np.ndarray]) -> None:
        """Store a block of samples, by signal name, from sample ``start`` on."""
        for name, values in signals.items():
            self.signals[name][start:start + len(values)] = values

    def end(self, samples: int) -> tuple[np.ndarray, dict, dict]:
        """The samples reached: ``(time, signals, units)``."""
        return (self.time[:samples], {k: v[:samples] for k, v in self.signals.items()},
                self.units)


def block_samples(structure: Structure, layout, ports: bool, extra: int = 0) -> int:
    """Samples per block: as many as fit `BLOCK_BYTES` with the state rows, the
    engine's observation and the named signals of each sample (and ``extra`` columns
    of a controller's, in the rows and as signals)."""
    from ..output import signals_bound  # circle: vsj.output imports vsj.simulate

    width = 2 * layout.n_state + layout.n_acc + 4 * (layout.n + layout.n_sources) \
        + 8 * (layout.n_frictions + layout.n_springs + layout.n_motors) + 4 \
        + signals_bound(structure) * (1 if ports else 1) + 2 * extra
    return max(1, BLOCK_BYTES // (8 * width))


def simulate(structure: Structure, inputs: Mapping[str, Input], duration: float, *,
             options: SimulationOptions | None = None, initial: InitialState | None = None,
             ports: bool = True, sink=None, controller=None) -> Result:
    """Simulate ``structure`` for ``duration`` seconds.

    ``inputs`` maps channel names to `vsj.inputs.Input` (missing channels are
    zero; a number is a constant). A run fails if the pivot leaves the range its
    mechanism allows (`vsj.network.Pivot`). ``ports`` adds the torque and power of
    every connection. A failed run returns ``success=False`` with the time and state
    of the failure in ``message``; its samples up to the failure are kept.

    The run is sampled in blocks of samples (`BLOCK_BYTES`), which go to ``sink``:
    by default a `MemorySink`, whose samples the `Result` holds; a sink that writes
    them to a file (`vsj.output.TrajectoryFile`) keeps memory flat however long the
    run, and its `Result` holds no samples. The blocks do not change the result: the
    engine's steps do not depend on them.

    ``controller`` (a `vsj.control.Controller`) closes the loop: it runs in the engine
    at its own period, drives the channels its actuators name (leave them out of
    ``inputs``), and its signals join the result (``control.<name>``,
    ``actuator.<channel>``).
    """
    inputs, options, initial = check_arguments(structure, inputs, duration, options, initial)
    duration = float(duration)
    # the size first: a run too large for memory or disk is refused before anything else
    check_run_size(structure, duration, options, choose_solver(structure, options),
                   in_memory=getattr(sink, "keeps_samples", True), ports=ports)
    return run_plan(prepare(structure, inputs, duration, options, initial, controller),
                    ports=ports, sink=sink)


def run_plan(plan: Plan, *, ports: bool = True, sink=None) -> Result:
    """Run a plan made by `prepare` (or `vsj.scenario.prepare_case`), as `simulate` runs
    it: sampled on its options' output grid, block by block into ``sink``, watched by
    the physical checks and judged by the energy ledger."""
    structure, options, duration = plan.structure, plan.options, plan.duration
    solver = plan.scheme.name
    sink = MemorySink() if sink is None else sink
    extra = plan.controller.width if plan.controller is not None else 0
    check_run_size(structure, duration, options, solver,
                   in_memory=getattr(sink, "keeps_samples", True), ports=ports, extra=extra)
    layout = plan.layout
    t_out = sample_times(duration, options.output_step)
    n_out = len(t_out)
    table = catalogue(structure, ports=ports, controller=plan.controller)
    sink.begin(table, t_out)
    watch = Watch(structure)
    started = _time.perf_counter()
    engine = plan.engine()
    # the last sample may lie past the duration by the grid's round-off: the run reaches it
    run = plan.start(until=float(t_out[-1]))
    per_block = block_samples(structure, layout, ports, extra)
    reached, status = 0, core.OK
    for start in range(0, n_out, per_block):
        times = t_out[start:start + per_block]
        out, coulomb, stuck = run.advance(times, finish=start + per_block >= n_out)
        valid = len(times) if run.status == core.OK else \
            int(np.count_nonzero(~np.isnan(out[:, 0]))) if out.shape[1] else 0
        times, out, coulomb, stuck = times[:valid], out[:valid], coulomb[:valid], stuck[:valid]
        signals, _ = collect(structure, engine, layout, times, out, coulomb, stuck,
                             ports=ports, table=table, controller=plan.controller)
        sink.write(start, signals)
        watch.see(times, signals, out)
        reached = start + valid
        status = run.status
        if status != core.OK:
            break
    y_end = run.y
    wall = _time.perf_counter() - started
    report = {"name": solver, "steps": int(run.steps)}
    report.update({"rejected": int(run.rejected)} if solver != "timestep" else
                  {"step": options.step})
    report.update(wall_time=wall, options={k: v for k, v in asdict(options).items()})
    flips = run.transitions()
    transitions = {fr.name: int(flips[e]) for e, fr in enumerate(structure.frictions)
                   if flips[e]}
    n_state = 2 * layout.n + layout.n_motors

    def state_at(y) -> str:
        return ", ".join(f"{name}={value:.6g}"
                         for name, value in zip(state_names(structure), y[:n_state]))

    balance: dict = {}
    if status == core.OK:
        balance = ledger(structure, engine, layout, plan.y0, y_end, duration)
        problem = watch.judge(balance, options, solver, float(t_out[-1]))
        if problem is None:
            success, message = True, f"simulated {duration:g} s"
        else:  # the run ended, but its result cannot be trusted
            when, reason = problem
            state = watch.state if watch.state is not None else y_end
            success, message = False, f"{reason} at t = {when:.6g} s; state: {state_at(state)}"
    else:
        success = False
        message = f"{STATUS_TEXT[status]} at t = {run.t:.6g} s; state: {state_at(y_end)}"
    time, signals, units = sink.end(reached)
    return Result(time=time, signals=signals, units=units, ledger=balance, success=success,
                  message=message, solver=report, transitions=transitions,
                  warnings=watch.warnings(), plan=plan,
                  descriptions={spec.name: spec.description for spec in table
                                if spec.name in signals})


def _read_number(path: str) -> float | None:
    try:
        with open(path, encoding="ascii") as handle:
            text = handle.read().strip()
    except OSError:
        return None
    return None if text in ("", "max") else float(text)


#: Where a control group says its memory limit and use: (limit, usage) files of
#: cgroup v2, then v1; the first pair that reads is taken.
CGROUP_FILES = (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                 "/sys/fs/cgroup/memory/memory.usage_in_bytes"))


def available_memory() -> tuple[float, str]:
    """Bytes this process can still take, and what limits it: the least of the
    machine's available memory (MemAvailable), the address-space limit (RLIMIT_AS,
    less what the process maps already) and its control group's limit (less its use)."""
    limits = []
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    limits.append((float(line.split()[1]) * 1024.0, "the machine's memory"))
    except OSError:
        pass
    try:
        import resource  # lazy: Unix only, its absence is handled here

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            mapped = 0.0
            with open("/proc/self/status", encoding="ascii") as handle:
                for line in handle:
                    if line.startswith("VmSize:"):
                        mapped = float(line.split()[1]) * 1024.0
            limits.append((soft - mapped, "the address-space limit (ulimit -v)"))
    except (ImportError, OSError, ValueError):
        pass
    for limit, usage in CGROUP_FILES:
        top, used = _read_number(limit), _read_number(usage)
        if top is not None and used is not None and top < 2 ** 60:
            limits.append((top - used, "the control group's memory limit"))
            break
    if not limits:
        return 8.0 * 2 ** 30, "an assumed 8 GiB"
    return min(limits)


def check_run_size(structure: Structure, duration: float, options: SimulationOptions,
                   solver: str, *, in_memory: bool = True, ports: bool = True,
                   extra: int = 0, runs: int = 1, width: int | None = None) -> None:
    """`InputError` before anything is allocated when a run's steps exceed
    ``max_steps`` or do not land on the samples, or its samples would not fit in the
    memory this process may take (`available_memory`): all of them for a run kept in
    memory, one block (`BLOCK_BYTES`) for a run streamed to a file. A batch of ``runs``
    keeps ``width`` columns a sample of each (default: a single run's signals)."""
    if not (is_number(duration) and math.isfinite(duration) and duration > 0.0):
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
    from ..output import signals_bound  # circle: vsj.output imports vsj.simulate

    samples = sample_count(duration, options.output_step)
    batch = width is not None
    if width is None:
        width = signals_bound(structure) + extra  # a controller's signals too
    need = 3.0 * BLOCK_BYTES + (runs * samples * width * 8.0 if in_memory else 0.0)
    available, limit = available_memory()
    if need > 0.8 * available:
        if in_memory:
            each = f" in each of {runs} runs" if runs > 1 else ""
            instead = ("or run fewer runs at a time" if batch else
                       "or stream the run to a file (vsj simulate --out does)")
            raise InputError(
                f"{duration:g} s sampled every {options.output_step:g} s are {samples:.3g} "
                f"samples{each} of up to {width} signals: {need / 2 ** 30:.3g} GiB in "
                f"memory, more than {limit} leaves this process "
                f"({available / 2 ** 30:.3g} GiB); raise output_step, shorten the duration, "
                f"{instead}")
        raise InputError(f"a block of samples needs {need / 2 ** 20:.3g} MiB, more than "
                         f"{limit} leaves this process ({available / 2 ** 20:.3g} MiB)")

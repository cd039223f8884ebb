"""Many runs of one model in one call, on every core (`simulate_batch`)."""

from __future__ import annotations

import numbers
import time as _time
from collections.abc import Iterable, Mapping

import numpy as np

from ..engine import STATUS_TEXT, compile_model, core
from ..engine.plan import run_batch
from ..errors import InputError
from ..inputs import Input
from ..network import Structure
from .driver import check_arguments, check_run_size, choose_solver, prepare, sample_times
from .options import InitialState, SimulationOptions
from .result import BatchResult
from .signals import catalogue, state_names

#: Compiled arrays that a batch run may change: the rest are shared by every run.
_PER_RUN = ("mass", "Minv", "par")


def _same_topology(base, layout, model, layout_r, r: int) -> None:
    """Refuse a batch structure that differs from the first in anything but the
    per-run arrays (`_PER_RUN`): the batch engine would silently take the first
    structure's connection matrices, laws, inputs or tables for it."""
    if layout_r != layout:
        raise InputError(f"simulate_batch: structure {r} differs in topology ({layout_r} "
                         f"against {layout})")
    for name in base._fields:
        if name in _PER_RUN:
            continue
        a, b = np.asarray(getattr(base, name)), np.asarray(getattr(model, name))
        if a.shape != b.shape or not np.array_equal(a, b):
            raise InputError(f"simulate_batch: structure {r} differs from the first in "
                             f"{name!r}; batch runs may differ only in inertias and element "
                             f"parameters (run the others separately)")


def control_names(controller) -> list[str]:
    """The signal names of a compiled controller's columns (bus, then actuators)."""
    if controller is None:
        return []
    return ([f"control.{name}" for name in controller.bus]
            + [f"actuator.{channel}" for channel in controller.channels])


def simulate_batch(structure: Structure, inputs: Mapping[str, Input], duration: float, *,
                   initials: list[InitialState], options: SimulationOptions | None = None,
                   structures: list[Structure] | None = None,
                   threads: int | None = None, controller=None) -> BatchResult:
    """Run one model many times in parallel, on every core.

    Each run starts from its own `InitialState` (a sweep over the pivot
    position, say); with ``structures`` (one per run, same topology) the runs
    may also differ in every parameter. All runs share inputs, duration and
    options. Only the states are integrated and sampled (no energy ledger); use
    `BatchResult.angle` and `speed`. ``threads`` (default: every core) share
    the runs; the results do not depend on their number. ``controller`` (a
    `vsj.control.Controller`) closes each run's loop; its signals are
    ``batch["control.<name>"]`` and ``batch["actuator.<channel>"]``.
    """
    inputs, options, _ = check_arguments(structure, inputs, duration, options, None)
    duration = float(duration)
    initials = list(initials) if isinstance(initials, Iterable) else initials
    if not initials or not all(isinstance(i, InitialState) for i in initials):
        raise InputError("simulate_batch needs a list of at least one InitialState")
    if structures is not None and len(structures) != len(initials):
        raise InputError(f"simulate_batch: {len(structures)} structures for {len(initials)} runs")
    if threads is not None and (isinstance(threads, bool)
                                or not isinstance(threads, numbers.Integral) or threads < 1):
        raise InputError(f"simulate_batch: threads must be a whole number >= 1 (or None: every "
                         f"core), got {threads!r}")
    solver = choose_solver(structure, options)
    plan = prepare(structure, inputs, duration, options, InitialState(), controller)
    base, layout = plan.model, plan.layout
    # the checks of a single run (steps, sample grid, memory), for the batch's states
    width = layout.n_state + (plan.controller.width if plan.controller is not None else 0)
    check_run_size(structure, duration, options, solver, runs=len(initials), width=width)
    engine = plan.engine()
    u0 = engine.source_speeds(0.0)
    plans, src0s = [], np.zeros((len(initials), layout.n_sources))
    for r, initial in enumerate(initials):
        struct_r = structure if structures is None else structures[r]
        per_run = {}
        if structures is not None:
            m_r, layout_r = compile_model(struct_r, inputs, duration, friction=options.friction,
                                          friction_overrides=options.friction_overrides,
                                          slope_width=options.slope_width)
            _same_topology(base, layout, m_r, layout_r, r)
            per_run = {name: getattr(m_r, name) for name in _PER_RUN}
        run_plan = plan.started(initial, u0, structure=struct_r, **per_run)
        src0s[r] = run_plan.model.src_pos0
        plans.append(run_plan)
    t_out = sample_times(duration, options.output_step)
    started = _time.perf_counter()
    batch = run_batch(plans, t_out, threads=threads)
    outs, status, t_stop, steps, flips = (batch.states, batch.status, batch.stop_time,
                                          batch.steps, batch.transitions)
    wall = _time.perf_counter() - started
    messages = [STATUS_TEXT[int(s)] if s == core.OK else
                f"{STATUS_TEXT[int(s)]} at t = {t_stop[r]:.6g} s" for r, s in enumerate(status)]
    sigma, speeds = engine.source_signals(t_out)
    n_state = layout.n_state
    table = {spec.name: spec for spec in catalogue(structure, ports=False,
                                                   controller=plan.controller)}
    return BatchResult(time=t_out, states=outs[:, :, :n_state],
                       control=outs[:, :, n_state:] if plan.controller is not None else None,
                       control_names=control_names(plan.controller),
                       state_names=state_names(structure),
                       success=status == core.OK, messages=messages, stop_time=t_stop,
                       steps=steps, transitions=flips, wall_time=wall, solver=solver,
                       structure=structure,
                       source_angles=sigma[None, :, :] + (src0s - base.src_pos0)[:, None, :],
                       source_speeds=speeds,
                       units={name: spec.unit for name, spec in table.items()},
                       descriptions={name: spec.description for name, spec in table.items()})

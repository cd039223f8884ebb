"""One entry point to simulate a network: `simulate`.

The model (a `vsj.network.Structure`), the solver (`vsj.engine`) and this
driver are separate: `simulate` compiles the structure with the run's inputs
and options, integrates, samples every signal on a uniform output grid, and
returns a `Result` that says whether the run succeeded, how, and where energy
went (`Result.ledger`).

Two solvers:

``dopri``
    adaptive Dormand-Prince 5(4), for friction laws that are functions of
    speed (viscous, arctan, sign, slope);
``timestep``
    fixed-step, linearly implicit, with exact Coulomb stiction impulses solved
    jointly for every element at each step (`vsj.engine.timestep`); required
    by the ``stiction`` law and usable with every other law.

``solver="auto"`` picks ``timestep`` when any element uses ``stiction``.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import asdict, dataclass, field
from typing import Mapping

import numpy as np

from . import friction as friction_laws
from .engine import STATUS_TEXT, Engine, Layout, compile_model, observation_layout
from .engine import core
from .engine.model import friction_laws_for
from .errors import InputError
from .inputs import Input
from .network import Signal, Structure


@dataclass(frozen=True)
class SimulationOptions:
    """How to simulate: friction law, solver and numerical knobs (SI units).

    ``slope_width`` is the report's ``w`` of fig 4.8 (a numerical knob, not a
    property of the prototype). ``rtol``/``atol`` steer ``dopri``; ``step`` is
    the fixed step of ``timestep``. ``output_step`` sets the sample grid.
    """

    friction: str = "arctan"
    friction_overrides: Mapping[str, str] = field(default_factory=dict)
    slope_width: float = 0.01
    solver: str = "auto"
    rtol: float = 1e-8
    atol: float = 1e-10
    max_step: float = math.inf
    step: float = 1e-3
    output_step: float = 1e-3
    max_steps: int = 20_000_000

    def validate(self) -> None:
        friction_laws.law_code(self.friction)
        if self.solver not in ("auto", "dopri", "timestep"):
            raise InputError(f"solver must be 'auto', 'dopri' or 'timestep', got {self.solver!r}")
        for name in ("slope_width", "rtol", "atol", "step", "output_step", "max_step"):
            value = getattr(self, name)
            if not (value > 0.0):
                raise InputError(f"option {name} must be > 0, got {value!r}")
        if self.max_steps < 1:
            raise InputError(f"option max_steps must be >= 1, got {self.max_steps!r}")


@dataclass(frozen=True)
class InitialState:
    """Initial angles and speeds of named flanges, pivot position and currents.

    Flanges not named start at rest in the reference configuration (or as
    close to it as the named ones allow). ``q`` [m] sets the pivot mechanism.
    """

    angles: Mapping[str, float] = field(default_factory=dict)
    speeds: Mapping[str, float] = field(default_factory=dict)
    q: float | None = None
    currents: Mapping[str, float] = field(default_factory=dict)


@dataclass
class Result:
    """Trajectory of every signal, energy ledger and solver report of one run."""

    time: np.ndarray
    signals: dict[str, np.ndarray]
    units: dict[str, str]
    ledger: dict
    success: bool
    message: str
    solver: dict
    transitions: dict[str, int] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.signals[name]
        except KeyError:
            raise KeyError(f"no signal {name!r}; signals include "
                           f"{', '.join(list(self.signals)[:12])}, ...") from None

    def columns(self) -> list[str]:
        return list(self.signals)

    def to_xarray(self):
        """The run as an `xarray.Dataset`: one variable per signal over ``time`` [s],
        each with its unit (``units``, as CF names it); the run's success, message
        and solver as attributes."""
        import xarray as xr

        from . import __version__

        data = {name: ("time", values, {"units": self.units[name]})
                for name, values in self.signals.items()}
        ds = xr.Dataset(data, coords={"time": ("time", self.time, {"units": "s"})})
        ds.attrs.update(success=int(self.success), message=self.message,
                        solver=str(self.solver.get("name", "")),
                        steps=int(self.solver.get("steps", 0)), vsj_version=__version__)
        return ds

    def summary(self) -> str:
        lines = [f"{'success' if self.success else 'FAILED'}: {self.message}",
                 f"solver {self.solver['name']}: {self.solver['steps']} steps in "
                 f"{self.solver['wall_time']:.3f} s"]
        led = self.ledger
        if led:
            lines.append(f"energy ledger: work in {led['total_in']:.6g} J = stored "
                         f"{led['total_stored']:.6g} J + dissipated {led['total_dissipated']:.6g} J"
                         f" + residual {led['residual']:.3g} J "
                         f"({led['relative_residual']:.2g} of the work done)")
        if self.transitions:
            lines.append(f"stick/slip transitions: {sum(self.transitions.values())}")
        return "\n".join(lines)


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


def choose_solver(structure: Structure, options: SimulationOptions) -> str:
    laws = friction_laws_for(structure, options.friction, options.friction_overrides)
    sticky = "stiction" in laws
    if options.solver == "dopri" and sticky:
        raise InputError("the stiction law needs the time-stepping solver (solver = "
                         "'timestep' or 'auto'); dopri integrates smooth laws only")
    if options.solver == "auto":
        return "timestep" if sticky else "dopri"
    return options.solver


def prepare(structure: Structure, inputs: Mapping[str, Input], duration: float,
            options: SimulationOptions, initial: InitialState,
            pivot_range: tuple[float, float] | None):
    """Compile the model and build the initial state vector."""
    if not (math.isfinite(duration) and duration > 0.0):
        raise InputError(f"duration must be > 0 s, got {duration!r}")
    options.validate()
    model, layout = compile_model(structure, inputs, duration, friction=options.friction,
                                  friction_overrides=options.friction_overrides,
                                  slope_width=options.slope_width, pivot_range=pivot_range)
    u0 = Engine(model).source_speeds(0.0)
    x0, v0, sigma0, currents = _initial(structure, inputs, initial, u0)
    model = model._replace(src_pos0=np.ascontiguousarray(sigma0, dtype=float))
    y0 = np.concatenate([x0, v0, currents, np.zeros(layout.n_acc)])
    return model, layout, y0


def simulate(structure: Structure, inputs: Mapping[str, Input], duration: float, *,
             options: SimulationOptions | None = None, initial: InitialState | None = None,
             pivot_range: tuple[float, float] | None = None, ports: bool = True) -> Result:
    """Simulate ``structure`` for ``duration`` seconds.

    ``inputs`` maps channel names to `vsj.inputs.Input` (missing channels are
    zero). ``pivot_range`` (q_min, q_max) [m] makes the run fail if the pivot
    leaves it. ``ports`` adds the torque and power of every connection.
    A failed run returns ``success=False`` with the time and state of the
    failure in ``message``; its samples up to the failure are kept.
    """
    options = options or SimulationOptions()
    initial = initial or InitialState()
    solver = choose_solver(structure, options)
    model, layout, y0 = prepare(structure, inputs, duration, options, initial, pivot_range)
    n_out = int(math.floor(duration / options.output_step + 1e-9)) + 1
    t_out = np.arange(n_out) * options.output_step
    if solver == "timestep":
        ratio = options.output_step / options.step
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            raise InputError(f"output_step ({options.output_step:g} s) must be a whole multiple "
                             f"of the time step ({options.step:g} s)")
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
    result = collect(structure, engine, layout, t_out, out, coulomb, stuck, ports=ports)
    result.transitions = {fr.name: int(flips[e]) for e, fr in enumerate(structure.frictions)
                          if flips[e]}
    if status == core.OK:
        result.success = True
        result.message = f"simulated {duration:g} s"
        result.ledger = ledger(structure, engine, layout, y0, y_end, duration)
    else:
        n_state = 2 * layout.n + layout.n_motors
        state = ", ".join(f"{name}={value:.6g}" for name, value in
                          zip(state_names(structure), y_end[:n_state]))
        result.success = False
        result.message = (f"{STATUS_TEXT[status]} at t = {t_stop:.6g} s; state: {state}")
        result.ledger = {}
    result.solver = report
    return result


def state_names(structure: Structure) -> list[str]:
    names = [f"{f}.angle" for f in structure.free] + [f"{f}.speed" for f in structure.free]
    return names + [f"{m.name}.current" for m in structure.motors]


def collect(structure: Structure, engine: Engine, layout: Layout, t_out, out, coulomb, stuck,
            *, ports: bool) -> Result:
    """Evaluate every signal at the samples (one compiled pass), then name them."""
    raw = engine.observe(t_out, out, coulomb)
    cols = observation_layout(layout)
    sig: dict[str, np.ndarray] = {}
    units: dict[str, str] = {}

    def put(name, values, unit):
        sig[name] = np.ascontiguousarray(values)
        units[name] = unit

    x, v = raw[:, cols["x"]], raw[:, cols["v"]]
    sigma, u = raw[:, cols["sigma"]], raw[:, cols["u"]]
    named = {s.flange for s in structure.signals}
    probes = list(structure.signals) + [Signal(f, f) for f in structure.free if f not in named]
    for s in probes:
        rx, ru = structure.rows(s.flange)
        put(s.name, x @ rx + sigma @ ru, "rad")
        put(f"{s.name}.speed", v @ rx + u @ ru, "rad/s")
    if structure.pivot.flange is not None or structure.springs:
        put("q", raw[:, cols["q"]][:, 0], "m")
        put("q.rate", raw[:, cols["qdot"]][:, 0], "m/s")
    for j, src in enumerate(structure.sources):
        put(f"source.{src.name}.speed", u[:, j], "rad/s")
        put(f"source.{src.name}.torque", raw[:, cols["src_tau"]][:, j], "N m")
        put(f"source.{src.name}.power", u[:, j] * raw[:, cols["src_tau"]][:, j], "W")
    for j, ld in enumerate(structure.loads):
        tau, speed = raw[:, cols["ld_tau"]][:, j], raw[:, cols["ld_w"]][:, j]
        put(f"load.{ld.name}.torque", tau, "N m")
        put(f"load.{ld.name}.power", tau * speed, "W")
    for j, mo in enumerate(structure.motors):
        cur, volt = raw[:, cols["current"]][:, j], raw[:, cols["mo_V"]][:, j]
        put(f"motor.{mo.name}.current", cur, "A")
        put(f"motor.{mo.name}.voltage", volt, "V")
        put(f"motor.{mo.name}.speed", raw[:, cols["mo_w"]][:, j], "rad/s")
        put(f"motor.{mo.name}.power", volt * cur, "W")
    slip, torque = raw[:, cols["fr_s"]], raw[:, cols["fr_f"]]
    for e, fr in enumerate(structure.frictions):
        put(f"friction.{fr.name}.torque", torque[:, e], "N m")
        put(f"friction.{fr.name}.power", -torque[:, e] * slip[:, e], "W")
        put(f"friction.{fr.name}.stuck", stuck[:, e].astype(float), "1")
    for k, sp in enumerate(structure.springs):
        put(f"spring.{sp.name}.deflection", raw[:, cols["sp_d"]][:, k], "rad")
        put(f"spring.{sp.name}.torque", raw[:, cols["sp_tau"]][:, k], "N m")
        put(f"spring.{sp.name}.stiffness", raw[:, cols["sp_k"]][:, k], "N m/rad")
        put(f"spring.{sp.name}.energy", raw[:, cols["sp_V"]][:, k], "J")
        put(f"spring.{sp.name}.power", raw[:, cols["sp_tau"]][:, k] * raw[:, cols["sp_dd"]][:, k],
            "W")
    if ports and len(t_out):
        for name, torque_c, power_c in port_flows(structure, raw, cols):
            put(f"port.{name}.torque", torque_c, "N m")
            put(f"port.{name}.power", power_c, "W")
    return Result(time=t_out, signals=sig, units=units, ledger={}, success=False, message="",
                  solver={})


def port_flows(structure: Structure, raw, cols):
    """Torque and power through every connection, from Newton's law per flange.

    With all element torques known, the constraint forces follow from
    ``I domega/dt - Q = E^T nu`` (``E``: every kinematic constraint and source
    row). A connection ``a -- b`` transmits ``nu`` into flange ``a``; its
    power is ``nu * omega_a``.
    """
    A, B, I = structure.A, structure.B, structure.inertia
    accel = raw[:, cols["a"]] @ A.T + raw[:, cols["ud"]] @ B.T
    speed = raw[:, cols["v"]] @ A.T + raw[:, cols["u"]] @ B.T
    applied = -raw[:, cols["fr_f"]] @ structure.friction_rows
    applied += raw[:, cols["sp_tau"]] @ structure.spring_rows
    for j, ld in enumerate(structure.loads):
        applied[:, structure.index(ld.flange)] += raw[:, cols["ld_tau"]][:, j]
    for j, mo in enumerate(structure.motors):
        applied[:, structure.index(mo.flange)] += mo.torque_constant * raw[:, cols["current"]][:, j]
    residual = accel * I - applied
    E = structure.constraint_rows
    nu = residual @ np.linalg.pinv(E.T).T
    flows = []
    for r, name in enumerate(structure.constraint_names):
        if not name.startswith("connection "):
            continue
        a, b = name[len("connection "):].split(" -- ")
        torque = nu[:, r]
        flows.append((f"{a}--{b}", torque, torque * speed[:, structure.index(a)]))
    return flows


def ledger(structure: Structure, engine: Engine, layout: Layout, y0, y_end, duration):
    """Energy balance of a run: work in = stored change + dissipated (+ residual)."""
    n_state = 2 * layout.n + layout.n_motors
    acc = y_end[n_state:]
    slices = layout.acc_slices()
    (kin0, pot0, ind0), spring_v0 = engine.stored_energy(0.0, y0[:n_state])
    (kin1, pot1, ind1), spring_v1 = engine.stored_energy(duration, y_end[:n_state])
    work_in = {}
    for j, src in enumerate(structure.sources):
        work_in[f"source {src.name}"] = float(acc[slices["sources"]][j])
    for j, ld in enumerate(structure.loads):
        work_in[f"load {ld.name}"] = float(acc[slices["loads"]][j])
    for j, mo in enumerate(structure.motors):
        work_in[f"motor {mo.name} (electric)"] = float(acc[slices["electric"]][j])
    pivot_work = float(np.sum(acc[slices["pivot"]]))
    if structure.pivot.flange is not None:
        work_in["pivot (non-backdrivable) on springs"] = pivot_work
    dissipated = {f"friction {fr.name}": float(acc[slices["friction"]][e])
                  for e, fr in enumerate(structure.frictions)}
    for j, mo in enumerate(structure.motors):
        dissipated[f"resistance {mo.name}"] = float(acc[slices["resistance"]][j])
    stored = {"kinetic": float(kin1 - kin0), "springs": float(pot1 - pot0),
              "inductors": float(ind1 - ind0)}
    nonconservative = {}
    from .components.elastic_element import GEOMETRIC_REPORT

    for k, sp in enumerate(structure.springs):
        if sp.law == GEOMETRIC_REPORT:
            dv = spring_v1[k] - spring_v0[k]
            w_spring = float(acc[slices["spring"]][k])
            w_pivot = float(acc[slices["pivot"]][k])
            nonconservative[f"spring {sp.name} (eq 3.8 is not a potential force)"] = float(
                w_pivot - w_spring - dv)
    total_in = sum(work_in.values())
    total_stored = sum(stored.values())
    total_diss = sum(dissipated.values()) + sum(nonconservative.values())
    residual = total_in - total_stored - total_diss
    scale = max(sum(abs(v) for v in work_in.values()), sum(abs(v) for v in dissipated.values()),
                abs(total_stored), 1e-300)
    return {"work_in": work_in, "stored_change": stored, "dissipated": dissipated,
            "nonconservative": nonconservative, "total_in": total_in,
            "total_stored": total_stored, "total_dissipated": total_diss,
            "residual": residual, "relative_residual": abs(residual) / scale}



@dataclass
class BatchResult:
    """States of many runs of one model, sampled on a common grid.

    ``states[r, k]`` is the state vector (angles, speeds, currents; see
    ``state_names``) of run ``r`` at ``time[k]``; `angle` and `speed` give any
    flange of the network for all runs.
    """

    time: np.ndarray
    states: np.ndarray
    state_names: list[str]
    success: np.ndarray
    messages: list[str]
    stop_time: np.ndarray
    steps: np.ndarray
    transitions: np.ndarray
    wall_time: float
    solver: str
    structure: Structure = field(repr=False)
    source_angles: np.ndarray = field(repr=False)
    source_speeds: np.ndarray = field(repr=False)

    def angle(self, flange: str) -> np.ndarray:
        """Angle [rad] of a flange, shape (runs, samples)."""
        rx, ru = self.structure.rows(flange)
        n = self.structure.n
        return self.states[:, :, :n] @ rx + self.source_angles @ ru

    def speed(self, flange: str) -> np.ndarray:
        """Speed [rad/s] of a flange, shape (runs, samples)."""
        rx, ru = self.structure.rows(flange)
        n = self.structure.n
        return self.states[:, :, n:2 * n] @ rx + (self.source_speeds @ ru)[None, :]


def simulate_batch(structure: Structure, inputs: Mapping[str, Input], duration: float, *,
                   initials: list[InitialState], options: SimulationOptions | None = None,
                   structures: list[Structure] | None = None,
                   pivot_range: tuple[float, float] | None = None,
                   threads: int | None = None) -> BatchResult:
    """Run one model many times in parallel, on every core.

    Each run starts from its own `InitialState` (a sweep over the pivot
    position, say); with ``structures`` (one per run, same topology) the runs
    may also differ in every parameter. All runs share inputs, duration and
    options. Only the states are integrated and sampled (no energy ledger); use
    `BatchResult.angle` and `speed`. ``threads`` (default: every core) share
    the runs; the results do not depend on their number.
    """
    options = options or SimulationOptions()
    if not initials:
        raise InputError("simulate_batch needs at least one initial state")
    if structures is not None and len(structures) != len(initials):
        raise InputError(f"simulate_batch: {len(structures)} structures for {len(initials)} runs")
    solver = choose_solver(structure, options)
    base, layout, _ = prepare(structure, inputs, duration, options, InitialState(), pivot_range)
    engine = Engine(base)
    u0 = engine.source_speeds(0.0)
    runs = len(initials)
    n_state = layout.n_state
    # dopri integrates the state only: batch runs keep no ledger, and the engine
    # then skips the elements that only the sources feel; the time-stepper's
    # vector keeps room for the accumulators, which batch runs leave unbooked
    y0s = np.zeros((runs, n_state if solver == "dopri" else n_state + layout.n_acc))
    src0s = np.zeros((runs, layout.n_sources))
    masses = np.repeat(base.mass[None], runs, axis=0)
    Minvs = np.repeat(base.Minv[None], runs, axis=0)
    pars = np.repeat(base.par[None], runs, axis=0)
    for r, initial in enumerate(initials):
        struct_r = structure if structures is None else structures[r]
        if structures is not None:
            m_r, layout_r = compile_model(struct_r, inputs, duration, friction=options.friction,
                                          friction_overrides=options.friction_overrides,
                                          slope_width=options.slope_width,
                                          pivot_range=pivot_range)
            if layout_r != layout or m_r.rows.shape != base.rows.shape:
                raise InputError(f"simulate_batch: structure {r} differs in topology")
            masses[r], Minvs[r], pars[r] = m_r.mass, m_r.Minv, m_r.par
        x0, v0, sigma0, currents = _initial(struct_r, inputs, initial, u0)
        y0s[r, :n_state] = np.concatenate([x0, v0, currents])
        src0s[r] = sigma0
    step = options.output_step
    n_out = int(math.floor(duration / step + 1e-9)) + 1
    t_out = np.arange(n_out) * step
    started = _time.perf_counter()
    outs, y_end, status, t_stop, steps, flips = core.run_batch(
        solver, engine, masses, Minvs, pars, src0s, y0s, duration, t_out, rtol=options.rtol,
        atol=options.atol, h_max=options.max_step, max_steps=options.max_steps, h=options.step,
        threads=threads)
    wall = _time.perf_counter() - started
    messages = [STATUS_TEXT[int(s)] if s == core.OK else
                f"{STATUS_TEXT[int(s)]} at t = {t_stop[r]:.6g} s" for r, s in enumerate(status)]
    sigma, speeds = engine.source_signals(t_out)
    return BatchResult(time=t_out, states=outs, state_names=state_names(structure),
                       success=status == core.OK, messages=messages, stop_time=t_stop,
                       steps=steps, transitions=flips, wall_time=wall, solver=solver,
                       structure=structure,
                       source_angles=sigma[None, :, :] + (src0s - base.src_pos0)[:, None, :],
                       source_speeds=speeds)

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


#: Sane ranges of the numerical settings (SI): outside them a run cannot be trusted
#: (a relative tolerance of 0.5 gives no accuracy at all) and is refused up front.
RANGES = {"rtol": (1e-14, 1e-2), "atol": (1e-20, 1e-2), "step": (1e-7, 0.05),
          "output_step": (1e-7, math.inf), "slope_width": (1e-12, 1e3),
          "max_step": (1e-9, math.inf), "ledger_tolerance": (1e-15, 1.0)}
#: A run fails when its energy ledger's residual exceeds this fraction of the energy
#: in play (the work done, the energy dissipated, or the energy the mechanism holds;
#: a sound run closes it to 1e-15 with the time-stepper, to about rtol with dopri;
#: the default tolerance of 1e-8 gives about 1e-11).
LEDGER_TOLERANCE = 1e-3
#: A spring pressed this far [rad] into its end stop has left what the parameter set
#: describes (a warning); ten turns past it, a run has diverged (a failure).
INTO_STOP = 0.1
DIVERGED = 20 * math.pi


@dataclass(frozen=True)
class SimulationOptions:
    """How to simulate: friction law, solver and numerical knobs (SI units).

    ``slope_width`` is the report's ``w`` of fig 4.8 (a numerical knob, not a
    property of the prototype). ``rtol``/``atol`` steer ``dopri``; ``step`` is
    the fixed step of ``timestep``. ``output_step`` sets the sample grid. A run
    whose energy ledger leaves a residual above ``ledger_tolerance`` (a fraction
    of the energy in play) is reported as failed. `RANGES` bounds every number.
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
    ledger_tolerance: float = LEDGER_TOLERANCE

    def validate(self) -> None:
        friction_laws.law_code(self.friction)
        if self.solver not in ("auto", "dopri", "timestep"):
            raise InputError(f"solver must be 'auto', 'dopri' or 'timestep', got {self.solver!r}")
        for name, (lo, hi) in RANGES.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not lo <= value <= hi:
                raise InputError(f"option {name} must be a number in [{lo:g}, {hi:g}], got "
                                 f"{value!r}")
        if isinstance(self.max_steps, bool) or not isinstance(self.max_steps, int) \
                or not 1 <= self.max_steps <= 10 ** 10:
            raise InputError(f"option max_steps must be a whole number in [1, 1e10], got "
                             f"{self.max_steps!r}")


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
    #: Where the run left what the parameter set describes (it still succeeded).
    warnings: list[str] = field(default_factory=list)

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
                         f"({led['relative_residual']:.2g} of the energy in play)")
        if self.transitions:
            lines.append(f"stick/slip transitions: {sum(self.transitions.values())}")
        lines += [f"warning: {text}" for text in self.warnings]
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


def rigid_stops(structure: Structure) -> list[str]:
    """Springs of ``structure`` whose end stop is rigid (infinite stiffness)."""
    from .springs import end_stop

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
    options = options or SimulationOptions()
    initial = initial or InitialState()
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
    result = collect(structure, engine, layout, t_out, out, coulomb, stuck, ports=ports)
    result.transitions = {fr.name: int(flips[e]) for e, fr in enumerate(structure.frictions)
                          if flips[e]}
    n_state = 2 * layout.n + layout.n_motors
    if status == core.OK:
        result.ledger = ledger(structure, engine, layout, y0, y_end, duration)
        problem = judge(structure, result, options)
        if problem is None:
            result.success = True
            result.message = f"simulated {duration:g} s"
        else:  # the run ended, but its result cannot be trusted
            when, reason = problem
            k = int(np.searchsorted(result.time, when))
            state = ", ".join(f"{name}={value:.6g}" for name, value in
                              zip(state_names(structure), out[min(k, len(out) - 1), :n_state]))
            result.success = False
            result.message = f"{reason} at t = {when:.6g} s; state: {state}"
    else:
        state = ", ".join(f"{name}={value:.6g}" for name, value in
                          zip(state_names(structure), y_end[:n_state]))
        result.success = False
        result.message = (f"{STATUS_TEXT[status]} at t = {t_stop:.6g} s; state: {state}")
        result.ledger = {}
    result.warnings = warnings_of(structure, result)
    result.solver = report
    return result


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


def _stop_angles(structure: Structure) -> dict[str, float]:
    from .springs import end_stop

    angles = {}
    for sp in structure.springs:
        stop = end_stop(sp.law, sp.parameters)
        if stop is not None and stop[0] > 0.0:
            angles[sp.name] = stop[0]
    return angles


def judge(structure: Structure, result: Result, options: SimulationOptions
          ) -> tuple[float, str] | None:
    """Why a run that ended cannot be trusted, with the time it shows: an energy
    ledger that does not close, or a spring `DIVERGED` past its end stop; None if
    neither."""
    for name, stop in _stop_angles(structure).items():
        past = np.abs(result[f"spring.{name}.deflection"]) - stop
        over = np.flatnonzero(past > DIVERGED)
        if over.size:
            k = int(over[0])
            return float(result.time[k]), (
                f"spring {name} deflected {past[k] + stop:.4g} rad, ten turns past its "
                f"{stop:.4g} rad end stop: the run diverged")
    residual = result.ledger.get("relative_residual", 0.0)
    if not residual <= options.ledger_tolerance:
        return float(result.time[-1]), (
            f"the energy ledger does not close: its residual is {residual:.3g} of the energy "
            f"in play, above the ledger tolerance {options.ledger_tolerance:g} (the numerical "
            f"settings are too coarse for this run: tighten rtol, or shorten the step)")
    return None


def warnings_of(structure: Structure, result: Result) -> list[str]:
    """Where a run left what the parameter set describes: a spring pressed more than
    `INTO_STOP` into its end stop, a DC motor above its voltage limit."""
    out = []
    for name, stop in _stop_angles(structure).items():
        deflection = result.signals.get(f"spring.{name}.deflection")
        if deflection is None or not len(deflection):
            continue
        k = int(np.argmax(np.abs(deflection)))
        if abs(deflection[k]) - stop > INTO_STOP:
            out.append(f"spring {name} was driven to {deflection[k]:.4g} rad at t = "
                       f"{result.time[k]:.4g} s, {abs(deflection[k]) - stop:.3g} rad past its "
                       f"{stop:.4g} rad end stop: the loads exceed what the mechanism takes")
    for mo in structure.motors:
        voltage = result.signals.get(f"motor.{mo.name}.voltage")
        if voltage is None or not len(voltage) or not math.isfinite(mo.voltage_limit):
            continue
        k = int(np.argmax(np.abs(voltage)))
        if abs(voltage[k]) > mo.voltage_limit:
            out.append(f"motor {mo.name} was driven at {voltage[k]:.4g} V at t = "
                       f"{result.time[k]:.4g} s, beyond its {mo.voltage_limit:g} V limit")
    return out


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
        put(f"friction.{fr.name}.slip", slip[:, e], "rad/s")
        # the resistive torque: the one exception to the port convention (vsj.ports)
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
    stops = acc[slices["stops"]]
    for k, sp in enumerate(structure.springs):
        if stops[k] != 0.0:
            dissipated[f"end stop {sp.name}"] = float(stops[k])
    stored = {"kinetic": float(kin1 - kin0), "springs": float(pot1 - pot0),
              "inductors": float(ind1 - ind0)}
    nonconservative = {}
    from .springs import GEOMETRIC_REPORT

    for k, sp in enumerate(structure.springs):
        if sp.law == GEOMETRIC_REPORT:
            dv = spring_v1[k] - spring_v0[k]
            w_spring = float(acc[slices["spring"]][k])
            w_pivot = float(acc[slices["pivot"]][k])
            nonconservative[f"spring {sp.name} (eq 3.8 is not a potential force)"] = float(
                w_pivot - w_spring - dv - stops[k])
    total_in = sum(work_in.values())
    total_stored = sum(stored.values())
    total_diss = sum(dissipated.values()) + sum(nonconservative.values())
    residual = total_in - total_stored - total_diss
    # the energy in play: what flowed in or out, or what the mechanism holds (a run
    # that rests under a load does almost no work, but its springs hold energy)
    held = max(abs(kin0) + abs(pot0) + abs(ind0), abs(kin1) + abs(pot1) + abs(ind1))
    scale = max(sum(abs(v) for v in work_in.values()), sum(abs(v) for v in dissipated.values()),
                abs(total_stored), held, 1e-300)
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


def simulate_batch(structure: Structure, inputs: Mapping[str, Input], duration: float, *,
                   initials: list[InitialState], options: SimulationOptions | None = None,
                   structures: list[Structure] | None = None,
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
    base, layout, _ = prepare(structure, inputs, duration, options, InitialState())
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
                                          slope_width=options.slope_width)
            _same_topology(base, layout, m_r, layout_r, r)
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

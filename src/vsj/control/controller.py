"""A sampled controller, declared in Python and run in the C engine.

A `Controller` runs every ``period`` seconds from the start of a run: it reads its
`Sensor` s, runs its blocks (`PID`, `Linear`) in order and sets its `Actuator` s, whose
values then hold until its next sample (zero-order hold) while the plant runs on its
own scheme (engine/c/control.c). Every signal of the controller has a name on one bus:
its references (`Controller.references`: input signals, read at each sample), its
sensors' readings, and its blocks' outputs. A block's input and an actuator's command
are a bus name or a weighted sum of names (``{"e_x": 1.0, "e_y": -1.0}``); a block reads
references, readings and the outputs of blocks before it.

`compile_controller` checks a controller against a network and gives the arrays the
engine takes; every refusal is an `InputError` naming the key at fault.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Mapping
from typing import Union

import numpy as np

from ..errors import InputError, finite_number
from ..inputs import as_inputs
from ..network import Structure

#: The most samples a controller's delay lines may hold, all its sensors together: the
#: C engine refuses any array longer than this (engine/c/blob.c, the binding's checks).
MAX_DELAY = 10 ** 8

#: A bus signal, or a weighted sum of bus signals.
Combination = Union[str, Mapping[str, float]]

#: What a sensor may measure, with the unit of its reading (engine: enum vsj_sensor).
QUANTITIES = {"angle": (0, "rad"), "speed": (1, "rad/s"), "current": (2, "A"),
              "q": (3, "m")}
#: Anti-windup schemes of a PID (engine: enum vsj_pid, column VSJ_PID_WINDUP).
ANTI_WINDUP = {"none": 0.0, "back-calculation": 1.0, "clamping": 2.0}

# the engine's row widths (c/vsj.h); the binding holds them too
N_CTL, N_MEAS, N_BLK, N_PID, N_ACT = 2, 4, 6, 10, 5


def _finite(value, name: str, *, low: float | None = None, strict: bool = False) -> float:
    return finite_number(name, value, low=low, strict=strict)


@dataclass(frozen=True)
class Sensor:
    """A measured signal: ``quantity`` (``angle`` [rad], ``speed`` [rad/s] of a flange or
    a named network signal, ``current`` [A] of a motor, ``q`` [m] the pivot position) of
    ``signal`` (a network signal such as ``theta_x``, a flange, or a motor's name; not
    needed for ``q``). The reading is the nearest multiple of ``resolution`` (an encoder
    of N counts per revolution: 2 pi / N rad; 0: exact), plus Gaussian noise of standard
    deviation ``noise`` (seeded by the controller's ``seed``), ``delay`` samples late.
    ``name`` is its name on the bus (default: ``signal``, or ``signal.quantity`` for a
    speed or a current, ``q`` for the pivot)."""

    signal: str = ""
    quantity: str = "angle"
    resolution: float = 0.0
    noise: float = 0.0
    delay: int = 0
    name: str = ""

    @property
    def label(self) -> str:
        """Its name on the bus."""
        if self.name:
            return self.name
        if self.quantity == "q":
            return "q"
        return self.signal if self.quantity == "angle" else f"{self.signal}.{self.quantity}"

    @staticmethod
    def encoder(signal: str, counts_per_revolution: int, **kwargs) -> "Sensor":
        """An incremental encoder on ``signal`` with this many counts per revolution."""
        counts = _finite(counts_per_revolution, f"sensor {signal!r}: counts per revolution",
                         low=0.0, strict=True)
        return Sensor(signal, "angle", resolution=2 * math.pi / counts, **kwargs)


@dataclass(frozen=True)
class PID:
    """A PID with the semantics of Modelica's ``LimPID``, sampled at the controller's
    period: output ``k (wp r - y + I + D) + feed_forward``, limited to ``[y_min, y_max]``,
    with ``I`` the integral of ``r - y`` over ``Ti`` seconds (``inf``: no integral action)
    and ``D`` the derivative of ``wd r - y`` through the filter ``Td s / (1 + s Td / Nd)``
    (``Td = 0``: none). While the output is limited, ``anti_windup`` ``back-calculation``
    feeds ``(limited - unlimited) / (k Ni)`` into the integrator, ``clamping`` stops it
    while the error would push further, ``none`` lets it wind up. ``setpoint``,
    ``measurement`` and ``feed_forward`` are bus combinations; the output is the bus
    signal ``name``, in the unit of what it drives (the gain's unit is that over the
    measurement's)."""

    name: str
    setpoint: Combination
    measurement: Combination
    k: float
    Ti: float = math.inf
    Td: float = 0.0
    Nd: float = 10.0
    wp: float = 1.0
    wd: float = 0.0
    y_min: float = -math.inf
    y_max: float = math.inf
    Ni: float = 0.9
    anti_windup: str = "back-calculation"
    feed_forward: Combination = field(default_factory=dict)

    def parameters(self, period: float) -> np.ndarray:
        """The engine's parameter row (enum vsj_pid), after checking each."""
        where = f"controller block {self.name!r}"
        k = _finite(self.k, f"{where}: k")
        Ti = float(self.Ti) if self.Ti == math.inf else _finite(self.Ti, f"{where}: Ti",
                                                                 low=0.0, strict=True)
        Td = _finite(self.Td, f"{where}: Td", low=0.0)
        Nd = _finite(self.Nd, f"{where}: Nd", low=0.0, strict=True)
        Ni = _finite(self.Ni, f"{where}: Ni", low=0.0, strict=True)
        wp, wd = _finite(self.wp, f"{where}: wp"), _finite(self.wd, f"{where}: wd")
        y_min, y_max = float(self.y_min), float(self.y_max)
        if math.isnan(y_min) or math.isnan(y_max) or not y_min <= y_max:
            raise InputError(f"{where}: y_min <= y_max needed, got {self.y_min!r}, "
                             f"{self.y_max!r}")
        if self.anti_windup not in ANTI_WINDUP:
            raise InputError(f"{where}: anti_windup must be one of {', '.join(ANTI_WINDUP)}, "
                             f"got {self.anti_windup!r}")
        if math.isfinite(Ti) and self.anti_windup == "back-calculation" \
                and period / (Ti * Ni) >= 1.0:
            raise InputError(f"{where}: the back-calculation's tracking time Ni Ti = "
                             f"{Ni * Ti:g} s is shorter than the period {period:g} s; the "
                             "sampled anti-windup would overshoot (raise Ni or Ti, or sample "
                             "faster)")
        return np.array([k, Ti, Td, Nd, wp, wd, y_min, y_max, Ni, ANTI_WINDUP[self.anti_windup]])


@dataclass(frozen=True)
class Linear:
    """Any discrete linear controller ``x+ = A x + B u, y = C x + D u``, run at the
    controller's period: ``system`` a python-control ``StateSpace`` or ``TransferFunction``
    with that sample time (a static gain may be a plain matrix ``D``). ``inputs`` are bus
    combinations (one per input of the system), ``outputs`` the names of its outputs on
    the bus. A system whose own poles lie outside the unit circle is refused (most
    often a continuous design's coefficients given as discrete ones) unless
    ``allow_unstable``: some stable loops need a compensator unstable on its own (an
    observer-based design; `vsj.control.design` checks its loop and sets it). Poles on
    the circle (an integrator) are allowed."""

    name: str
    system: object
    inputs: tuple
    outputs: tuple
    allow_unstable: bool = False

    def matrices(self, period: float) -> tuple[np.ndarray, ...]:
        """``(A, B, C, D)`` checked: sample time equal to the period, sizes that match the
        inputs and outputs, finite entries, a stable state matrix."""
        import control  # lazy: python-control takes ~1 s to import; only Linear blocks need it

        where = f"controller block {self.name!r}"
        system = self.system
        if isinstance(system, (np.ndarray, list, tuple)) and not hasattr(system, "dt"):
            D = np.atleast_2d(np.asarray(system, dtype=float))
            A = np.zeros((0, 0))
            B, C = np.zeros((0, D.shape[1])), np.zeros((D.shape[0], 0))
        elif isinstance(system, (control.StateSpace, control.TransferFunction)):
            dt = system.dt
            if dt is None or dt is True or dt == 0:
                raise InputError(f"{where}: the system is continuous (dt = {dt!r}); discretise "
                                 f"it at the controller's period {period:g} s first "
                                 "(control.c2d or sample_system)")
            if abs(float(dt) - period) > 1e-9 * period:
                raise InputError(f"{where}: the system's sample time {float(dt):g} s differs "
                                 f"from the controller's period {period:g} s")
            ss = control.ss(system) if isinstance(system, control.TransferFunction) else system
            A, B, C, D = (np.atleast_2d(np.asarray(m, dtype=float)) for m in
                          (ss.A, ss.B, ss.C, ss.D))
            n = ss.nstates
            A, B, C = A.reshape(n, n), B.reshape(n, ss.ninputs), C.reshape(ss.noutputs, n)
            D = D.reshape(ss.noutputs, ss.ninputs)
        else:
            raise InputError(f"{where}: system must be a python-control StateSpace or "
                             f"TransferFunction with a sample time, or a gain matrix, got "
                             f"{type(system).__name__}")
        if D.shape != (len(self.outputs), len(self.inputs)):
            raise InputError(f"{where}: the system has {D.shape[1]} inputs and {D.shape[0]} "
                             f"outputs; the block names {len(self.inputs)} inputs and "
                             f"{len(self.outputs)} outputs")
        for name, m in zip("ABCD", (A, B, C, D)):
            if not np.all(np.isfinite(m)):
                raise InputError(f"{where}: matrix {name} is not finite")
        # the circle's own poles (integrators) come out of a conversion to state space
        # within a few ulps of modulus 1
        radius = np.max(np.abs(np.linalg.eigvals(A))) if A.size else 0.0
        if radius > 1.0 + 1e-9 and not self.allow_unstable:
            raise InputError(f"{where}: the controller itself is unstable (an eigenvalue of A "
                             f"of modulus {radius:.6g} > 1; a continuous design's coefficients "
                             "given as discrete?); if the loop it closes is stable, say "
                             "allow_unstable=True")
        return A, B, C, D


@dataclass(frozen=True)
class Actuator:
    """What the controller drives: input ``channel`` (a motor's voltage [V] or a load's
    torque [N m]) takes ``command`` (a bus combination) plus ``offset``, clipped to
    ``limits``; ``current_limit`` [A] (a motor's channel only) bounds the voltage so that
    the steady current ``(V - k_t omega) / R`` at the motor's speed stays within it. A
    motor's own ``voltage_limit`` (parameter file) is its default limit."""

    channel: str
    command: Combination
    offset: float = 0.0
    limits: tuple | None = None
    current_limit: float = math.inf


Block = Union[PID, Linear]


@dataclass(frozen=True)
class Controller:
    """A sampled controller: its ``period`` [s], ``sensors``, ``blocks`` (run in order),
    ``actuators``, ``references`` (bus name -> `vsj.inputs.Input` or number), the
    ``seed`` of its sensors' noise and, optionally, the ``units`` of bus signals (name ->
    unit, for the results; a sensor's reading has its quantity's unit without it)."""

    period: float
    actuators: tuple
    sensors: tuple = ()
    blocks: tuple = ()
    references: Mapping[str, object] = field(default_factory=dict)
    seed: int = 0
    units: Mapping[str, str] = field(default_factory=dict)

    def bus(self) -> list[str]:
        """Names on the bus, in order: references, readings, blocks' outputs."""
        names = list(self.references) + [s.label for s in self.sensors]
        for b in self.blocks:
            names += [b.name] if isinstance(b, PID) else list(b.outputs)
        return names


@dataclass(frozen=True)
class CompiledController:
    """A controller checked against a network: the engine's arrays (`arrays`, named as
    in c/vsj_layout.h), its sizes, its references as input channels (``ref.<name>``),
    and the names and units of its bus and actuators for the results."""

    sizes: dict
    arrays: dict
    references: dict
    bus: tuple
    units: tuple
    channels: tuple          # the channel each actuator drives
    period: float
    channel_units: tuple = ()  # the unit of each actuator's channel

    @property
    def width(self) -> int:
        """Columns a sample row gains (vsj_control_width)."""
        return len(self.bus) + len(self.channels)


def _row(combination: Combination, bus: Mapping[str, int], where: str) -> np.ndarray:
    row = np.zeros(len(bus))
    terms = {combination: 1.0} if isinstance(combination, str) else combination
    if not isinstance(terms, Mapping):
        raise InputError(f"{where}: must be a bus signal's name or a mapping of names to "
                         f"weights, got {combination!r}")
    for name, weight in terms.items():
        if name not in bus:
            raise InputError(f"{where}: unknown signal {name!r}; the bus has "
                             f"{', '.join(bus) or 'nothing'} before it")
        row[bus[name]] += _finite(weight, f"{where}: weight of {name!r}")
    return row


def _sensor_arrays(sensor: Sensor, structure: Structure, where: str):
    """(kind, row over x and sigma, parameter row) of a sensor; the unit of its reading."""
    if sensor.quantity not in QUANTITIES:
        raise InputError(f"{where}: quantity must be one of {', '.join(QUANTITIES)}, got "
                         f"{sensor.quantity!r}")
    kind, unit = QUANTITIES[sensor.quantity]
    row = np.zeros(structure.n + len(structure.sources))
    motor = 0.0
    if sensor.quantity == "current":
        names = [m.name for m in structure.motors]
        if sensor.signal not in names:
            raise InputError(f"{where}: {sensor.signal!r} is not a motor; motors: "
                             f"{', '.join(names) or 'none'}")
        motor = float(names.index(sensor.signal))
    elif sensor.quantity == "q":
        if structure.pivot.flange is None and not structure.springs:
            raise InputError(f"{where}: network {structure.name!r} has no pivot to measure")
    else:
        flanges = {s.name: s.flange for s in structure.signals}
        flange = flanges.get(sensor.signal, sensor.signal)
        try:
            rx, ru = structure.rows(flange)
        except (KeyError, ValueError, InputError):
            raise InputError(f"{where}: unknown signal {sensor.signal!r}; the network's "
                             f"signals: {', '.join(flanges)}") from None
        row = np.concatenate([rx, ru])
    resolution = _finite(sensor.resolution, f"{where}: resolution", low=0.0)
    noise = _finite(sensor.noise, f"{where}: noise", low=0.0)
    if not isinstance(sensor.delay, (int, np.integer)) or isinstance(sensor.delay, bool) \
            or not 0 <= sensor.delay <= MAX_DELAY:
        raise InputError(f"{where}: delay must be a whole number of samples in 0..{MAX_DELAY}, "
                         f"got {sensor.delay!r}")
    return kind, row, np.array([resolution, noise, float(sensor.delay), motor]), unit


def _actuator_arrays(act: Actuator, structure: Structure, bus: Mapping[str, int],
                     where: str):
    motors = {m.channel: (j, m) for j, m in enumerate(structure.motors)}
    loads = {ld.channel for ld in structure.loads}
    if act.channel not in motors and act.channel not in loads:
        sources = {s.channel for s in structure.sources}
        hint = (" (a velocity source: the controller drives voltages or torques; build the "
                "network with DC motors)" if act.channel in sources else "")
        raise InputError(f"{where}: {act.channel!r} is not a motor's voltage or a load's "
                         f"torque{hint}; allowed: {', '.join(sorted(motors) + sorted(loads))}")
    index, motor = motors.get(act.channel, (-1, None))
    if act.limits is None:
        rated = motor.voltage_limit if motor is not None else math.inf
        lo, hi = -rated, rated
    else:
        try:
            lo, hi = (float(v) for v in act.limits)
        except (TypeError, ValueError):
            raise InputError(f"{where}: limits must be a pair (low, high), got "
                             f"{act.limits!r}") from None
        if math.isnan(lo) or math.isnan(hi) or not lo < hi:
            raise InputError(f"{where}: limits need low < high, got {act.limits!r}")
    current = float(act.current_limit)
    if not current > 0.0:
        raise InputError(f"{where}: current_limit must be > 0 A, got {act.current_limit!r}")
    if math.isfinite(current) and motor is None:
        raise InputError(f"{where}: a current limit needs a motor's channel; {act.channel!r} "
                         "is a load's torque (limit it by `limits`)")
    row = _row(act.command, bus, f"{where}: command")
    par = np.array([_finite(act.offset, f"{where}: offset"), lo, hi, current, float(index)])
    return row, par, ("V" if motor is not None else "N m")


def compile_controller(controller: Controller, structure: Structure,
                       channels: tuple[str, ...]) -> CompiledController:
    """``controller`` checked against ``structure`` (whose input channels are
    ``channels``, references appended after them): the engine's arrays."""
    if not isinstance(controller, Controller):
        raise InputError(f"controller must be a vsj.control.Controller, got "
                         f"{type(controller).__name__}")
    period = _finite(controller.period, "controller period", low=0.0, strict=True)
    seed = controller.seed
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or not 0 <= seed < 2 ** 53:
        raise InputError(f"controller seed must be a whole number in 0 .. 2^53, got {seed!r}")
    if not controller.actuators:
        raise InputError("controller: it drives nothing; give at least one actuator")
    refs = as_inputs(dict(controller.references), tuple(controller.references))
    for name, signal in refs.items():
        if signal.is_position:
            raise InputError(f"controller reference {name!r}: give the reference's value "
                             "itself (not Position)")
    names = controller.bus()
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"controller: names used twice on its bus: {', '.join(dup)}")
    units = ["1"] * len(refs)
    kinds, meas_rows, meas_par = [], [], []
    for i, sensor in enumerate(controller.sensors):
        if not isinstance(sensor, Sensor):
            raise InputError(f"controller sensor {i}: must be a vsj.control.Sensor, got "
                             f"{type(sensor).__name__}")
        kind, row, par, unit = _sensor_arrays(sensor, structure, f"controller sensor "
                                              f"{sensor.label!r}")
        kinds.append(kind)
        meas_rows.append(row)
        meas_par.append(par)
        units.append(unit)
    held = sum(int(s.delay) for s in controller.sensors)
    if held > MAX_DELAY:
        raise InputError(f"the controller's sensors' delays add up to {held} samples; its "
                         f"delay lines may hold at most {MAX_DELAY} together")
    known = {name: i for i, name in enumerate(names[:len(refs) + len(controller.sensors)])}
    width = len(names)
    blk, blk_in, blk_par, n_state = [], [], [], 0
    for block in controller.blocks:
        where = f"controller block {getattr(block, 'name', block)!r}"
        if isinstance(block, PID):
            rows = [_row(block.setpoint, known, f"{where}: setpoint"),
                    _row(block.measurement, known, f"{where}: measurement"),
                    _row(block.feed_forward, known, f"{where}: feed_forward")]
            par, outputs, states, kind = block.parameters(period), [block.name], 2, 0
        elif isinstance(block, Linear):
            rows = [_row(c, known, f"{where}: input {j}") for j, c in enumerate(block.inputs)]
            A, B, C, D = block.matrices(period)
            par = np.concatenate([m.reshape(-1) for m in (A, B, C, D)])
            outputs, states, kind = list(block.outputs), A.shape[0], 1
        else:
            raise InputError(f"{where}: a block must be a vsj.control.PID or Linear, got "
                             f"{type(block).__name__}")
        blk.append([kind, len(rows), len(outputs), states, sum(len(p) for p in blk_par),
                    len(blk_in)])
        blk_in += [np.pad(r, (0, width - len(r))) for r in rows]
        blk_par.append(par)
        n_state += states
        for name in outputs:
            known[name] = len(known)
            units.append("1")
    act_ch, act_rows, act_par, act_units = [], [], [], []
    for act in controller.actuators:
        if not isinstance(act, Actuator):
            raise InputError(f"controller actuator: must be a vsj.control.Actuator, got "
                             f"{type(act).__name__}")
        row, par, unit = _actuator_arrays(act, structure, known, f"controller actuator "
                                          f"{act.channel!r}")
        if channels.index(act.channel) in act_ch:
            raise InputError(f"controller: two actuators drive {act.channel!r}")
        act_ch.append(channels.index(act.channel))
        act_rows.append(row)
        act_par.append(par)
        act_units.append(unit)
    n_net = len(channels)
    arrays = {
        "ctl": np.array([period, float(seed)]),
        "ref_ch": np.arange(n_net, n_net + len(refs), dtype=np.int64),
        "meas_kind": np.array(kinds, dtype=np.int64),
        "meas_row": np.array(meas_rows, dtype=float).reshape(-1),
        "meas_par": np.array(meas_par, dtype=float).reshape(-1),
        "blk": np.array(blk, dtype=np.int64).reshape(-1),
        "blk_in": np.array(blk_in, dtype=float).reshape(-1),
        "blk_par": np.concatenate(blk_par) if blk_par else np.zeros(0),
        "act_ch": np.array(act_ch, dtype=np.int64),
        "act_row": np.array(act_rows, dtype=float).reshape(-1),
        "act_par": np.array(act_par, dtype=float).reshape(-1),
    }
    sizes = dict(n_refs=len(refs), n_meas=len(kinds), n_blocks=len(blk), n_acts=len(act_ch),
                 n_bus=width, n_cstate=n_state,
                 n_delay=held,
                 n_blk_in=len(blk_in), n_blk_par=int(arrays["blk_par"].size))
    given = dict(controller.units)
    unknown = sorted(set(given) - set(names))
    if unknown:
        raise InputError(f"controller units: no bus signal {', '.join(map(repr, unknown))}; the "
                         f"bus has {', '.join(names)}")
    units = [given.get(name, unit) for name, unit in zip(names, units)]
    return CompiledController(sizes=sizes, arrays=arrays,
                              references={f"ref.{k}": v for k, v in refs.items()},
                              bus=tuple(names), units=tuple(units),
                              channels=tuple(a.channel for a in controller.actuators),
                              period=period, channel_units=tuple(act_units))


#: The engine's arrays and sizes of a model without a controller.
NO_CONTROLLER_SIZES = dict(n_refs=0, n_meas=0, n_blocks=0, n_acts=0, n_bus=0, n_cstate=0,
                           n_delay=0, n_blk_in=0, n_blk_par=0)
NO_CONTROLLER_ARRAYS = {
    "ctl": np.zeros(0), "ref_ch": np.zeros(0, dtype=np.int64),
    "meas_kind": np.zeros(0, dtype=np.int64), "meas_row": np.zeros(0),
    "meas_par": np.zeros(0), "blk": np.zeros(0, dtype=np.int64), "blk_in": np.zeros(0),
    "blk_par": np.zeros(0), "act_ch": np.zeros(0, dtype=np.int64), "act_row": np.zeros(0),
    "act_par": np.zeros(0)}

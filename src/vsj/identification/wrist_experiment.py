"""Experiments on the whole wrist: what drives it, and how its sensors record it.

An experiment file (TOML, written by ``vsj excite``, read by ``vsj synth
wrist``) says which signals drive the wrist and what sensors record it::

    [experiment]
    description = "Ds-optimal excitation for 8 parameters"
    duration = "20 s"
    sample_period = "1 ms"
    motors = "velocity"          # velocity sources (speeds) or dc (voltages)
    elastic = "geometric"
    q = "0.5 cm"                 # pivot position at the start

    [signals.motor_1]            # rad/s with velocity sources, V with DC motors
    multisine = { frequency = [0.3, 1.1], amplitude = [2.0, 1.0], phase = [0.0, 1.2] }
    [signals.tau_x]              # N m on the end-effector
    pulses = { start = [2.0, 6.0], width = 0.3, height = [0.05, -0.05] }
    [signals.q]                  # pivot position steps [m], moved by the pivot motor
    steps = { time = [8.0], value = [-0.01] }

    [sensors]                    # the artefacts of `vsj.synth.wrist`
    encoder_counts = 16384
    angle_noise = "0.2 mrad"
    time_offset = "0.2 ms"       # end-effector channels behind the motor channels
    ...

Inside a component, numbers are SI (rad/s, V, N m, m, s) and frequencies Hz.
Every motor signal fades in over `FADE` so the wrist starts from rest.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import tomli_w

from .. import synth
from ..errors import InputError, read_text
from ..measurements import Measurement
from ..units import format_quantity, to_si
from .wrist_model import Setup, WristModel

#: Motor signals rise smoothly (quintic smoothstep) over this time [s] from rest.
FADE = 0.5
#: A step of q is a smooth ramp of this duration [s] (the pivot motor's speed stays finite).
Q_RAMP = 0.3
CHANNELS = ("motor_1", "motor_2", "voltage_1", "voltage_2", "tau_x", "tau_y", "q")
COMPONENTS = {"multisine": ("frequency", "amplitude", "phase"),
              "chirp": ("start_frequency", "end_frequency", "amplitude"),
              "sine": ("frequency", "amplitude"),
              "pulses": ("start", "width", "height"),
              "steps": ("time", "value")}


@dataclass(frozen=True)
class Sensors:
    """Artefacts of the recording (SI): encoder counts per turn, white noise of angles,
    currents, torques and q, a current sensor offset, the end-effector channels' delay
    behind the motor channels, and the sample clock's jitter (sd).

    ``time_offset`` [s]: the end-effector angles logged at time t are the wrist's at
    t - time_offset, so a positive offset puts them behind the motor channels (a lag,
    which ``vsj fit wrist`` reports as a positive delay) and a negative one ahead. Its
    size is below the experiment's duration. ``jitter`` stays below a tenth of the
    sample period, so that the sample times keep their order.
    """

    encoder_counts: int = 16384
    angle_noise: float = 2e-4
    current_noise: float = 5e-3
    current_offset: float = 0.02
    torque_noise: float = 1e-4
    q_noise: float = 1e-5
    time_offset: float = 2e-4
    jitter: float = 2e-5

    def artefacts(self) -> str:
        """The recording's artefacts in one sentence (for the log's comments)."""
        return (f"encoder quantisation ({self.encoder_counts} counts per turn), white noise "
                f"(angles {self.angle_noise:g} rad, currents {self.current_noise:g} A, torques "
                f"{self.torque_noise:g} N m, q {self.q_noise:g} m), current sensor offset "
                f"{self.current_offset:g} A, end-effector channels {abs(self.time_offset):g} s "
                f"{'ahead of' if self.time_offset < 0 else 'behind'} the motor channels, "
                f"sample-time jitter sd {self.jitter:g} s")


_SENSOR_UNITS = {"angle_noise": "rad", "current_noise": "A", "current_offset": "A",
                 "torque_noise": "N*m", "q_noise": "m", "time_offset": "s", "jitter": "s"}


@dataclass(frozen=True)
class Experiment:
    """Duration and sample period [s], wrist options, start pivot position [m], the
    signals (channel -> components) and the sensors."""

    duration: float
    signals: Mapping[str, tuple[tuple[str, Mapping[str, object]], ...]]
    sample_period: float = 1e-3
    motors: str = "velocity"
    elastic: str = "geometric"
    q: float = 0.0
    description: str = ""
    sensors: Sensors = field(default_factory=Sensors)
    step: float = 5e-4
    origin: str = "<experiment>"

    def value(self, channel: str, t) -> np.ndarray:
        """The channel's command at times ``t`` [s] (SI; q in m)."""
        t = np.asarray(t, dtype=float)
        out = np.zeros_like(t)
        for kind, spec in self.signals.get(channel, ()):
            out = out + _component(kind, spec, t, self.duration)
        if channel == "q":
            return self.q + out
        if channel.startswith(("motor_", "voltage_")):
            z = np.clip(t / FADE, 0.0, 1.0)
            out = out * z ** 3 * (10.0 - 15.0 * z + 6.0 * z * z)
        return out

    def to_toml(self) -> str:
        """The experiment as the text of an experiment file (TOML, with units)."""
        s = self.sensors
        doc = {"experiment": {"description": self.description,
                              "duration": format_quantity(self.duration, "s", digits=10),
                              "sample_period": format_quantity(self.sample_period, "ms",
                                                               digits=10),
                              "motors": self.motors, "elastic": self.elastic,
                              "q": format_quantity(self.q, "cm", digits=10)},
               "signals": {ch: {kind: _plain(spec) for kind, spec in comps}
                           for ch, comps in self.signals.items()},
               "sensors": {"encoder_counts": s.encoder_counts,
                           **{k: format_quantity(getattr(s, k), u.replace("*", " "), digits=8)
                              for k, u in _SENSOR_UNITS.items()}},
               "simulation": {"step": format_quantity(self.step, "ms", digits=10)}}
        return ("# vsj experiment on the whole wrist: inputs and sensors (see vsj.identification"
                ".wrist_experiment)\n" + tomli_w.dumps(doc))


def _plain(spec):
    return {k: (list(map(float, v)) if isinstance(v, (list, tuple, np.ndarray)) else float(v))
            for k, v in spec.items()}


#: Per component: the keys that are lists (of one length, one entry per term) and those
#: that are single numbers; frequencies and widths must be > 0.
_SHAPES = {"multisine": (("frequency", "amplitude", "phase"), ()),
           "chirp": ((), ("start_frequency", "end_frequency", "amplitude")),
           "sine": ((), ("frequency", "amplitude")),
           "pulses": (("start", "height"), ("width",)),
           "steps": (("time", "value"), ())}
_POSITIVE = ("frequency", "start_frequency", "end_frequency", "width")


def _check_component(kind: str, spec: Mapping, where: str) -> None:
    """`InputError` unless ``spec`` has the shape its ``kind`` needs (`_SHAPES`)."""
    lists, numbers = _SHAPES[kind]
    extra = sorted(set(spec) - set(lists) - set(numbers))
    if extra:
        raise InputError(f"{where}.{extra[0]}: unknown key; {kind} takes "
                         f"{', '.join(lists + numbers)}")
    for key in numbers:
        if not isinstance(spec[key], float):
            raise InputError(f"{where}.{key} = {[float(v) for v in spec[key]]!r}: a single "
                             "number")
    for key in lists:
        if not isinstance(spec[key], tuple):
            raise InputError(f"{where}.{key} = {spec[key]!r}: a list of numbers, one per term")
    lengths = {key: len(spec[key]) for key in lists}
    if len(set(lengths.values())) > 1:
        raise InputError(f"{where}: {', '.join(f'{k} has {n}' for k, n in lengths.items())} "
                         "entries; each term needs one of each")
    for key in _POSITIVE:
        if key in spec and not np.all(np.asarray(spec[key]) > 0.0):
            raise InputError(f"{where}.{key} = {spec[key]!r}: must be > 0")
    if kind == "steps" and np.any(np.diff(spec["time"]) <= 0.0):
        raise InputError(f"{where}.time = {list(spec['time'])!r}: times must increase")


def _smoothstep(z):
    z = np.clip(z, 0.0, 1.0)
    return z ** 3 * (10.0 - 15.0 * z + 6.0 * z * z)


def _component(kind: str, spec: Mapping, t: np.ndarray, duration: float) -> np.ndarray:
    if kind == "multisine":
        out = np.zeros_like(t)
        for f, a, p in zip(spec["frequency"], spec["amplitude"], spec["phase"]):
            out += a * np.sin(2 * math.pi * f * t + p)
        return out
    if kind == "sine":
        return spec["amplitude"] * np.sin(2 * math.pi * spec["frequency"] * t)
    if kind == "chirp":
        f0, f1 = spec["start_frequency"], spec["end_frequency"]
        k = (f1 - f0) / duration  # from f0 at the start to f1 at the end
        return spec["amplitude"] * np.sin(2 * math.pi * (f0 * t + 0.5 * k * t * t))
    if kind == "pulses":
        out = np.zeros_like(t)
        width = spec["width"]
        edge = min(0.05, width / 4)
        for start, height in zip(spec["start"], spec["height"]):
            out += height * (_smoothstep((t - start) / edge)
                             - _smoothstep((t - start - width) / edge))
        return out
    if kind == "steps":
        out = np.zeros_like(t)
        level = 0.0
        for time, value in zip(spec["time"], spec["value"]):
            out += (value - level) * _smoothstep((t - time) / Q_RAMP)
            level = value
        return out
    raise InputError(f"unknown signal component {kind!r}")


def load(path) -> Experiment:
    """Read and check an experiment file; `InputError` names the file and the key."""
    origin = str(path)
    try:
        doc = tomllib.loads(read_text(path, "experiment file"))
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{origin}: not valid TOML: {exc}") from None
    return from_table(doc, origin)


def from_table(doc: Mapping, origin: str) -> Experiment:
    """An `Experiment` from a parsed experiment file ``doc``; `InputError` naming ``origin``
    and the key for anything missing, unknown or out of range."""
    unknown = set(doc) - {"experiment", "signals", "sensors", "simulation"}
    if unknown:
        raise InputError(f"{origin}: unknown table(s) {', '.join(sorted(unknown))}; allowed: "
                         "experiment, signals, sensors, simulation")
    head = doc.get("experiment")
    if not isinstance(head, Mapping):
        raise InputError(f"{origin}: missing [experiment] table (duration, motors, ...)")

    def quantity(table, key, unit, where, default=None, positive=False):
        if key not in table:
            if default is None:
                raise InputError(f"{origin}: {where}.{key}: missing")
            return default
        value = to_si(table[key], unit, where=f"{origin}: {where}.{key}")
        if positive and not value > 0:
            raise InputError(f"{origin}: {where}.{key} = {table[key]!r}: must be > 0")
        return value

    allowed = {"description", "duration", "sample_period", "motors", "elastic", "q"}
    extra = set(head) - allowed
    if extra:
        raise InputError(f"{origin}: experiment.{min(extra)}: unknown key; allowed: "
                         f"{', '.join(sorted(allowed))}")
    duration = quantity(head, "duration", "s", "experiment", positive=True)
    period = quantity(head, "sample_period", "s", "experiment", 1e-3, positive=True)
    if duration / period > 5e6:
        raise InputError(f"{origin}: experiment: {duration / period:.3g} samples; at most 5e6")
    motors = head.get("motors", "velocity")
    if motors not in ("velocity", "dc"):
        raise InputError(f"{origin}: experiment.motors = {motors!r}: velocity or dc")
    elastic = str(head.get("elastic", "geometric"))
    q = quantity(head, "q", "m", "experiment", 0.0)
    signals = {}
    for channel, comps in (doc.get("signals") or {}).items():
        if channel not in CHANNELS:
            raise InputError(f"{origin}: signals.{channel}: unknown channel; channels: "
                             f"{', '.join(CHANNELS)}")
        if not isinstance(comps, Mapping):
            raise InputError(f"{origin}: signals.{channel} must be a table of components")
        out = []
        for kind, spec in comps.items():
            where = f"{origin}: signals.{channel}.{kind}"
            if kind not in COMPONENTS or not isinstance(spec, Mapping):
                raise InputError(f"{where}: unknown component; components: "
                                 f"{', '.join(COMPONENTS)}")
            keys = COMPONENTS[kind]
            missing = [k for k in keys if k not in spec]
            if missing:
                raise InputError(f"{where}: missing {', '.join(missing)}")
            clean = {}
            for k, v in spec.items():
                arr = np.atleast_1d(np.asarray(v, dtype=float)) if isinstance(v, list) else None
                if arr is not None:
                    if not np.all(np.isfinite(arr)):
                        raise InputError(f"{where}.{k}: every number must be finite")
                    clean[k] = tuple(arr)
                elif isinstance(v, (int, float)) and math.isfinite(v):
                    clean[k] = float(v)
                else:
                    raise InputError(f"{where}.{k} = {v!r}: a number or a list of numbers")
            _check_component(kind, clean, where)
            out.append((kind, clean))
        signals[channel] = tuple(out)
    need = ("motor_1", "motor_2") if motors == "velocity" else ("voltage_1", "voltage_2")
    wrong = [c for c in signals if c.startswith(("motor_", "voltage_")) and c not in need]
    if wrong:
        raise InputError(f"{origin}: signals.{wrong[0]}: with {motors} motors the motor "
                         f"channels are {', '.join(need)}")
    sensor_table = doc.get("sensors") or {}
    sensors = Sensors()
    values = {}
    for k, v in sensor_table.items():
        if k == "encoder_counts":
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise InputError(f"{origin}: sensors.encoder_counts = {v!r}: a whole number "
                                 ">= 1")
            values[k] = v
        elif k in _SENSOR_UNITS:
            values[k] = quantity(sensor_table, k, _SENSOR_UNITS[k], "sensors")
            if k == "time_offset":
                if not abs(values[k]) < duration:
                    raise InputError(f"{origin}: sensors.time_offset = {v!r}: its size must be "
                                     f"below the duration ({duration:g} s); positive: the "
                                     "end-effector channels lag the motor channels, negative: "
                                     "they lead")
            elif values[k] < 0:
                raise InputError(f"{origin}: sensors.{k}: must be >= 0")
            if k == "jitter" and not values[k] < 0.1 * period:
                raise InputError(f"{origin}: sensors.jitter = {v!r}: must be below a tenth of "
                                 f"the sample period ({0.1 * period:g} s), so that sample "
                                 "times keep their order")
        else:
            raise InputError(f"{origin}: sensors.{k}: unknown key; allowed: encoder_counts, "
                             f"{', '.join(_SENSOR_UNITS)}")
    sensors = replace(sensors, **values)
    step = quantity(doc.get("simulation") or {}, "step", "s", "simulation", 5e-4, positive=True)
    return Experiment(duration=duration, signals=signals, sample_period=period, motors=motors,
                      elastic=elastic, q=q, description=str(head.get("description", "")),
                      sensors=sensors, step=step, origin=origin)


# -- design -----------------------------------------------------------------------------

#: Band of the multisine designs [Hz]: from slow (the stiction-dominated crawl) to
#: above the end-effector's modes at the stiffer pivot positions.
BAND = (0.1, 6.0)


@dataclass(frozen=True)
class MotorLimits:
    """What each primary motor can do, at its gearhead's output (SI): the largest
    speed and torque, and the supply voltage with the motor's constants, which turn
    a speed and a torque into the voltage they need (``R tau / (G k) + k G omega``,
    the DC motor's steady state: its speed-torque line)."""

    max_speed: float
    max_torque: float
    voltage: float
    resistance: float
    torque_constant: float
    gear_ratio: float

    @classmethod
    def of(cls, params, max_speed: float | None = None, max_torque: float | None = None):
        """Limits of the parameter set's motors: by default half the no-load speed and
        the stall torque at the supply voltage."""
        mo = params.motor
        G, k, R, V = mo.gear_ratio, mo.torque_constant, mo.resistance, mo.voltage_limit
        speed = 0.5 * V / (k * abs(G)) if max_speed is None else max_speed
        torque = abs(G) * k * V / R if max_torque is None else max_torque
        for name, value in (("speed", speed), ("torque", torque)):
            if not (math.isfinite(value) and value > 0):
                raise InputError(f"motor {name} limit {value!r}: must be > 0")
        return cls(speed, torque, V, R, k, abs(G))


def motor_use(run, experiment: Experiment, limits: MotorLimits) -> dict:
    """Peak speed, torque and needed voltage of each primary motor in a run
    (`vsj.synth.wrist_run`), and ``worst``: the largest of their ratios to the limits
    (at most 1 within every limit)."""
    out = {}
    worst = 0.0
    for m in ("motor_1", "motor_2"):
        if experiment.motors == "velocity":
            speed = np.asarray(run[f"source.{m}.speed"])
            torque = np.asarray(run[f"source.{m}.torque"])
            volts = (limits.resistance * torque / (limits.gear_ratio * limits.torque_constant)
                     + limits.torque_constant * limits.gear_ratio * speed)
        else:
            speed = np.asarray(run[f"{m}.speed"])
            torque = (limits.gear_ratio * limits.torque_constant
                      * np.asarray(run[f"motor.{m}.current"]))
            volts = experiment.value(f"voltage_{m[-1]}", np.asarray(run.time))
        peak = {"speed": float(np.max(np.abs(speed))), "torque": float(np.max(np.abs(torque))),
                "voltage": float(np.max(np.abs(volts)))}
        ratio = max(peak["speed"] / limits.max_speed, peak["torque"] / limits.max_torque,
                    peak["voltage"] / limits.voltage)
        out[m] = peak
        worst = max(worst, ratio)
    out["worst"] = worst
    return out


def scaled_motors(experiment: Experiment, factor: float) -> Experiment:
    """The experiment with every motor command's amplitude times ``factor``."""
    def scale(key, value):
        if key != "amplitude":
            return value
        return tuple(factor * v for v in value) if isinstance(value, tuple) else factor * value

    signals = {}
    for ch, comps in experiment.signals.items():
        if ch.startswith(("motor_", "voltage_")):
            comps = tuple((kind, {k: scale(k, v) for k, v in spec.items()})
                          for kind, spec in comps)
        signals[ch] = comps
    return replace(experiment, signals=signals)


#: A design whose motors exceed a limit is scaled down (motor amplitudes) by bisection on
#: the scale, at most this many simulations: friction makes a motor's torque fall less
#: than its amplitude, so a proportional guess alone may not reach the limit.
LIMIT_TRIES = 8
#: The bisection stops when the feasible scale is known to this fraction.
LIMIT_RESOLUTION = 0.05


def within_limits(experiment: Experiment, params, limits: MotorLimits):
    """``(experiment, run, use)`` with the motor amplitudes scaled down as little as
    needed (to `LIMIT_RESOLUTION`) for every motor to stay within ``limits`` (speed,
    torque, voltage), or None when no scale found does (the external torques or
    friction alone load a motor beyond its limit)."""
    def attempt(factor):
        e = experiment if factor == 1.0 else scaled_motors(experiment, factor)
        run = synth.wrist_run(e, params)
        use = motor_use(run, e, limits)
        return e, run, use

    found = attempt(1.0)
    if found[2]["worst"] <= 1.0 + 1e-9:
        return found
    lo, hi = 0.0, 1.0
    factor = 0.97 / found[2]["worst"]   # proportional first guess
    found = None
    for _ in range(LIMIT_TRIES - 1):
        trial = attempt(factor)
        if trial[2]["worst"] <= 1.0 + 1e-9:
            lo, found = factor, trial
        else:
            hi = factor
        if found is not None and hi - lo <= LIMIT_RESOLUTION * hi:
            break
        factor = 0.5 * (lo + hi)
    return found


def predicted(experiment: Experiment, params, free, *, threads=None, run=None,
              input_draws: int = 0):
    """Predicted standard errors [SI] of ``free`` from an experiment, and log det of the
    Fisher information in relative parameter units: the batch Jacobian of a noiseless
    synthetic log (true stiction, windows restarted as the fit restarts them) weighted
    by the sensors' noise. The fit also estimates each compared signal's delay, which
    takes information from the parameters: the delays are in the Jacobian, and the log
    det is that of the parameters' information once the delays are known from the
    same data (Ds-optimality). ``run``: `vsj.synth.wrist_run` of the experiment, if at
    hand.

    The log det, which ranks designs, counts the compared signals' noise only. With
    ``input_draws`` the standard errors also count the noise of the measured torque
    inputs as a fit does (`vsj.identification.wrist`): the design's inputs get that
    many fresh draws of the sensors' torque noise, and each draw's residual change is
    taken through one Gauss-Newton step. Without, they are a lower bound on a fit's."""
    # lazy: scipy.optimize; synth wrist loads experiments without it
    from .wrist import DELAY_UNIT, FINAL, _Problem

    quiet = replace(experiment.sensors, encoder_counts=2 ** 40, angle_noise=0.0,
                    current_noise=0.0, current_offset=0.0, torque_noise=0.0, q_noise=0.0,
                    time_offset=0.0, jitter=0.0)
    data = synth.wrist(replace(experiment, sensors=quiet), params, seed=0, run=run)
    log = Measurement("<design>", {k: v[0] for k, v in data.columns.items()},
                      {k: v[1] for k, v in data.columns.items()}, data.comments)
    model = WristModel([log], params, Setup(free=tuple(free), threads=threads))
    s = experiment.sensors
    angle = math.sqrt(s.angle_noise ** 2 + (2 * math.pi / s.encoder_counts) ** 2 / 12)
    model.set_noise({o.name: (s.current_noise if o.kind == "current" else
                              s.q_noise if o.kind == "q" else angle) or 1e-9
                     for o in model.outputs})
    n_par, n_delay = len(model.names), len(model.delay_names)
    scale = np.concatenate([np.abs(model.base), np.full(n_delay, DELAY_UNIT)])
    problem = _Problem(model, scale, FINAL)
    theta = np.concatenate([np.ones(n_par), np.zeros(n_delay)])
    J = problem.jac(theta)
    F = J.T @ J
    w, V = np.linalg.eigh(F)
    logdet = float(np.sum(np.log(np.maximum(w, 1e-300))))
    if n_delay:  # the delays are nuisance: the information on the parameters given them
        logdet -= float(np.sum(np.log(np.maximum(np.linalg.eigvalsh(F[n_par:, n_par:]),
                                                 1e-300))))
    keep = w > 1e-12 * max(w[-1], 1e-300)
    cov = (V[:, keep] / w[keep]) @ V[:, keep].T
    noisy = {column: s.torque_noise for channel, (column, _) in model.channels.items()
             if channel.startswith("tau_")} if s.torque_noise > 0 else {}
    if input_draws > 1 and noisy:
        perturbed, ran = model.perturbed_residuals(theta * scale, FINAL, input_draws,
                                                   noise=noisy)
        steps = -(perturbed[ran] - problem.fun(theta)[None]) @ J @ cov
        if len(steps) > 1:  # their spread about their mean, as a fit takes it
            cov = cov + np.atleast_2d(np.cov(steps, rowvar=False))
    se = np.sqrt(np.clip(np.diag(cov), 0, None)) * scale
    se[np.sum(V[:, ~keep] ** 2, axis=1) > 0.1] = math.inf
    return dict(zip(model.names, se[:n_par])), logdet


def plain_sine(duration: float, max_speed: float, *, motors="velocity", q=0.0,
               frequency=1.0) -> Experiment:
    """The reference: one sine on motor 1 at the speed limit, nothing else."""
    ch = "motor_1" if motors == "velocity" else "voltage_1"
    return Experiment(duration=duration, motors=motors, q=q,
                      signals={ch: (("sine", {"frequency": frequency,
                                              "amplitude": max_speed}),)},
                      description=f"plain sine of {frequency:g} Hz on {ch}")


def candidate(duration: float, max_speed: float, max_torque: float, rng, *,
              motors="velocity", q=0.0, q_range=None, elastic="geometric") -> Experiment:
    """A random design: multisines on both motors (log-spaced frequencies in `BAND`,
    random phases, amplitudes falling with frequency, scaled to the speed limit),
    external torque pulses of either sign on both axes, and, with ``q_range``, steps
    of the pivot."""
    grid = np.linspace(0.0, duration, int(duration * 200) + 1)
    signals = {}
    channels = ("motor_1", "motor_2") if motors == "velocity" else ("voltage_1", "voltage_2")
    for ch in channels:
        n = int(rng.integers(4, 9))
        f = np.sort(np.exp(rng.uniform(np.log(BAND[0]), np.log(BAND[1]), n)))
        a = f ** -rng.uniform(0.0, 1.0)
        p = rng.uniform(0, 2 * math.pi, n)
        wave = sum(ai * np.sin(2 * math.pi * fi * grid + pi) for fi, ai, pi in zip(f, a, p))
        a = a * max_speed / max(float(np.max(np.abs(wave))), 1e-12)
        signals[ch] = (("multisine", {"frequency": tuple(f), "amplitude": tuple(a),
                                      "phase": tuple(p)}),)
    for ch in ("tau_x", "tau_y"):
        count = max(1, int(duration / rng.uniform(1.5, 4.0)))
        starts = np.sort(rng.uniform(0.5, max(duration - 1.0, 0.6), count))
        signals[ch] = (("pulses", {"start": tuple(starts), "width": float(rng.uniform(0.2, 0.6)),
                                   "height": tuple(max_torque * rng.choice([-1.0, 1.0], count))}),)
    if q_range is not None:
        count = max(1, int(duration / 8))
        times = np.sort(rng.uniform(1.0, duration - 1.0, count))
        signals["q"] = (("steps", {"time": tuple(times),
                                   "value": tuple(rng.uniform(q_range[0], q_range[1], count)
                                                  - q)}),)
    return Experiment(duration=duration, motors=motors, q=q, elastic=elastic, signals=signals,
                      description="multisines on the motors and torque pulses on the "
                                  "end-effector")


@dataclass(frozen=True)
class Design:
    """The chosen experiment with its predicted standard errors [SI] and log det of
    the Fisher information, its motors' peak use (`motor_use`), and the same for the
    plain sine it is compared with."""

    experiment: Experiment
    stderr: dict
    logdet: float
    use: dict
    reference: Experiment
    reference_stderr: dict
    reference_logdet: float
    reference_use: dict
    limits: MotorLimits


def design(params, free, duration: float, *, max_speed: float | None = None,
           max_torque: float, max_motor_torque: float | None = None, motors="velocity",
           q=0.0, candidates: int = 6, seed: int = 0, threads=None, elastic="geometric",
           progress=None, input_draws: int = Setup.input_draws) -> Design:
    """Ds-optimal choice among ``candidates`` random designs (`candidate`): the one whose
    Fisher information on the free parameters (`predicted`: the delays a fit estimates
    taken as nuisance) has the largest determinant, among those that keep every
    motor within its speed and torque limits (`MotorLimits`; a candidate beyond them
    is first scaled down, `within_limits`). ``max_torque`` is the height of the
    external torque pulses. The plain sine it is compared with obeys the same
    limits. The standard errors predicted for both count the torque inputs' noise
    with ``input_draws`` draws, as a fit does (`predicted`)."""
    say = progress or (lambda text: None)
    limits = MotorLimits.of(params, max_speed, max_motor_torque)
    rng = np.random.default_rng(seed)
    q_range = None
    if any(n.startswith(("elastic_element.", "pivot.")) for n in free):
        q_range = (params.pivot.q_min, params.pivot.q_max)
    best = None
    refused = 0
    for k in range(candidates):
        e = candidate(duration, limits.max_speed, max_torque, rng, motors=motors, q=q,
                      q_range=q_range, elastic=elastic)
        fitted = within_limits(e, params, limits)
        if fitted is None:
            refused += 1
            say(f"candidate {k + 1}/{candidates}: beyond the motors' limits, dropped")
            continue
        e, run, use = fitted
        _, logdet = predicted(e, params, free, threads=threads, run=run)
        say(f"candidate {k + 1}/{candidates}: log det {logdet:.4g} (motors at "
            f"{100 * use['worst']:.3g} % of their limits)")
        if best is None or logdet > best[2]:
            best = (e, run, logdet, use)
    if best is None:
        raise InputError(f"every one of the {candidates} candidate excitations needs more than "
                         f"the motors give (speed {limits.max_speed:.4g} rad/s, torque "
                         f"{limits.max_torque:.4g} N m, {limits.voltage:.4g} V), even scaled "
                         f"down: lower the external torque pulses (now {max_torque:.4g} N m) "
                         "or raise the motor torque limit")
    e, run, logdet, use = best
    say("the chosen design's standard errors, the torque inputs' noise counted")
    se, _ = predicted(e, params, free, threads=threads, run=run, input_draws=input_draws)
    ref = plain_sine(duration, limits.max_speed, motors=motors, q=q)
    fitted = within_limits(ref, params, limits)
    if fitted is None:
        raise InputError("the plain sine to compare with exceeds the motors' limits even "
                         "scaled down")
    ref, ref_run, ref_use = fitted
    ref_se, ref_logdet = predicted(ref, params, free, threads=threads, run=ref_run,
                                   input_draws=input_draws)
    e = replace(e, description=f"Ds-optimal among {candidates - refused} candidates within the "
                               f"motors' limits (seed {seed}) for {', '.join(free)}: "
                               f"{e.description}")
    return Design(e, se, logdet, use, ref, ref_se, ref_logdet, ref_use, limits)

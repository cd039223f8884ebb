"""Explosive motion: how much faster than its motors can the link move?

A joint with a spring in it can store the motors' work and give it back to the link at
once, as a throw does. Haddadin et al. (ICRA 2011, "Optimal control for maximizing link
velocity of robotic variable stiffness joints"), Garabini et al. (ICRA 2011, "Optimality
principles in variable stiffness control: the VSA hammer") and Braun et al. (RSS 2012,
"Optimal torque and stiffness control in compliantly actuated robots") optimise the
motor (and stiffness) trajectory for the largest link speed; on hardware they reach
about twice what a stiff joint with the same motors can (which is the motors' own speed
limit reflected to the link: a ratio of 1).

Here the motors' voltage profile over a window (``knots`` values, linear between them,
within the voltage limit; both output motors alike, so only ``theta_x`` moves) and the
stiffness setting ``q`` are optimised for the largest ``theta_x`` speed, each candidate
simulated by vsj's engine on the whole wrist (DC motors, friction, the elastic element's
own law with its slack springs and end stop). The ring deflection must stay within the
end stop: beyond it the stop, a stiff spring of its own (50 N m/rad in the bundled set),
would be the one throwing. The ratio reported is the peak speed over the motors' no-load
speed at the voltage limit reflected to ``theta_x`` (`AxisModel.no_load_speed`).

`reduced_explosive` solves the same problem on the one-axis model
(`vsj.studies.axis`), with a rigid joint for comparison: a tool for tests and for seeing
the physics without friction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import expm
from scipy.optimize import minimize

from ..characteristics import spring_extensions
from ..control.wrist import wrist_kinematics
from ..errors import InputError, SimulationError
from ..inputs import Constant, Table
from ..params import Parameters
from ..simulate import InitialState, SimulationOptions, simulate
from ..wrist import WristOptions, build_wrist
from .axis import AxisModel, axis_model


@dataclass(frozen=True)
class Explosive:
    """The problem: a voltage profile of ``knots`` values over ``window`` [s] (held at
    its last value for ``tail`` [s] more, where the peak may still come), the pivot at
    ``q`` [m] (None: optimised with the profile), SLSQP for at most ``max_iterations``
    iterations from the reduced model's optimum (see `optimise_wrist`). ``friction``: the engine's friction law;
    ``output_step`` [s]: the sampling of the run, on which the peak is read."""

    window: float = 0.25
    knots: int = 16
    tail: float = 0.05
    q: float | None = None
    max_iterations: int = 60
    friction: str = "arctan"
    output_step: float = 1e-4

    def check(self) -> None:
        """`InputError` naming the field for a value out of range."""
        for key in ("window", "output_step"):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or v <= 0:
                raise InputError(f"explosive motion: {key} must be a finite number > 0 s, got "
                                 f"{v!r}")
        if isinstance(self.tail, bool) or not isinstance(self.tail, (int, float)) \
                or not math.isfinite(self.tail) or self.tail < 0:
            raise InputError(f"explosive motion: tail must be a finite number >= 0 s, got "
                             f"{self.tail!r}")
        for key, low in (("knots", 2), ("max_iterations", 1)):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise InputError(f"explosive motion: {key} must be a whole number >= {low}, "
                                 f"got {v!r}")
        if self.q is not None and (isinstance(self.q, bool) or not isinstance(
                self.q, (int, float)) or not math.isfinite(self.q)):
            raise InputError(f"explosive motion: q must be a pivot position [m] or None, got "
                             f"{self.q!r}")
        if self.output_step > self.window / 10:
            raise InputError(f"explosive motion: output_step {self.output_step!r} s must be at "
                             f"most a tenth of the window ({self.window!r} s)")


def starting_profile(model: AxisModel, q: float, setup: Explosive) -> np.ndarray:
    """A voltage profile to start from [V] at the knots: full voltage switched at the
    joint's natural frequency at ``q`` (link against the motor side held), which pumps
    the elastic mode, the classical way to swing a spring up."""
    J = np.asarray(model.mass, dtype=float)
    K = float(model.joint.stiffness(q))
    omega = math.sqrt(K / (J[1, 1] - J[0, 1] ** 2 / J[0, 0]))
    t = np.linspace(0.0, setup.window, setup.knots)
    return model.voltage_limit * np.where(np.sin(omega * t) >= 0.0, 1.0, -1.0)


@dataclass
class ExplosiveResult:
    """The optimum: ``q`` [m], ``times`` [s] and ``voltages`` [V] of the profile, the run
    (``time`` [s], ``speed`` of theta_x [rad/s], ``motor_speed`` [rad/s]: the motor side
    reflected to theta_x, ``deflection`` [rad]: the larger ring angle's magnitude,
    ``voltage`` [V]), ``peak_speed`` [rad/s], ``no_load_speed`` [rad/s], ``ratio``,
    ``history`` (the ratio after each iteration), ``evaluations`` (engine runs),
    ``success`` and ``message`` (SLSQP's), and ``limits``: what bounds the result (see
    `limits_of`)."""

    q: float
    times: np.ndarray
    voltages: np.ndarray
    time: np.ndarray
    speed: np.ndarray
    motor_speed: np.ndarray
    deflection: np.ndarray
    voltage: np.ndarray
    peak_speed: float
    no_load_speed: float
    history: list
    evaluations: int
    success: bool
    message: str
    limits: dict = field(default_factory=dict)
    start_ratio: float = math.nan

    @property
    def ratio(self) -> float:
        """Peak link speed over the motors' speed limit reflected to the axis."""
        return self.peak_speed / self.no_load_speed


class _WristRuns:
    """The wrist's engine runs for voltage profiles, memoised by the parameter vector."""

    def __init__(self, params: Parameters, model: AxisModel, setup: Explosive):
        self.model = model
        self.setup = setup
        self.structure = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc")
                                     ).assemble()
        flanges = {s.name: s.flange for s in self.structure.signals}
        self.kin = wrist_kinematics(self.structure)
        self.flanges = flanges
        self.end_stop = float(params["elastic_element.end_stop"])
        self.times = np.linspace(0.0, setup.window, setup.knots)
        self.cache: dict = {}
        self.evaluations = 0

    def run(self, voltages, q: float):
        key = (tuple(np.round(voltages, 12)), round(float(q), 15))
        if key in self.cache:
            return self.cache[key]
        signs = np.sign(self.kin.to_rotors[:2, 0])
        inputs = {self.kin.channels[j]: Table(tuple(self.times), tuple(signs[j] * voltages))
                  for j in range(2)}
        inputs[self.kin.channels[2]] = Constant(0.0)
        s = self.setup
        result = simulate(self.structure, inputs, s.window + s.tail,
                          initial=InitialState(q=float(q)),
                          options=SimulationOptions(friction=s.friction, rtol=1e-10,
                                                    atol=1e-12, output_step=s.output_step),
                          ports=False)
        self.evaluations += 1
        if not result.success:
            raise SimulationError(f"explosive motion: the engine's run failed at q = {q:g} m: "
                                  f"{result.message}")
        w = self.kin.to_wrist[0, :2]
        motor = w[0] * result["motor_1.rotor.speed"] + w[1] * result["motor_2.rotor.speed"]
        out = {"time": result.time, "speed": result["theta_x.speed"], "motor_speed": motor,
               "deflection": np.maximum(np.abs(result["phi_1"]), np.abs(result["phi_2"])),
               "voltage": signs[0] * result["motor.motor_1.voltage"],
               "current": np.maximum(np.abs(result["motor.motor_1.current"]),
                                     np.abs(result["motor.motor_2.current"])),
               "q": result["q"]}
        self.cache[key] = out
        return out


def limits_of(model: AxisModel, params: Parameters, voltages, run: dict, q: float) -> dict:
    """What bounds an optimum: ``end_stop`` (the largest ring deflection over the end
    stop, 1 when it is reached), ``holdable`` (the largest joint deflection over what the
    joint holds at q: above 1 the link swings past the torque's peak), ``slack`` (the
    share of the run a spring is slack), ``voltage`` (the share of the profile's knots at
    the limit), ``motor_speed`` (the motor side's largest speed over the no-load speed)
    and ``peak_current`` [A] (the parameter set gives no current limit)."""
    end_stop = float(params["elastic_element.end_stop"])
    ring_per_output = float(np.max(model.joint.deflection)) / end_stop
    joint_deflection = run["deflection"] * ring_per_output
    geometry = tuple(params[f"elastic_element.{k}"] for k in (
        "ring_radius", "lever_length", "lever_width", "anchor_x", "anchor_y", "rest_length",
        "spring_stiffness"))
    slack = np.array([min(spring_extensions(geometry, float(qq), float(phi))) < 0.0
                      for qq, phi in zip(run["q"][::10], run["deflection"][::10])])
    return {"end_stop": float(np.max(run["deflection"]) / end_stop),
            "holdable": float(np.max(joint_deflection)
                              / model.joint.holdable_deflection(q)[0]),
            "slack": float(np.mean(slack)),
            "voltage": float(np.mean(np.abs(voltages) >= model.voltage_limit * (1 - 1e-6))),
            "motor_speed": float(np.max(np.abs(run["motor_speed"])) / model.no_load_speed),
            "peak_current": float(np.max(run["current"]))}


#: Finite-difference step of the optimiser's gradients, on the scaled variables (volts
#: over the limit, the pivot over its range). The engine runs at rtol 1e-10, so the
#: difference quotient's noise is about 1e-10 / 1e-3 of the speed, and its truncation
#: error (second order, forward) a few 1e-3 of the curvature's scale.
FD_STEP = 1e-3


#: Pivot positions (as shares of the range, stiff to soft) at which the reduced model is
#: optimised to choose where the engine's optimisation of a free q starts.
REDUCED_SWEEP = np.linspace(0.0, 1.0, 8)


def optimise_wrist(params: Parameters, setup: Explosive | None = None, *,
                   model: AxisModel | None = None, start=None) -> ExplosiveResult:
    """The explosive motion of the wrist's ``theta_x`` (see the module's notes): SLSQP on
    the voltage profile (and ``q`` unless ``setup.q`` fixes it), every evaluation an
    engine run.

    ``start`` = ``(voltages [V] at the knots, q [m])`` is where the optimiser starts;
    without it, the reduced model's optimum (`reduced_explosive`) at ``setup.q``, or at
    the best of `REDUCED_SWEEP` when q is free: the linear, friction-free axis finds the
    pumping rhythm in about a second, and the engine's runs refine it. A start that
    drives the ring past its end stop is scaled down until it does not. The result is the
    fastest profile run within the end stop (never below the start). `SimulationError`
    if a run fails; the result says whether SLSQP converged (``success``, ``message``)."""
    setup = setup or Explosive()
    setup.check()
    if not isinstance(params, Parameters):
        raise InputError(f"explosive motion needs a vsj.params.Parameters set, got "
                         f"{type(params).__name__}")
    model = model or axis_model(params)
    if setup.q is not None and not model.q_min <= setup.q <= model.q_max:
        raise InputError(f"explosive motion: q = {setup.q!r} m is outside the pivot's range "
                         f"[{model.q_min:g}, {model.q_max:g}] m")
    runs = _WristRuns(params, model, setup)
    V = model.voltage_limit
    q_span = model.q_max - model.q_min
    free_q = setup.q is None
    if start is None:
        qs = [float(setup.q)] if not free_q else \
            [model.q_min + f * q_span for f in REDUCED_SWEEP]
        found = [(reduced_explosive(model, q, window=setup.window, knots=setup.knots,
                                    tail=setup.tail, max_iterations=60), q) for q in qs]
        best, q0 = max(found, key=lambda f: f[0].ratio)
        volts0 = best.voltages
    else:
        volts0, q0 = np.asarray(start[0], dtype=float), float(start[1])
        if volts0.shape != (setup.knots,) or not model.q_min <= q0 <= model.q_max:
            raise InputError(f"explosive motion: start must be {setup.knots} voltages and a "
                             f"pivot position within [{model.q_min:g}, {model.q_max:g}] m")
        if not free_q:
            q0 = float(setup.q)

    def unpack(x):
        q = model.q_min + x[-1] * q_span if free_q else q0
        return x[:setup.knots] * V, q

    best: dict = {}

    def evaluate(x):
        volts, q = unpack(x)
        run = runs.run(volts, q)
        r = float(np.max(run["speed"])) / model.no_load_speed
        m = 1.0 - float(np.max(run["deflection"])) / runs.end_stop
        if m >= 0.0 and r > best.get("ratio", -math.inf):
            best.update(ratio=r, x=np.array(x, dtype=float))
        return r, m

    def ratio(x):
        return evaluate(x)[0]

    def margin(x):
        return evaluate(x)[1]

    x0 = np.clip(volts0 / V, -1.0, 1.0)
    if free_q:
        x0 = np.append(x0, (q0 - model.q_min) / q_span)
    for factor in (1.0, 0.8, 0.6, 0.4, 0.2, 0.1):
        trial = x0.copy()
        trial[:setup.knots] *= factor
        if margin(trial) >= 0:
            break
    x0 = trial
    history = [ratio(x0)]
    bounds = [(-1.0, 1.0)] * setup.knots + ([(0.0, 1.0)] if free_q else [])
    res = minimize(lambda x: -ratio(x), x0, method="SLSQP", bounds=bounds,
                   constraints=[{"type": "ineq", "fun": margin}],
                   callback=lambda x: history.append(ratio(x)),
                   options={"maxiter": setup.max_iterations, "ftol": 1e-6, "eps": FD_STEP})
    evaluate(np.clip(res.x, [b[0] for b in bounds], [b[1] for b in bounds]))
    if "x" not in best:
        raise SimulationError(f"explosive motion: no profile tried kept the ring within its "
                              f"end stop ({res.message})")
    # the best profile run within the end stop (SLSQP's last iterate, or a point it
    # tried on the way, its finite differences' included: each is an engine run)
    volts, q = unpack(best["x"])
    run = runs.run(volts, q)
    return ExplosiveResult(
        q=q, times=runs.times, voltages=volts, time=run["time"], speed=run["speed"],
        motor_speed=run["motor_speed"], deflection=run["deflection"], voltage=run["voltage"],
        peak_speed=float(np.max(run["speed"])), no_load_speed=model.no_load_speed,
        history=history, evaluations=runs.evaluations, success=bool(res.success),
        message=str(res.message), limits=limits_of(model, params, volts, run, q),
        start_ratio=history[0])


# -- the reduced model ---------------------------------------------------------------


@dataclass
class ReducedExplosive:
    """An optimum on the reduced model: ``voltages`` [V] at ``times`` [s], the
    ``peak_speed`` of the link [rad/s], the ``ratio`` to the no-load speed, ``history``
    (ratio per iteration) and SLSQP's ``success`` and ``message``."""

    times: np.ndarray
    voltages: np.ndarray
    peak_speed: float
    ratio: float
    history: list
    success: bool
    message: str


def _linear_axis(model: AxisModel, q: float, rigid: bool):
    """``(F, G, link, deflection)``: the axis linearised at ``q`` (the joint's stiffness at
    zero deflection; exact for a linear joint) as ``x' = F x + G V``, with the rows that
    read the link's speed and the joint's deflection from ``x``. ``rigid``: one inertia
    ``sum(M)``, state ``(theta, omega)``."""
    M = np.asarray(model.mass, dtype=float)
    C = np.asarray(model.back_emf, dtype=float) + np.asarray(model.damping, dtype=float)
    g = np.asarray(model.voltage_gain, dtype=float)
    if rigid:
        one = np.ones(2)
        J, c, gv = float(one @ M @ one), float(one @ C @ one), float(np.sum(g))
        F = np.array([[0.0, 1.0], [0.0, -c / J]])
        return F, np.array([0.0, gv / J]), np.array([0.0, 1.0]), np.zeros(2)
    K = float(model.joint.stiffness(q))
    Minv = np.linalg.inv(M)
    F = np.zeros((4, 4))
    F[0, 2] = F[1, 3] = 1.0
    F[2:, :2] = Minv @ (K * np.array([[-1.0, 1.0], [1.0, -1.0]]))
    F[2:, 2:] = -Minv @ C
    G = np.concatenate([[0.0, 0.0], Minv @ g])
    return F, G, np.array([0.0, 0.0, 0.0, 1.0]), np.array([1.0, -1.0, 0.0, 0.0])


def _linear_run(F, G, times, voltages, duration: float, per_segment: int):
    """The linear axis from rest under the voltage linear between ``times`` (held after
    the last): states at ``per_segment`` points per segment, propagated exactly (the
    input's value and slope ride along as states of one matrix exponential)."""
    n = len(G)
    h = float(times[1] - times[0])
    step = h / per_segment
    aug = np.zeros((n + 2, n + 2))
    aug[:n, :n] = F
    aug[:n, n] = G
    aug[n, n + 1] = 1.0
    E = expm(aug * step)
    slopes = np.append(np.diff(voltages) / h, 0.0)
    z = np.zeros(n + 2)
    z[n] = voltages[0]
    out = [z[:n].copy()]
    segments = len(times) - 1 + int(math.ceil((duration - times[-1]) / h - 1e-12))
    for k in range(segments):
        z[n] = voltages[min(k, len(voltages) - 1)]
        z[n + 1] = slopes[k] if k < len(slopes) else 0.0
        for _ in range(per_segment):
            z = E @ z
            out.append(z[:n].copy())
    return np.array(out)


def reduced_explosive(model: AxisModel, q: float, *, window: float, knots: int,
                      tail: float = 0.0, rigid: bool = False, max_iterations: int = 100,
                      samples: int = 2000) -> ReducedExplosive:
    """The explosive motion on the reduced model: the axis linearised at ``q`` [m] (the
    joint's stiffness at zero deflection; exact for a `JointTable.linear` joint) without
    Coulomb friction, or with ``rigid`` the motors and the link as one inertia. SLSQP on
    ``knots`` voltages over ``window`` [s] (held ``tail`` [s] more); the link's peak speed
    is read on about ``samples`` points of the exact solution. The deflection must stay
    within what the joint holds at q. Returns a `ReducedExplosive`."""
    if not isinstance(model, AxisModel):
        raise InputError(f"reduced explosive motion: model must be an AxisModel, got "
                         f"{type(model).__name__}")
    Explosive(window=window, knots=knots, tail=tail, q=q,
              max_iterations=max_iterations, output_step=window / 10).check()
    times = np.linspace(0.0, window, knots)
    F, G, link_row, deflection_row = _linear_axis(model, q, rigid)
    V = model.voltage_limit
    hold = float(model.joint.holdable_deflection(q)[0])
    per_segment = max(2, samples // knots)

    def run(x):
        states = _linear_run(F, G, times, x * V, window + tail, per_segment)
        return float(np.max(states @ link_row)), float(np.max(np.abs(states @ deflection_row)))

    cache: dict = {}

    def cached(x):
        key = tuple(np.round(x, 13))
        if key not in cache:
            cache[key] = run(x)
        return cache[key]

    def ratio(x):
        return cached(x)[0] / model.no_load_speed

    if rigid:
        x0 = np.zeros(knots)
    else:
        x0 = starting_profile(model, q, Explosive(window=window, knots=knots)) / V * 0.5
    history = [ratio(x0)]
    cons = [] if rigid else [{"type": "ineq", "fun": lambda x: 1.0 - cached(x)[1] / hold}]
    res = minimize(lambda x: -ratio(x), x0, method="SLSQP", bounds=[(-1.0, 1.0)] * knots,
                   constraints=cons, callback=lambda x: history.append(ratio(x)),
                   options={"maxiter": max_iterations, "ftol": 1e-10, "eps": 1e-6})
    x = np.clip(res.x, -1.0, 1.0)
    peak, _ = cached(x)
    return ReducedExplosive(times=times, voltages=x * V, peak_speed=peak,
                            ratio=peak / model.no_load_speed, history=history,
                            success=bool(res.success), message=str(res.message))


__all__ = ["Explosive", "ExplosiveResult", "ReducedExplosive", "limits_of", "optimise_wrist",
           "reduced_explosive", "starting_profile"]

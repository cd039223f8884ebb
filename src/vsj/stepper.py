"""A fast step function: advance a network by one control period.

For estimators and controllers that run the model in their own loop (report
chapter 5: "estimator-based control, which requires fast computation"). A
`Stepper` holds one compiled model and advances a state vector by one period
``dt`` with the inputs held constant over the period (zero-order hold, what a
digital controller applies)::

    stepper = Stepper.wrist(params, period=1e-3)
    state = stepper.initial_state(InitialState(q=-0.004))
    for k in range(1000):
        state = stepper.step(state, [u1, u2, 0.0, tau_x, tau_y])

State vector (`Stepper.state_names`), in SI units::

    [x (n), p (n), i (motors), sigma (sources)]

``x`` are the generalised angles of the network (the free flanges, for the
wrist the ring angles ``vsm_i.ring`` = elastic deflections), ``p`` the
generalised momenta ``p = M v + M_su u`` [N m s] (``M``: mass matrix of the
free coordinates, ``M_su`` its coupling to the velocity sources' speeds ``u``),
``i`` the armature currents of DC motors and ``sigma`` the angles of the
velocity sources (motor positions, and the pivot drive's angle, which sets
``q``). Momenta rather than speeds because a velocity source that changes its
speed from one period to the next gives the free flanges an impulse: the
momentum is continuous across that jump, the speeds are not. `speeds` returns
``v = M^-1 (p - M_su u)`` for given inputs. The same coordinates are used by
`vsj.linear`, so its Jacobians apply to this state directly.

Inputs (`Stepper.input_names`) are the network's input channels in the order
of `vsj.network.Structure.channels`: velocity-source speeds [rad/s] first,
then load torques [N m] and motor voltages [V].

Integration: ``method="dopri"`` runs the simulator's own adaptive
Dormand-Prince 5(4) solver from 0 to ``dt`` with the run's ``rtol``/``atol``,
so a step is the computation `vsj.simulate.simulate` performs for a run of
one period with constant inputs (tests check agreement to 1e-9). Its cost
varies with the dynamics. ``method="rk4"`` takes ``substeps`` classical
Runge-Kutta steps of ``dt/substeps``: a fixed cost per call, for hard
real-time loops; its accuracy is the user's choice of ``substeps`` (stable
while ``dt/substeps`` times the fastest rate of the model stays below about
2.8; the bundled DC motors' armature time constant, L/R = 0.1 ms, needs at
least 4 substeps per millisecond). Substeps too long for the fastest modes at
rest are refused, naming the least count that is stable. Both integrate friction
laws that are functions of speed (the jump of the ``sign`` law makes ``dopri``
take very many tiny steps, `benchmarks/friction_laws.py`). ``method="timestep"`` runs the
simulator's time-stepper with true stiction at the options' ``step``; its
stick/slip history (which elements hold, the last impulses) is kept from one
call to the next, so calls must follow one another in time.

Cost per call: `benchmarks/step_cost.py` (run by `make bench`) prints it,
from Python and from C, against one `simulate` call of the same period.

From C: the same step is ``vsj_step`` (with a ``vsj_scheme``) of the engine's public
header ``vsj/engine/c/vsj.h``;
``examples/c/step_wrist.c`` loads a wrist exported by ``vsj export-model`` and
steps it.

A `Stepper` holds one work: use one `Stepper` per thread.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import replace
from collections.abc import Mapping, Sequence

import numpy as np

from . import _core
from .engine import OK, STATUS_TEXT
from .engine.core import pivot_position
from .engine.model import EngineModel, friction_laws_for
from .engine.plan import Plan, Scheme
from .errors import InputError, SimulationError, is_number
from .inputs import Constant
from .network import Structure
from .simulate import InitialState, SimulationOptions, prepare
from .wrist import build_wrist

METHODS = ("dopri", "rosenbrock", "rk4", "timestep")

#: The most steps one period may take (rk4 substeps, time-stepper steps; vsj.h's
#: VSJ_MAX_PERIOD_STEPS).
MAX_PERIOD_STEPS = 10_000_000

#: How much a mode may grow in one rk4 substep before `Stepper` refuses the substeps:
#: above the rounding of ``|R(h lambda)|`` near 1, and small enough that the growth it
#: lets through stays below 1e-2 over a million substeps.
RK4_GROWTH = 1e-8

#: Relative step of the central differences in `Stepper.jacobian` (times each
#: variable's scale); with Richardson extrapolation the truncation error is
#: O(h^4) and the round-off about 1e-16 / 1e-5 of the derivative's scale.
JACOBIAN_STEP = 1e-5


# -- the Python face -------------------------------------------------------------------


class Stepper:
    """One compiled network, advanced one control period per call.

    ``structure``: an assembled network (`vsj.wrist.build_wrist(...).assemble()`
    or any other); ``period`` [s]: the control period; ``options``: friction
    law and tolerances as for `vsj.simulate.simulate` (``rtol`` and ``atol``
    steer ``method="dopri"`` and ``"rosenbrock"``, whose steps are bounded by the
    period only;
    ``max_steps`` bounds them per period); ``substeps`` sets ``method="rk4"``'s
    steps per period. A step fails when the pivot leaves the range its
    mechanism allows (`vsj.network.Pivot`).
    """

    def __init__(self, structure: Structure, period: float = 1e-3, *,
                 options: SimulationOptions | None = None, method: str = "dopri",
                 substeps: int = 4, max_steps: int = 100_000, controller=None):
        if not isinstance(structure, Structure):
            raise InputError(f"stepper: the model must be an assembled network (a Structure: "
                             f"Network.assemble(), or vsj.build_wrist(params).assemble()), got "
                             f"{type(structure).__name__}")
        options = SimulationOptions() if options is None else options
        if not isinstance(options, SimulationOptions):
            raise InputError(f"stepper: options must be a SimulationOptions, got "
                             f"{type(options).__name__}")
        options.validate()
        if not is_number(period) or not (math.isfinite(period) and period > 0.0):
            raise InputError(f"stepper: period must be > 0 s (a number of seconds), got {period!r}")
        if isinstance(substeps, numbers.Integral) and not isinstance(substeps, bool):
            substeps = int(substeps)  # NumPy's integers are the numbers they hold
        if isinstance(max_steps, numbers.Integral) and not isinstance(max_steps, bool):
            max_steps = int(max_steps)
        if method not in METHODS:
            raise InputError(f"stepper: method must be one of {', '.join(METHODS)}, got "
                             f"{method!r}")
        if not (isinstance(substeps, int) and 1 <= substeps <= MAX_PERIOD_STEPS):
            raise InputError(f"stepper: substeps must be an integer in 1..{MAX_PERIOD_STEPS}, "
                             f"got {substeps!r}")
        if method == "timestep" and not period / options.step <= MAX_PERIOD_STEPS:
            raise InputError(f"stepper: a period of {period:g} s is {period / options.step:.3g} "
                             f"steps of {options.step:g} s, more than {MAX_PERIOD_STEPS}")
        if not (isinstance(max_steps, int) and max_steps >= 1):
            raise InputError(f"stepper: max_steps must be an integer >= 1, got {max_steps!r}")
        if method != "timestep" and "stiction" in friction_laws_for(
                structure, options.friction, options.friction_overrides):
            raise InputError("stepper: the stiction friction law needs method='timestep' "
                             "(the time-stepping solver); dopri, rosenbrock and rk4 integrate "
                             "smooth laws "
                             "(viscous, arctan, sign, slope)")
        self.structure = structure
        self.period = float(period)
        self.options = options
        self.method = method
        self.substeps = substeps
        self.max_steps = int(max_steps)
        self.rtol = float(options.rtol)
        self.atol = float(options.atol)
        self.step_size = float(options.step)
        held = {ch: Constant(0.0) for ch in structure.channels()}
        scheme = replace(Scheme.of(method, options), max_steps=self.max_steps,
                         substeps=substeps)
        self.plan = Plan.compile(structure, held, self.period, options, None, scheme,
                                 held=True, controller=controller)
        #: the compiled controller (`vsj.control.CompiledController`), if any
        self.controller = self.plan.controller
        # a controller's references are inputs too, after the network's channels
        self.input_names = structure.channels() + (
            tuple(self.controller.references) if self.controller is not None else ())
        self.layout = self.plan.layout
        self.use_model(self.plan.model)
        n, nm, s = self.layout.n, self.layout.n_motors, self.layout.n_sources
        self.state_names = tuple(
            [f"{f}.angle" for f in structure.free] + [f"{f}.momentum" for f in structure.free]
            + [f"{m.name}.current" for m in structure.motors]
            + [f"{src.flange}.angle" for src in structure.sources])
        self.state_units = tuple(["rad"] * n + ["N m s"] * n + ["A"] * nm + ["rad"] * s)
        self.input_units = tuple(_channel_unit(structure, ch) for ch in self.input_names)
        self._n_state = 2 * n + nm + s
        #: whether rk4's substeps are checked against the modes at rest (also when
        #: `use_model` changes the parameters)
        self._judge_rk4 = method == "rk4" and "sign" not in friction_laws_for(
            structure, options.friction, options.friction_overrides)
        if self._judge_rk4:
            self._check_rk4_substeps()

    def _check_rk4_substeps(self) -> None:
        """`InputError` when rk4's substeps are too long for the network's modes at rest
        (no inputs; the state of zeros, or the pivot in the middle of its range where
        zeros lie outside it), naming the least count that is stable.

        A substep of RK4 multiplies a mode ``exp(lambda t)`` by ``R(h lambda)``,
        ``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``. Where a mode that decays or oscillates
        has ``|R| > 1`` (by more than `RK4_GROWTH`), rounding alone starts it growing,
        and the steps return a finite state that the model does not have. A stiffer
        setting (the pivot at the stiff end, springs deflected) can need more substeps
        than rest does; a law with a jump (``sign``) has no rate at rest and is not
        judged, nor is a network whose rates at rest are not finite."""
        lam = self._modes_at_rest()
        if lam is None or not len(lam):
            return

        def growth(substeps: int) -> np.ndarray:
            z = self.period / substeps * lam
            with np.errstate(over="ignore", invalid="ignore"):
                r = np.abs(1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24)
            return np.where(np.isfinite(r), r, np.inf)

        def stable(substeps: int) -> bool:
            return bool(np.all(growth(substeps) <= 1.0 + RK4_GROWTH))

        if stable(self.substeps):
            return
        # the least stable count: each mode's |R| falls as its substeps shorten, so the
        # counts that are stable are those from one on; found by doubling, then halving
        low, high = self.substeps, self.substeps
        while not stable(high) and high <= MAX_PERIOD_STEPS:
            low, high = high, 2 * high
        while high - low > 1 and high <= MAX_PERIOD_STEPS:
            mid = (low + high) // 2
            low, high = (low, mid) if stable(mid) else (mid, high)
        worst = int(np.argmax(growth(self.substeps)))
        advice = (f"use at least {high} substeps" if high <= MAX_PERIOD_STEPS else
                  f"no count up to {MAX_PERIOD_STEPS} is: shorten the period")
        raise InputError(
            f"stepper: {self.substeps} rk4 substeps of a {self.period:g} s period are beyond "
            f"RK4's stability limit for this network: a mode at rest of rate "
            f"{abs(lam[worst]):.4g} 1/s would grow {growth(self.substeps)[worst]:.3g}x a "
            f"substep; {advice}")

    def _modes_at_rest(self) -> np.ndarray | None:
        """The decaying and oscillating modes [1/s] of the Jacobian at rest (see
        `_check_rk4_substeps`), an oscillation's real part within rounding of the
        Jacobian taken as zero; None where the network has no finite rates at rest."""
        rests = [lambda: np.zeros(self.n_state)]
        pivot = self.structure.pivot
        if pivot.flange is not None and math.isfinite(pivot.q_min + pivot.q_max):
            middle = InitialState(q=0.5 * (pivot.q_min + pivot.q_max))
            rests.append(lambda: self.initial_state(middle))
        for rest in rests:
            try:
                jx, _ = self.jacobian(rest(), np.zeros(self.n_inputs))
            except (SimulationError, InputError):
                continue  # not a state the network can take: try the next
            if not np.all(np.isfinite(jx)):
                return None
            lam = np.linalg.eigvals(jx)
            lam = np.where(np.abs(lam.real) <= 1e-6 * np.abs(lam), 1j * lam.imag, lam)
            return lam[lam.real <= 0.0]  # a growing mode grows in the model too
        return None

    def use_model(self, model: EngineModel) -> None:
        """Step with ``model`` from now on: the engine arrays of the same network with
        other parameters (the time-stepper's stick/slip history starts afresh)."""
        self.model = model
        self.plan = replace(self.plan, model=model)
        self._engine = self.plan.engine()
        self._c, self._work = self._engine.c, self._engine.work
        if self.method == "timestep":
            _core.ts_prepare(self._c, self._work)
        if getattr(self, "_judge_rk4", False):
            self._check_rk4_substeps()

    @classmethod
    def wrist(cls, params, wrist_options=None, period: float = 1e-3, **kwargs) -> "Stepper":
        """A stepper of the whole wrist (`vsj.wrist.build_wrist`)."""
        return cls(build_wrist(params, wrist_options).assemble(), period, **kwargs)

    # -- sizes and names ----------------------------------------------------------------
    @property
    def n_state(self) -> int:
        """Length of the state vector."""
        return self._n_state

    @property
    def n_inputs(self) -> int:
        """Number of inputs (`input_names`)."""
        return len(self.input_names)

    def input_vector(self, inputs: Mapping[str, float] | Sequence[float] | np.ndarray | None
                     ) -> np.ndarray:
        """Inputs as the array the engine takes (a mapping names a subset; others are 0)."""
        if inputs is None:
            return np.zeros(self.n_inputs)
        if isinstance(inputs, Mapping):
            unknown = sorted(set(inputs) - set(self.input_names))
            if unknown:
                raise InputError(f"stepper: unknown input(s) {', '.join(unknown)}; inputs are "
                                 f"{', '.join(self.input_names)}")
            inputs = [float(inputs.get(ch, 0.0)) for ch in self.input_names]
        u = np.ascontiguousarray(inputs, dtype=float)
        if u.shape != (self.n_inputs,):
            raise InputError(f"stepper: expected {self.n_inputs} inputs "
                             f"({', '.join(self.input_names)}), got shape {u.shape}")
        return u

    def _check_finite(self, state: np.ndarray, inputs: np.ndarray) -> None:
        """InputError naming what is not finite (the engine refuses it too; this
        only finds the names)."""
        bad = [name for name, v in zip(self.input_names, inputs) if not math.isfinite(v)]
        bad += [name for name, v in zip(self.state_names, state) if not math.isfinite(v)]
        if bad:
            raise InputError(f"stepper: {', '.join(bad)} must be finite")

    def _state_vector(self, state) -> np.ndarray:
        y = np.ascontiguousarray(state, dtype=float)
        if y.shape != (self.n_state,):
            raise InputError(f"stepper: expected a state of {self.n_state} values "
                             f"({', '.join(self.state_names)}), got shape {y.shape}")
        return y

    # -- states -------------------------------------------------------------------------
    def initial_state(self, initial: InitialState | None = None, inputs=None) -> np.ndarray:
        """The state for named initial angles, speeds, pivot position and currents.

        Same conventions as `vsj.simulate.simulate` (``initial.speeds`` are flange
        speeds; with ``inputs``, velocity sources already run at their speeds).
        """
        u = self.input_vector(inputs)
        held = {ch: Constant(float(v)) for ch, v in zip(self.structure.channels(), u)}
        plan = prepare(self.structure, held, self.period, self.options,
                       initial or InitialState())
        self.reset_controller()
        model, layout, y0 = plan.model, plan.layout, plan.y0
        n, nm = layout.n, layout.n_motors
        state = np.empty(self.n_state)
        state[:n] = y0[:n]
        state[2 * n:2 * n + nm] = y0[2 * n:2 * n + nm]
        state[2 * n + nm:] = model.src_pos0
        us = u[self.model.src_ch]
        state[n:2 * n] = self.model.mass[:n, :n] @ y0[n:2 * n] + self.model.mass[:n, n:] @ us
        return state

    def reset_controller(self) -> None:
        """Start the controller afresh at the next `step` (block states zero, delay lines
        refilled, noise from its seed); `initial_state` does it too. The controller's
        state lives in the stepper: it closes one loop at a time."""
        if self.controller is not None:
            _core.control_reset(self._c, self._work)

    def control_values(self) -> dict[str, float]:
        """The controller's signals as they hold now (after the last `step`'s last sample):
        ``control.<name>`` of its bus and ``actuator.<channel>``; empty without one."""
        if self.controller is None:
            return {}
        out = np.empty(self.controller.width)
        _core.control_values(self._c, self._work, out)
        names = ([f"control.{n}" for n in self.controller.bus]
                 + [f"actuator.{c}" for c in self.controller.channels])
        return dict(zip(names, out.tolist()))

    def speeds(self, state, inputs) -> np.ndarray:
        """Generalised speeds ``v = M^-1 (p - M_su u)`` [rad/s] of the free coordinates."""
        y = self._state_vector(state)
        u = self.input_vector(inputs)
        n = self.layout.n
        return self.model.Minv @ (y[n:2 * n] - self.model.mass[:n, n:] @ u[self.model.src_ch])

    def angle_rows(self, names: Sequence[str]) -> np.ndarray:
        """Matrix ``C`` with ``C @ state`` = the angles [rad] of named signals or flanges.

        Angles are linear in the state (``A x + B sigma``, `vsj.network`): an
        estimator's measurement model of encoders is exactly this matrix.
        """
        n, nm = self.layout.n, self.layout.n_motors
        by_signal = {s.name: s.flange for s in self.structure.signals}
        C = np.zeros((len(names), self.n_state))
        for k, name in enumerate(names):
            flange = by_signal.get(name, name)
            if flange not in self.structure.nodes:
                raise InputError(f"stepper: unknown signal or flange {name!r}; signals are "
                                 f"{', '.join(by_signal)}")
            rx, ru = self.structure.rows(flange)
            C[k, :n] = rx
            C[k, 2 * n + nm:] = ru
        return C

    def signals(self, state, inputs) -> dict[str, float]:
        """The state as a single run's `vsj.simulate.Result` names it: every named
        signal's angle [rad] and ``.speed`` [rad/s] (``theta_x``, ``theta_x.speed``,
        ``phi_1``, ...), the free flanges not named, and the pivot position ``q``
        [m], for ``inputs`` held at this instant."""
        y = self._state_vector(state)
        u = self.input_vector(inputs)
        n, nm = self.layout.n, self.layout.n_motors
        v = self.speeds(y, u)
        sigma, u_src = y[2 * n + nm:], u[self.model.src_ch]
        named = {s.name: s.flange for s in self.structure.signals}
        taken = set(named.values())
        named.update({f: f for f in self.structure.free if f not in taken})
        out: dict[str, float] = {}
        for name, flange in named.items():
            rx, ru = self.structure.rows(flange)
            out[name] = float(rx @ y[:n] + ru @ sigma)
            out[f"{name}.speed"] = float(rx @ v + ru @ u_src)
        if self.structure.pivot.flange is not None or self.structure.springs:
            out["q"] = self.pivot_position(y)
        return out

    def signal_units(self) -> dict[str, str]:
        """The unit of each of `signals`' names, as a run's `Result.units` gives it."""
        zero = self.signals(np.zeros(self.n_state), np.zeros(self.n_inputs))
        return {name: "m" if name == "q" else "rad/s" if name.endswith(".speed") else "rad"
                for name in zero}

    # -- stepping -----------------------------------------------------------------------
    def step(self, state, inputs, out: np.ndarray | None = None) -> np.ndarray:
        """The state one period later, for ``inputs`` held over the period.

        ``out`` (optional) receives the result, which avoids an allocation;
        it may be ``state`` itself. Raises `SimulationError` if the step fails.
        """
        y = self._state_vector(state)
        u = self.input_vector(inputs)
        if out is None:
            out = y.copy()
        elif out is not y:
            out[:] = y
        try:
            status = self.plan.hold(self._work, out, u)
        except ValueError:
            self._check_finite(y, u)
            raise
        if status != OK:
            values = ", ".join(f"{name}={v:.6g}" for name, v in zip(self.state_names, y))
            raise SimulationError(f"stepper: {STATUS_TEXT[status]} within a period of "
                                  f"{self.period:g} s from the state {values}")
        return out

    def rate(self, state, inputs) -> np.ndarray:
        """Time derivative of the state (see the module docstring)."""
        y = self._state_vector(state).copy()
        u = self.input_vector(inputs)
        dstate = np.empty(self.n_state)
        try:
            status = _core.step_rate(self._c, self._work, y, u, dstate)
        except ValueError:
            self._check_finite(y, u)
            raise
        if status != OK:
            raise SimulationError(f"stepper: {STATUS_TEXT[status]} at the state {y}")
        return dstate

    def pivot_position(self, state) -> float:
        """Pivot position q [m] of a state."""
        y = self._state_vector(state)
        n, nm = self.layout.n, self.layout.n_motors
        return pivot_position(self.model, y[:n], y[2 * n + nm:])

    def jacobian(self, state, inputs) -> tuple[np.ndarray, np.ndarray]:
        """Continuous-time Jacobians ``(d rate/d state, d rate/d inputs)`` at any state.

        Central differences of the compiled right-hand side with Richardson
        extrapolation (`JACOBIAN_STEP` times each variable's scale: 1 rad,
        the momentum of 1 rad/s, 1 A, 1 rad/s, 1 N m, 1 V). Friction laws with
        a jump (``sign``) or a kink (``slope``) at zero speed are not
        differentiable there; the result is then a secant, not a derivative.
        For an extended Kalman filter, discretise with `discretize`.
        """
        y = self._state_vector(state).copy()
        u = self.input_vector(inputs).copy()
        scale_x = self._state_scales()
        scale_u = np.ones(self.n_inputs)
        jx = np.empty((self.n_state, self.n_state))
        ju = np.empty((self.n_state, self.n_inputs))
        for j in range(self.n_state):
            jx[:, j] = self._derivative(y, u, j, scale_x[j], on_state=True)
        for j in range(self.n_inputs):
            ju[:, j] = self._derivative(y, u, j, scale_u[j], on_state=False)
        return jx, ju

    def discretize(self, state, inputs) -> tuple[np.ndarray, np.ndarray]:
        """Discrete-time Jacobians ``(F, G)`` of one period (zero-order hold of `jacobian`)."""
        from scipy.linalg import expm  # lazy: heavy; only discretize() needs it

        jx, ju = self.jacobian(state, inputs)
        ns, ni = jx.shape[0], ju.shape[1]
        block = np.zeros((ns + ni, ns + ni))
        block[:ns, :ns] = jx
        block[:ns, ns:] = ju
        phi = expm(block * self.period)
        return phi[:ns, :ns], phi[:ns, ns:]

    def _state_scales(self) -> np.ndarray:
        n, nm, s = self.layout.n, self.layout.n_motors, self.layout.n_sources
        momentum = np.abs(np.diag(self.model.mass[:n, :n])) if n else np.zeros(0)
        return np.concatenate([np.ones(n), np.maximum(momentum, 1e-300), np.ones(nm),
                               np.ones(s)])

    def _derivative(self, y, u, j, scale, *, on_state: bool) -> np.ndarray:
        target = y if on_state else u

        def f(delta):
            saved = target[j]
            target[j] = saved + delta
            try:
                return self.rate(y, u)
            finally:
                target[j] = saved

        h = JACOBIAN_STEP * scale
        d1 = (f(h) - f(-h)) / (2 * h)
        d2 = (f(h / 2) - f(-h / 2)) / h
        return (4.0 * d2 - d1) / 3.0


def _channel_unit(structure: Structure, channel: str) -> str:
    if channel.startswith("ref."):  # a controller's reference: its measurement's unit
        return "1"
    if any(src.channel == channel for src in structure.sources):
        return "rad/s"
    if any(m.channel == channel for m in structure.motors):
        return "V"
    return "N m"


__all__ = ["Stepper", "OK", "METHODS", "STATUS_TEXT"]

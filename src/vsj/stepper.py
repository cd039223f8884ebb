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
Dormand-Prince 5(4) kernel (`vsj.engine.dopri`) from 0 to ``dt`` with the
run's ``rtol``/``atol``, so a step is the computation `vsj.simulate.simulate`
performs for a run of one period with constant inputs (tests check agreement
to 1e-9). Its cost varies with the dynamics. ``method="rk4"`` takes
``substeps`` classical Runge-Kutta steps of ``dt/substeps``: a fixed cost per
call, for hard real-time loops; its accuracy is the user's choice of
``substeps`` (stable while ``dt/substeps`` times the fastest rate of the
model stays below about 2.8; with the DC motors' armature time constant of
0.1 ms, use at least 8 substeps per millisecond). Friction laws that are
functions of speed only: the ``stiction`` law needs the time-stepping solver
of `vsj.simulate`, and the jump of the ``sign`` law makes ``dopri`` take very
many tiny steps (`benchmarks/friction_laws.py`).

Cost per call (`benchmarks/step_cost.py`: the default wrist, 1 ms period,
arctan friction, inputs changing every period; the 2-core development VM
while shared, so expect some scatter): from Python about 21 us per
`Stepper.step` with ``dopri`` (rtol 1e-8, one or two steps per period) and
28 us with ``rk4`` (4 substeps, 17 evaluations), of which about 8 us are the
Python wrapper and numba's dispatch; from a compiled loop 13 us and 20 us.
One `simulate` call of the same period costs about 1.8 ms (it compiles the
model's arrays and samples every signal), 90 times more. The right-hand side
itself costs about 1.3 us per evaluation.

From compiled code (numba): `step_dopri` and `step_rk4` are numba functions
taking the model and work tuples `Stepper.model` and `Stepper.work`. Call
them from your own ``@numba.njit`` function; numba then calls them directly,
without Python in between::

    from numba import njit
    from vsj.stepper import OK, step_dopri

    @njit
    def run(model, work, state, inputs, dt, rtol, atol, max_steps):
        for k in range(inputs.shape[0]):
            if step_dopri(model, work, state, inputs[k], dt, rtol, atol, max_steps) != OK:
                return k
        return inputs.shape[0]

    run(stepper.model, stepper.work, state, inputs, stepper.period, stepper.rtol,
        stepper.atol, stepper.max_steps)

The state is advanced in place (left unchanged if the step fails; the return
value is the engine's status, `vsj.engine.STATUS_TEXT`). The model's input
arrays are scratch space that every call overwrites: use one `Stepper` per
thread.
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .engine import OK, STATUS_TEXT, compile_model, make_work
from .engine.core import STATUS, Work, eval_derivatives
from .engine.dopri import integrate
from .engine.model import D_M, D_N, EngineModel, friction_laws_for
from .errors import InputError, SimulationError
from .inputs import Constant
from .jit import inline, kernel
from .network import Structure
from .simulate import InitialState, SimulationOptions, prepare

METHODS = ("dopri", "rk4")

#: Relative step of the central differences in `Stepper.jacobian` (times each
#: variable's scale); with Richardson extrapolation the truncation error is
#: O(h^4) and the round-off about 1e-16 / 1e-5 of the derivative's scale.
JACOBIAN_STEP = 1e-5

#: How long the held-input splines run, in periods: stage times never reach
#: the end of a spline, where its integral would be read from a stale table.
_SPLINE_PERIODS = 4.0


# -- compiled kernels ------------------------------------------------------------------


@inline
def _set_inputs(coef, cum, knots, first, src_ch, src_pos0, state, inputs, base):
    """Hold ``inputs`` over the period and start the sources at ``state[base:]``."""
    for c in range(first.shape[0]):
        p = first[c]
        koff = p + c
        coef[p, 0] = inputs[c]
        cum[koff + 1] = inputs[c] * (knots[koff + 1] - knots[koff])
    for j in range(src_ch.shape[0]):
        src_pos0[j] = state[base + j]


@inline
def _to_engine(n, nm, mass, Minv, src_ch, state, inputs, y):
    """Engine state ``[x, v, i]`` from ``[x, p, i, ...]``: ``v = M^-1 (p - M_su u)``."""
    s = src_ch.shape[0]
    for i in range(n):
        y[i] = state[i]
        acc = 0.0
        bound = 0.0
        for r in range(n):
            pr = state[n + r]
            size = abs(pr)
            for j in range(s):
                term = mass[r, n + j] * inputs[src_ch[j]]
                pr -= term
                size += abs(term)
            acc += Minv[i, r] * pr
            bound += abs(Minv[i, r]) * size
        # a speed within the round-off of the cancellation p - M_su u (8 ulp of its
        # terms) is zero: left at 1e-19, it would make the integrator's first step
        # 1e-19 s long with a tight atol (Hairer's initial-step estimate)
        y[n + i] = acc if abs(acc) > 8.0 * 2.220446049250313e-16 * bound else 0.0
    for k in range(nm):
        y[2 * n + k] = state[2 * n + k]


@inline
def _from_engine(n, nm, mass, src_ch, y, inputs, dt, state):
    """Back to ``[x, p, i, sigma]`` after a period (sources moved ``u dt``)."""
    s = src_ch.shape[0]
    for r in range(n):
        state[r] = y[r]
        acc = 0.0
        for i in range(n):
            acc += mass[r, i] * y[n + i]
        for j in range(s):
            acc += mass[r, n + j] * inputs[src_ch[j]]
        state[n + r] = acc
    for k in range(nm):
        state[2 * n + k] = y[2 * n + k]
    base = 2 * n + nm
    for j in range(s):
        state[base + j] += inputs[src_ch[j]] * dt


@kernel
def step_dopri(m, w, state, inputs, dt, rtol, atol, max_steps):
    """Advance ``state`` in place by ``dt`` with adaptive DOPRI5; returns the status.

    ``m``, ``w``: `Stepper.model`, `Stepper.work`; ``inputs``: one value per
    input channel, held over the period. On failure the state is unchanged.
    """
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, \
        cum, first, count = m
    n = dims[D_N]
    nm = dims[D_M]
    ny = 2 * n + nm
    _set_inputs(coef, cum, knots, first, src_ch, src_pos0, state, inputs, ny)
    y = np.empty(ny)
    _to_engine(n, nm, mass, Minv, src_ch, state, inputs, y)
    status, t_stop, steps, rejected = integrate(m, w, y, 0.0, dt, np.empty(0),
                                                rtol, atol, np.inf, max_steps, ny,
                                                np.empty((0, ny)))
    if status == OK:
        _from_engine(n, nm, mass, src_ch, y, inputs, dt, state)
    return status


#: Classical Runge-Kutta: stage nodes and the weights of the previous stage.
_RK4_C = np.array([0.0, 0.5, 0.5, 1.0])
_RK4_W = np.array([1.0, 2.0, 2.0, 1.0]) / 6.0


@kernel
def step_rk4(m, w, state, inputs, dt, substeps):
    """Advance ``state`` in place by ``dt`` with ``substeps`` fixed RK4 steps.

    A fixed cost per call: ``4 substeps + 1`` evaluations of the right-hand
    side. Returns the status; on failure (a non-finite value, the pivot
    leaving its range at the end point) the state is unchanged.
    """
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, \
        cum, first, count = m
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    n = dims[D_N]
    nm = dims[D_M]
    ny = 2 * n + nm
    _set_inputs(coef, cum, knots, first, src_ch, src_pos0, state, inputs, ny)
    y = np.empty(ny)
    _to_engine(n, nm, mass, Minv, src_ch, state, inputs, y)
    k = np.zeros(ny)
    yt = np.empty(ny)
    acc = np.empty(ny)
    h = dt / substeps
    scal[STATUS] = OK
    # one call site of the inlined right-hand side (each one is compiled in full); after
    # the last substep it is evaluated once more, at the end point, for its status
    for sub in range(substeps + 1):
        t = sub * h
        last = sub == substeps
        for stage in range(1 if last else 4):
            a = _RK4_C[stage]
            for i in range(ny):
                yt[i] = y[i] + a * h * k[i] if stage else y[i]
            eval_derivatives(t + a * h, yt, k, dims, mass, Minv, xp, xc, xv, up, uc, uv, par,
                             code, src_ch, src_pos0, knots, coef, cum, first, count, hint, chan,
                             srcw, frw, spw, ldw, mow, gen, scal)
            if last:
                break
            for i in range(ny):
                if stage == 0:
                    acc[i] = 0.0
                acc[i] += _RK4_W[stage] * k[i]
        if not last:
            for i in range(ny):
                y[i] += h * acc[i]
    status = int(scal[STATUS])
    if status == OK:
        _from_engine(n, nm, mass, src_ch, y, inputs, dt, state)
    return status


@kernel
def rate(m, w, state, inputs, dstate):
    """Time derivative of the state ``[x, p, i, sigma]`` at held ``inputs``; returns the status.

    ``dx/dt = v``, ``dp/dt`` = the generalised force (every element's torque
    mapped to the free coordinates), ``di/dt`` from the armature circuits,
    ``dsigma/dt = u``. The time-derivative of the source speeds drops out:
    that is what the momentum coordinates buy.
    """
    dims, mass, Minv, rows, xp, xc, xv, up, uc, uv, par, code, src_ch, src_pos0, knots, coef, \
        cum, first, count = m
    n = dims[D_N]
    nm = dims[D_M]
    ny = 2 * n + nm
    _set_inputs(coef, cum, knots, first, src_ch, src_pos0, state, inputs, ny)
    y = np.empty(ny)
    dy = np.empty(ny)
    _to_engine(n, nm, mass, Minv, src_ch, state, inputs, y)
    hint, chan, srcw, frw, spw, ldw, mow, gen, scal = w
    scal[STATUS] = OK
    eval_derivatives(0.0, y, dy, dims, mass, Minv, xp, xc, xv, up, uc, uv, par, code, src_ch,
                     src_pos0, knots, coef, cum, first, count, hint, chan, srcw, frw, spw, ldw,
                     mow, gen, scal)
    for i in range(n):
        dstate[i] = y[n + i]
        acc = 0.0
        for r in range(n):
            acc += mass[i, r] * dy[n + r]
        dstate[n + i] = acc
    for k in range(nm):
        dstate[2 * n + k] = dy[2 * n + k]
    for j in range(src_ch.shape[0]):
        dstate[ny + j] = inputs[src_ch[j]]
    return int(scal[STATUS])


@inline
def _named(mt, wt):
    """The engine's named tuples from plain ones (cheap in compiled code)."""
    m = EngineModel(mt[0], mt[1], mt[2], mt[3], mt[4], mt[5], mt[6], mt[7], mt[8], mt[9],
                    mt[10], mt[11], mt[12], mt[13], mt[14], mt[15], mt[16], mt[17], mt[18])
    w = Work(wt[0], wt[1], wt[2], wt[3], wt[4], wt[5], wt[6], wt[7], wt[8])
    return m, w


@kernel
def _dopri_from_python(mt, wt, state, inputs, dt, rtol, atol, max_steps):
    m, w = _named(mt, wt)
    return step_dopri(m, w, state, inputs, dt, rtol, atol, max_steps)


@kernel
def _rk4_from_python(mt, wt, state, inputs, dt, substeps):
    m, w = _named(mt, wt)
    return step_rk4(m, w, state, inputs, dt, substeps)


@kernel
def _rate_from_python(mt, wt, state, inputs, dstate):
    m, w = _named(mt, wt)
    return rate(m, w, state, inputs, dstate)


# -- the Python face -------------------------------------------------------------------


class Stepper:
    """One compiled network, advanced one control period per call.

    ``structure``: an assembled network (`vsj.wrist.build_wrist(...).assemble()`
    or any other); ``period`` [s]: the control period; ``options``: friction
    law and tolerances as for `vsj.simulate.simulate` (``rtol`` and ``atol``
    steer ``method="dopri"``, whose steps are bounded by the period only;
    ``max_steps`` bounds them per period); ``substeps`` sets ``method="rk4"``;
    ``pivot_range`` (q_min, q_max) [m] makes a step fail when the pivot leaves
    it.
    """

    def __init__(self, structure: Structure, period: float = 1e-3, *,
                 options: SimulationOptions | None = None, method: str = "dopri",
                 substeps: int = 4, pivot_range: tuple[float, float] | None = None,
                 max_steps: int = 100_000):
        options = options or SimulationOptions()
        options.validate()
        if not (math.isfinite(period) and period > 0.0):
            raise InputError(f"stepper: period must be > 0 s, got {period!r}")
        if method not in METHODS:
            raise InputError(f"stepper: method must be one of {', '.join(METHODS)}, got "
                             f"{method!r}")
        if not (isinstance(substeps, int) and substeps >= 1):
            raise InputError(f"stepper: substeps must be an integer >= 1, got {substeps!r}")
        if "stiction" in friction_laws_for(structure, options.friction,
                                           options.friction_overrides):
            raise InputError("stepper: the stiction friction law needs the time-stepping "
                             "solver of vsj.simulate; the stepper integrates smooth laws "
                             "(viscous, arctan, sign, slope)")
        self.structure = structure
        self.period = float(period)
        self.options = options
        self.method = method
        self.substeps = substeps
        self.max_steps = int(max_steps)
        self.rtol = float(options.rtol)
        self.atol = float(options.atol)
        self.pivot_range = pivot_range
        self.input_names = structure.channels()
        held = {ch: Constant(0.0) for ch in self.input_names}
        self.model, self.layout = compile_model(
            structure, held, _SPLINE_PERIODS * self.period, friction=options.friction,
            friction_overrides=options.friction_overrides, slope_width=options.slope_width,
            pivot_range=pivot_range)
        self.work = make_work(self.model)
        # plain tuples: numba dispatches them from Python in half the time of named ones
        self._plain = (tuple(self.model), tuple(self.work))
        n, nm, s = self.layout.n, self.layout.n_motors, self.layout.n_sources
        self.state_names = tuple(
            [f"{f}.angle" for f in structure.free] + [f"{f}.momentum" for f in structure.free]
            + [f"{m.name}.current" for m in structure.motors]
            + [f"{src.flange}.angle" for src in structure.sources])
        self.state_units = tuple(["rad"] * n + ["N m s"] * n + ["A"] * nm + ["rad"] * s)
        self.input_units = tuple(_channel_unit(structure, ch) for ch in self.input_names)
        self._n_state = 2 * n + nm + s

    @classmethod
    def wrist(cls, params, wrist_options=None, period: float = 1e-3, **kwargs) -> "Stepper":
        """A stepper of the whole wrist (`vsj.wrist.build_wrist`), with its pivot range."""
        from .wrist import build_wrist, pivot_range

        kwargs.setdefault("pivot_range", pivot_range(params))
        return cls(build_wrist(params, wrist_options).assemble(), period, **kwargs)

    # -- sizes and names ----------------------------------------------------------------
    @property
    def n_state(self) -> int:
        return self._n_state

    @property
    def n_inputs(self) -> int:
        return len(self.input_names)

    def input_vector(self, inputs: Mapping[str, float] | Sequence[float] | np.ndarray | None
                     ) -> np.ndarray:
        """Inputs as the array the kernels take (a mapping names a subset; others are 0)."""
        if inputs is None:
            return np.zeros(self.n_inputs)
        if isinstance(inputs, Mapping):
            unknown = sorted(set(inputs) - set(self.input_names))
            if unknown:
                raise InputError(f"stepper: unknown input(s) {', '.join(unknown)}; inputs are "
                                 f"{', '.join(self.input_names)}")
            return np.array([float(inputs.get(ch, 0.0)) for ch in self.input_names])
        u = np.ascontiguousarray(inputs, dtype=float)
        if u.shape != (self.n_inputs,):
            raise InputError(f"stepper: expected {self.n_inputs} inputs "
                             f"({', '.join(self.input_names)}), got shape {u.shape}")
        return u

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
        held = {ch: Constant(float(v)) for ch, v in zip(self.input_names, u)}
        model, layout, y0 = prepare(self.structure, held, self.period, self.options,
                                    initial or InitialState(), self.pivot_range)
        n, nm = layout.n, layout.n_motors
        state = np.empty(self.n_state)
        state[:n] = y0[:n]
        state[2 * n:2 * n + nm] = y0[2 * n:2 * n + nm]
        state[2 * n + nm:] = model.src_pos0
        us = u[self.model.src_ch]
        state[n:2 * n] = self.model.mass[:n, :n] @ y0[n:2 * n] + self.model.mass[:n, n:] @ us
        return state

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
        if self.method == "dopri":
            status = _dopri_from_python(*self._plain, out, u, self.period, self.rtol,
                                        self.atol, self.max_steps)
        else:
            status = _rk4_from_python(*self._plain, out, u, self.period, self.substeps)
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
        status = _rate_from_python(*self._plain, y, u, dstate)
        if status != OK:
            raise SimulationError(f"stepper: {STATUS_TEXT[status]} at the state {y}")
        return dstate

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
        from scipy.linalg import expm

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
    if any(src.channel == channel for src in structure.sources):
        return "rad/s"
    if any(m.channel == channel for m in structure.motors):
        return "V"
    return "N m"


__all__ = ["Stepper", "step_dopri", "step_rk4", "rate", "OK", "METHODS", "STATUS_TEXT"]

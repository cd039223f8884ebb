"""Safe and fast: the minimum time of a rest-to-rest motion whose every instant is safe.

Bicchi and Tonietti's "safe brachistochrone" ("Fast and soft-arm tactics", IEEE Robotics
and Automation Magazine 11(2), 2004): move the link between two angles, from rest to
rest, as fast as the motors allow, while a collision at any instant would stay within a
force bound. Their finding: a joint whose stiffness can change gets there sooner than a
stiff one at the same bound, and the optimal stiffness goes stiff (to accelerate), soft
(at speed, where a collision is likely to hurt), stiff (to brake).

Here the problem is posed on the wrist's own ``theta_x`` axis (`vsj.studies.axis`): the
motors' voltage (both output motors alike, within their limit), the pivot position
``q`` (within its range, moved no faster than the stiffness motor can move it), the
joint's deflection within what it holds. Safety is the reduced impact model
(`vsj.studies.impact`): the link's speed may not exceed the speed whose impact on the
body reaches the force bound at the stiffness of that instant (the impact of the motor
side and the link at one speed, the joint undeflected, every contact of the collision).
The strategies compared:

``rigid``
    the same motors behind a rigid transmission (no elastic element): the reference of
    Bicchi and Tonietti's comparison;
``stiffest``
    the wrist at its stiffest setting, held;
``best fixed``
    the wrist at the one setting, held, that is fastest;
``schedule``
    ``q(t)`` optimised along the motion, moved by the stiffness motor;
``instant schedule``
    the same with a stiffness that changes at once (the idealised joint of the
    published studies).

Each is a minimum-time optimal control problem solved by direct collocation
(`vsj.studies.collocation`). `verify` runs the optimal commands through vsj's engine on
the real, nonlinear wrist (Coulomb friction, the elastic element's own law, DC motors)
and strikes a hand surrogate (`vsj.environment.Body`) at several instants.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.optimize import minimize_scalar

from ..control.wrist import wrist_kinematics
from ..environment import Body, Environment, add_environment
from ..errors import InputError, SimulationError
from ..inputs import Constant, Position, Table
from ..params import Parameters
from ..simulate import InitialState, SimulationOptions, simulate
from ..wrist import WristOptions, build_wrist
from . import collocation
from .axis import AxisModel, axis_model
from .impact import HAND, BodyModel, force_per_speed, impact, safe_speed

STRATEGIES = ("rigid", "stiffest", "best fixed", "schedule", "instant schedule")


@dataclass(frozen=True)
class SafeMotion:
    """The problem: move ``theta_x`` by ``distance`` [rad] from rest to rest; a
    collision of the tip of a link ``link`` [m] long (``tip_mass`` [kg] at its tip) with
    ``body`` must stay within ``body.force_limit``. ``nodes``: collocation intervals;
    ``safety_points``: pivot positions at which the safe speed is computed (then
    interpolated, monotone cubic); ``fixed_candidates``: settings tried before the best
    fixed one is refined."""

    distance: float = 1.0
    link: float = 0.1
    tip_mass: float = 0.0
    body: BodyModel = HAND
    nodes: int = 30
    safety_points: int = 15
    fixed_candidates: int = 7

    def check(self) -> None:
        """`InputError` naming the field for a value out of range."""
        for key, low in (("distance", 0.0), ("link", 0.0)):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                    or v <= low:
                raise InputError(f"safe motion: {key} must be a finite number > {low:g}, "
                                 f"got {v!r}")
        t = self.tip_mass
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t) \
                or t < 0:
            raise InputError(f"safe motion: tip_mass must be a finite number >= 0 kg, got {t!r}")
        if not isinstance(self.body, BodyModel):
            raise InputError(f"safe motion: body must be a vsj.studies.BodyModel, got "
                             f"{type(self.body).__name__}")
        self.body.check()
        for key, low in (("nodes", 4), ("safety_points", 4), ("fixed_candidates", 2)):
            v = getattr(self, key)
            if isinstance(v, bool) or not isinstance(v, int) or v < low:
                raise InputError(f"safe motion: {key} must be a whole number >= {low}, "
                                 f"got {v!r}")


@dataclass(frozen=True)
class SafeSpeed:
    """The safe link speed over the stiffness setting: at pivot positions ``q`` [m]
    (joint stiffness ``stiffness`` [N m/rad]) the peak force per tip speed
    ``force_per_speed`` [N s/m] and the largest safe link speed ``speed`` [rad/s];
    ``rigid_force_per_speed`` and ``rigid_speed`` the same for a rigid joint;
    ``first_contact`` the peak per speed of the first contact alone [N s/m] (what the
    later contacts add shows against it)."""

    q: np.ndarray
    stiffness: np.ndarray
    force_per_speed: np.ndarray
    speed: np.ndarray
    first_contact: np.ndarray
    rigid_force_per_speed: float
    rigid_speed: float

    def __call__(self, q):
        """``(speed [rad/s], dspeed/dq [rad/(s m)])`` at pivot positions ``q`` [m]."""
        f = PchipInterpolator(self.q, self.speed)
        q = np.clip(np.asarray(q, dtype=float), self.q[0], self.q[-1])
        return f(q), f(q, 1)


def safe_speeds(model: AxisModel, setup: SafeMotion) -> SafeSpeed:
    """`SafeSpeed` of ``model`` for ``setup``'s link and body."""
    q = np.linspace(model.q_min, model.q_max, setup.safety_points)
    K = model.joint.stiffness(q)
    per, first = [], []
    for k in K:
        omega = 1.0 / setup.link
        hit = impact(model.mass, float(k), setup.link, setup.body, speed_motor=omega,
                     speed_link=omega, tip_mass=setup.tip_mass)
        per.append(hit.peak_force)
        first.append(hit.first_peak)
    per = np.array(per)
    rigid = force_per_speed(model.mass, math.inf, setup.link, setup.body,
                            tip_mass=setup.tip_mass)
    limit = setup.body.force_limit / setup.link
    return SafeSpeed(q=q, stiffness=K, force_per_speed=per, speed=limit / per,
                     first_contact=np.array(first), rigid_force_per_speed=rigid,
                     rigid_speed=safe_speed(model.mass, math.inf, setup.link, setup.body,
                                            tip_mass=setup.tip_mass))


# -- the elastic axis as a collocation problem ----------------------------------------


def _elastic_problem(model: AxisModel, setup: SafeMotion, safe: SafeSpeed,
                     q_range: tuple[float, float], pivot_free: bool, T_guess: float):
    """States ``(theta_m, theta, omega_m, omega, q)``, controls ``(V, dq/dt)``."""
    Theta = setup.distance
    w_scale = max(Theta / T_guess, 1.0)
    r_top = float(np.max(model.pivot_rate_limit(np.linspace(model.q_min, model.q_max, 50))[0]))
    hold_top = float(np.max(model.joint.holdable))
    h_scale = hold_top

    def dynamics(X, U):
        acc, d_state, d_volt, d_q = model.acceleration(X[:, :4], U[:, 0], X[:, 4])
        n = len(X)
        f = np.column_stack([X[:, 2], X[:, 3], acc[:, 0], acc[:, 1], U[:, 1]])
        A = np.zeros((n, 5, 5))
        A[:, 0, 2] = 1.0
        A[:, 1, 3] = 1.0
        A[:, 2:4, 0:4] = d_state
        A[:, 2:4, 4] = d_q
        B = np.zeros((n, 5, 2))
        B[:, 2:4, 0] = d_volt
        B[:, 4, 1] = 1.0
        return f, A, B

    def path(X, U):
        n = len(X)
        q = X[:, 4]
        c = np.empty((n, 6))
        Cx = np.zeros((n, 6, 5))
        Cu = np.zeros((n, 6, 2))
        c[:, :4], Cx[:, :4, :4], Cx[:, :4, 4] = _speed_and_hold(model, safe, X, q, w_scale,
                                                               h_scale)
        rmax, drmax = model.pivot_rate_limit(q)
        for j, sgn in enumerate((1.0, -1.0)):
            c[:, 4 + j] = (rmax - sgn * U[:, 1]) / r_top
            Cx[:, 4 + j, 4] = drmax / r_top
            Cu[:, 4 + j, 1] = -sgn / r_top
        return c, Cx, Cu

    big = 10.0 * max(float(np.max(safe.speed)), model.no_load_speed)
    x_lo = np.array([-4 * Theta, -4 * Theta, -big, -big, q_range[0]])
    x_hi = np.array([5 * Theta, 5 * Theta, big, big, q_range[1]])
    r_bound = r_top if pivot_free else 0.0
    V = model.voltage_limit
    return collocation.Problem(
        dynamics=dynamics, nx=5, nu=2, x_bounds=(x_lo, x_hi),
        u_bounds=(np.array([-V, -r_bound]), np.array([V, r_bound])),
        first=np.array([0.0, 0.0, 0.0, 0.0, np.nan]),
        last=np.array([Theta, Theta, 0.0, 0.0, np.nan]),
        x_scale=np.array([Theta, Theta, w_scale, w_scale, model.q_max - model.q_min]),
        u_scale=np.array([V, r_top]), T_bounds=(1e-3 * T_guess, 50.0 * T_guess), path=path)


def _speed_and_hold(model: AxisModel, safe: SafeSpeed, X, q, w_scale: float,
                    h_scale: float):
    """The path constraints both problems share, scaled, >= 0 where met: the link speed
    within the safe speed at ``q`` either way (``X[:, 3]``), and the deflection ``X[:, 0] -
    X[:, 1]`` within what the joint holds at ``q`` either way. Returns the values (n, 4),
    their derivatives in the first four states (n, 4, 4) and in ``q`` (n, 4)."""
    n = len(X)
    ws, dws = safe(q)
    hold, dhold = model.joint.holdable_deflection(q)
    delta = X[:, 0] - X[:, 1]
    c = np.empty((n, 4))
    Cx = np.zeros((n, 4, 4))
    Cq = np.empty((n, 4))
    for j, sgn in enumerate((1.0, -1.0)):
        c[:, j] = (ws - sgn * X[:, 3]) / w_scale
        Cx[:, j, 3] = -sgn / w_scale
        Cq[:, j] = dws / w_scale
        c[:, 2 + j] = (hold - sgn * delta) / h_scale
        Cx[:, 2 + j, 0] = -sgn / h_scale
        Cx[:, 2 + j, 1] = sgn / h_scale
        Cq[:, 2 + j] = dhold / h_scale
    return c, Cx, Cq


def _instant_problem(model: AxisModel, setup: SafeMotion, safe: SafeSpeed, T_guess: float):
    """The idealised joint whose stiffness changes at once: states ``(theta_m, theta,
    omega_m, omega)``, controls ``(V, q)`` (the pivot a control, linear between nodes)."""
    Theta = setup.distance
    w_scale = max(Theta / T_guess, 1.0)
    h_scale = float(np.max(model.joint.holdable))

    def dynamics(X, U):
        acc, d_state, d_volt, d_q = model.acceleration(X, U[:, 0], U[:, 1])
        n = len(X)
        f = np.column_stack([X[:, 2], X[:, 3], acc[:, 0], acc[:, 1]])
        A = np.zeros((n, 4, 4))
        A[:, 0, 2] = 1.0
        A[:, 1, 3] = 1.0
        A[:, 2:4, :] = d_state
        B = np.zeros((n, 4, 2))
        B[:, 2:4, 0] = d_volt
        B[:, 2:4, 1] = d_q
        return f, A, B

    def path(X, U):
        n = len(X)
        Cu = np.zeros((n, 4, 2))
        c, Cx, Cu[:, :, 1] = _speed_and_hold(model, safe, X, U[:, 1], w_scale, h_scale)
        return c, Cx, Cu

    big = 10.0 * max(float(np.max(safe.speed)), model.no_load_speed)
    V = model.voltage_limit
    return collocation.Problem(
        dynamics=dynamics, nx=4, nu=2,
        x_bounds=(np.array([-4 * Theta, -4 * Theta, -big, -big]),
                  np.array([5 * Theta, 5 * Theta, big, big])),
        u_bounds=(np.array([-V, model.q_min]), np.array([V, model.q_max])),
        first=np.array([0.0, 0.0, 0.0, 0.0]), last=np.array([Theta, Theta, 0.0, 0.0]),
        x_scale=np.array([Theta, Theta, w_scale, w_scale]),
        u_scale=np.array([V, model.q_max - model.q_min]),
        T_bounds=(1e-3 * T_guess, 50.0 * T_guess), path=path)


def _rigid_problem(model: AxisModel, setup: SafeMotion, safe: SafeSpeed, T_guess: float):
    """The same motors behind a rigid transmission: states ``(theta, omega)``, control
    ``V``."""
    one = np.ones(2)
    J = float(one @ model.mass @ one)
    C = float(one @ (np.asarray(model.back_emf) + np.asarray(model.damping)) @ one)
    g = float(np.sum(model.voltage_gain))
    Theta = setup.distance
    w_scale = max(Theta / T_guess, 1.0)
    ws = safe.rigid_speed

    def dynamics(X, U):
        n = len(X)
        f = np.column_stack([X[:, 1], (g * U[:, 0] - C * X[:, 1]) / J])
        A = np.zeros((n, 2, 2))
        A[:, 0, 1] = 1.0
        A[:, 1, 1] = -C / J
        B = np.zeros((n, 2, 1))
        B[:, 1, 0] = g / J
        return f, A, B

    def path(X, U):
        n = len(X)
        c = np.column_stack([(ws - X[:, 1]) / w_scale, (ws + X[:, 1]) / w_scale])
        Cx = np.zeros((n, 2, 2))
        Cx[:, 0, 1] = -1.0 / w_scale
        Cx[:, 1, 1] = 1.0 / w_scale
        return c, Cx, np.zeros((n, 2, 1))

    V = model.voltage_limit
    big = 10.0 * max(ws, model.no_load_speed)
    return collocation.Problem(
        dynamics=dynamics, nx=2, nu=1, x_bounds=(np.array([-4 * Theta, -big]),
                                                 np.array([5 * Theta, big])),
        u_bounds=(np.array([-V]), np.array([V])), first=np.array([0.0, 0.0]),
        last=np.array([Theta, 0.0]), x_scale=np.array([Theta, w_scale]),
        u_scale=np.array([V]), T_bounds=(1e-3 * T_guess, 50.0 * T_guess), path=path)


def _time_guess(model: AxisModel, setup: SafeMotion, top: float) -> float:
    """A rest-to-rest time to start from [s]: the distance at the slower of the motors'
    and the safe speed, plus the motors' mechanical time constant twice over."""
    J = float(np.ones(2) @ model.mass @ np.ones(2))
    tau = J / float(model.back_emf[0][0])
    return setup.distance / min(top, model.no_load_speed) + 4.0 * tau


def _smooth_guess(model: AxisModel, setup: SafeMotion, T: float, nodes: int, q: float):
    """Minimum-jerk states and the rigid voltages that would drive them, at ``q``."""
    s = np.linspace(0.0, 1.0, nodes + 1)
    Theta = setup.distance
    theta = Theta * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)
    omega = Theta * (30 * s ** 2 - 60 * s ** 3 + 30 * s ** 4) / T
    alpha = Theta * (60 * s - 180 * s ** 2 + 120 * s ** 3) / T ** 2
    one = np.ones(2)
    J = float(one @ model.mass @ one)
    C = float(one @ (np.asarray(model.back_emf) + np.asarray(model.damping)) @ one)
    V = np.clip((J * alpha + C * omega) / float(np.sum(model.voltage_gain)),
                -model.voltage_limit, model.voltage_limit)
    X = np.column_stack([theta, theta, omega, omega, np.full_like(s, q)])
    U = np.column_stack([V, np.zeros_like(s)])
    return X, U


@dataclass
class Strategy:
    """One strategy's optimum: ``name`` (one of `STRATEGIES`), the collocation
    `Solution` (``solution.states`` holds ``theta_m, theta, omega_m, omega, q`` for the
    elastic strategies, ``theta, omega`` for ``rigid``), ``T`` [s], and for the best
    fixed setting the candidates tried (``candidates``: q [m] -> T [s])."""

    name: str
    solution: collocation.Solution
    candidates: dict = field(default_factory=dict)

    @property
    def T(self) -> float:
        """The minimum time [s]."""
        return self.solution.T

    @property
    def q(self) -> np.ndarray:
        """The pivot position at each node [m] (NaN for the rigid joint)."""
        s, u = self.solution.states, self.solution.controls
        if s.shape[1] == 5:
            return s[:, 4]
        return u[:, 1] if u.shape[1] == 2 else np.full(len(s), np.nan)

    @property
    def link_speed(self) -> np.ndarray:
        """The link's speed at each node [rad/s]."""
        s = self.solution.states
        return s[:, 3] if s.shape[1] >= 4 else s[:, 1]

    @property
    def deflection(self) -> np.ndarray:
        """The joint's deflection ``theta_m - theta`` at each node [rad] (NaN for the
        rigid joint)."""
        s = self.solution.states
        return s[:, 0] - s[:, 1] if s.shape[1] >= 4 else np.full(len(s), np.nan)


def with_tip(model: AxisModel, setup: SafeMotion) -> AxisModel:
    """``model`` with ``setup``'s tip mass on the link (its inertia ``m l^2``): the model
    the motion is optimised on (the impact model takes the tip mass on its own)."""
    if setup.tip_mass == 0:
        return model
    mass = np.array(model.mass, dtype=float)
    mass[1, 1] += setup.tip_mass * setup.link ** 2
    return replace(model, mass=mass)


def integrated_error(model: AxisModel, strategy: Strategy) -> float:
    """The collocation's own error: the strategy's commands (voltage linear between the
    nodes, and the pivot's path) integrated by `AxisModel.simulate` (DOP853 at rtol
    1e-9); returns how far theta ends from the collocation's final angle [rad]. The
    rigid joint returns NaN (its model is not an `AxisModel`)."""
    sol = strategy.solution
    if sol.states.shape[1] < 4:
        return math.nan
    t, V, q = sol.time, sol.controls[:, 0], strategy.q
    states = model.simulate(np.array([0.0, sol.T]), lambda s: float(np.interp(s, t, V)),
                            lambda s: float(np.interp(s, t, q)))
    return float(states[-1, 1] - sol.states[-1, 1])


def _checked(name: str, sol: collocation.Solution, feasibility: float) -> collocation.Solution:
    if not sol.success or sol.constraint_violation > feasibility:
        raise SimulationError(f"safe motion, {name}: the optimiser did not converge "
                              f"({sol.message}; largest constraint violation "
                              f"{sol.constraint_violation:.2e} after {sol.iterations} "
                              f"iterations)")
    return sol


#: Largest scaled constraint violation accepted at an optimum: the defects are scaled by
#: the states' sizes, so 1e-6 is a part in a million of the distance or speed; SLSQP
#: meets its constraints to about its own ftol (1e-9) when it converges.
FEASIBILITY = 1e-6


def _fixed(model, setup, safe, q, T_guess, start=None) -> collocation.Solution:
    """The minimum-time motion at the fixed setting ``q``: from ``start`` (another
    setting's optimum) if given, else from a minimum-jerk guess at ``T_guess`` and, if
    that does not converge, at half again as long."""
    problem = _elastic_problem(model, setup, safe, (q, q), False, T_guess)
    if start is not None:
        X, U = start.states.copy(), start.controls.copy()
        X[:, 4] = q
        U[:, 1] = 0.0
        return collocation.solve(problem, setup.nodes, X, U, start.T)
    for T0 in (T_guess, 1.5 * T_guess):
        X, U = _smooth_guess(model, setup, T0, setup.nodes, q)
        sol = collocation.solve(problem, setup.nodes, X, U, T0)
        if sol.success and sol.constraint_violation <= FEASIBILITY:
            break
    return sol


def _converged(sol: collocation.Solution) -> bool:
    return sol.success and sol.constraint_violation <= FEASIBILITY


def _best_fixed(model, setup, safe, T_guess, tried: dict) -> None:
    """Fill ``tried`` (q -> optimum, holding the stiffest's) with the fixed settings'
    optima: `SafeMotion.fixed_candidates` settings over the range, each started from the
    stiffest's optimum; the best of them refined between its neighbours; then the
    settings of the grid solved again from the best optimum found (a minimum-time problem
    has local optima, and a neighbour's is often the better start), keeping the faster."""
    stiffest = tried[model.q_min]
    grid = [float(q) for q in np.linspace(model.q_min, model.q_max, setup.fixed_candidates)]
    for q in grid[1:]:
        sol = _fixed(model, setup, safe, q, T_guess, start=stiffest)
        if not _converged(sol):
            sol = _fixed(model, setup, safe, q, T_guess)
        if _converged(sol):
            tried[q] = sol
    qs = sorted(tried)
    k = int(np.argmin([tried[q].T for q in qs]))
    lo, hi = qs[max(k - 1, 0)], qs[min(k + 1, len(qs) - 1)]
    if hi > lo:
        worst = max(tried[q].T for q in qs)

        def time_at(q):
            sol = _fixed(model, setup, safe, float(q), T_guess, start=tried[qs[k]])
            if not _converged(sol):
                return 2.0 * worst  # not converged there: never taken as the best
            tried[float(q)] = sol
            return sol.T
        # T is flat at its minimum (second order in q), so a thousandth of the range
        # (42 um on the wrist) finds it to far better than the collocation's accuracy
        minimize_scalar(time_at, bounds=(lo, hi), method="bounded",
                        options={"xatol": 1e-3 * (model.q_max - model.q_min), "maxiter": 10})
    leader = tried[min(tried, key=lambda q: tried[q].T)]
    for q in grid:
        if q in tried and tried[q] is not leader:
            sol = _fixed(model, setup, safe, q, T_guess, start=leader)
            if _converged(sol) and sol.T < tried[q].T:
                tried[q] = sol


def optimise(model: AxisModel, setup: SafeMotion | None = None,
             strategies=STRATEGIES) -> dict[str, Strategy]:
    """The minimum-time motion of each of ``strategies`` (names of `STRATEGIES`).
    Returns name -> `Strategy`; `SimulationError` if an optimisation fails.

    A minimum-time problem has local optima, so each elastic strategy starts from what
    the others found: the fixed settings from the stiffest's optimum and then from the
    best of them (`_best_fixed`, which may also improve the stiffest's), the schedules
    from the best fixed setting's."""
    setup = setup or SafeMotion()
    setup.check()
    if not isinstance(model, AxisModel):
        raise InputError(f"safe motion: model must be a vsj.studies.AxisModel, got "
                         f"{type(model).__name__}")
    unknown = [s for s in strategies if s not in STRATEGIES]
    if unknown or not strategies:
        raise InputError(f"safe motion: unknown strategies {unknown}; choose from "
                         f"{', '.join(STRATEGIES)}")
    safe = safe_speeds(model, setup)
    model = with_tip(model, setup)
    T_guess = _time_guess(model, setup, float(np.min(safe.speed)))
    out: dict[str, Strategy] = {}
    if "rigid" in strategies:
        problem = _rigid_problem(model, setup, safe, _time_guess(model, setup, safe.rigid_speed))
        X, U = _smooth_guess(model, setup, T_guess, setup.nodes, 0.0)
        sol = collocation.solve(problem, setup.nodes, X[:, [1, 3]], U[:, :1], T_guess)
        out["rigid"] = Strategy("rigid", _checked("rigid", sol, FEASIBILITY))
    elastic = {"stiffest", "best fixed", "schedule", "instant schedule"} & set(strategies)
    if not elastic:
        return out
    stiffest = _checked("stiffest", _fixed(model, setup, safe, model.q_min, T_guess),
                        FEASIBILITY)
    tried: dict[float, collocation.Solution] = {model.q_min: stiffest}
    if elastic - {"stiffest"}:
        _best_fixed(model, setup, safe, T_guess, tried)
    if "stiffest" in strategies:
        out["stiffest"] = Strategy("stiffest", tried[model.q_min])
    best = tried[min(tried, key=lambda q: tried[q].T)]
    if "best fixed" in strategies:
        out["best fixed"] = Strategy("best fixed", best,
                                     candidates={q: tried[q].T for q in sorted(tried)})
    if "schedule" in strategies:
        problem = _elastic_problem(model, setup, safe, (model.q_min, model.q_max), True,
                                   T_guess)
        sol = collocation.solve(problem, setup.nodes, best.states, best.controls, best.T)
        out["schedule"] = Strategy("schedule", _checked("schedule", sol, FEASIBILITY))
    if "instant schedule" in strategies:
        problem = _instant_problem(model, setup, safe, T_guess)
        U = np.column_stack([best.controls[:, 0], best.states[:, 4]])
        sol = collocation.solve(problem, setup.nodes, best.states[:, :4], U, best.T)
        out["instant schedule"] = Strategy("instant schedule",
                                           _checked("instant schedule", sol, FEASIBILITY))
    return out


# -- the optimum on the real wrist ---------------------------------------------------

#: How long the engine's runs go on after the motion's end [s]: the motion is rest to
#: rest, so what moves after T is the trajectory's error (friction, the reduced model's
#: neglects) ringing out.
SETTLE = 0.05
#: The motors' voltage falls from its last value to zero over this time after T [s]: a
#: hundredth of the motors' mechanical time constant (about 5 ms).
OFF_RAMP = 5e-5


@dataclass
class Verification:
    """A strategy's optimal commands run by vsj's engine on the whole wrist.

    The free run: ``time`` [s], the link's ``angle`` [rad] and ``speed`` [rad/s], the
    pivot ``q`` [m]; ``final_error`` [rad] (theta_x at T minus the target) and
    ``residual`` [rad] (the largest ``|theta_x - target|`` after T, the motors at 0 V). The strikes: at each of
    ``instants`` [s] a free hand surrogate (`vsj.environment.Body`, the body's mass and
    contact stiffness) placed where the link is then; ``first_peak`` [N] (the first
    contact's peak), ``peak`` [N] (over the rest of the motion, the motors going on with
    their plan), ``predicted_first`` and ``predicted`` [N] (the reduced impact model from
    the engine's state at the touch: the motor side's and the link's speeds and the
    joint's deflection)."""

    strategy: str
    time: np.ndarray
    angle: np.ndarray
    speed: np.ndarray
    q: np.ndarray
    final_error: float
    residual: float
    instants: np.ndarray
    first_peak: np.ndarray
    peak: np.ndarray
    predicted_first: np.ndarray
    predicted: np.ndarray
    touch_speed: np.ndarray


def _commands(strategy: Strategy, structure, kin, params: Parameters):
    """The engine's inputs for a strategy: each output motor's voltage (linear between
    the nodes, held after T) and, for a schedule, the pivot input's angle."""
    sol = strategy.solution
    t = tuple(sol.time)
    signs = np.sign(kin.to_rotors[:2, 0])
    # at T the motion is at rest and nothing loads it: the motors go to 0 V (within
    # OFF_RAMP of T), as a controller taking over would hold it, not on braking
    off = (*t, sol.time[-1] + OFF_RAMP)
    inputs = {kin.channels[j]: Table(off, (*(signs[j] * sol.controls[:, 0]), 0.0))
              for j in range(2)}
    q = sol.states[:, 4]
    if strategy.name == "schedule":
        per_input = float(structure.pivot_rows()[1][0])
        angle = np.arcsin(q / structure.pivot.amplitude) / per_input
        inputs["motor_s"] = Position(Table(t, tuple(angle), "cubic"))
    else:
        inputs[kin.channels[2]] = Constant(0.0)
    return inputs, float(q[0])


def verify(params: Parameters, strategy: Strategy, setup: SafeMotion, *,
           instants=(0.1, 0.3, 0.5, 0.7, 0.9), model: AxisModel | None = None,
           friction: str = "arctan") -> Verification:
    """Run ``strategy``'s optimal commands through vsj's engine on the wrist (DC motors;
    a schedule's pivot driven along its q(t) by the pivot's drive as a velocity source)
    and strike a hand surrogate at the fractions ``instants`` of the motion's time.
    `InputError` for a strategy the wrist cannot run (``rigid``, ``instant schedule``);
    `SimulationError` if a run fails."""
    if strategy.name not in ("stiffest", "best fixed", "schedule"):
        raise InputError(f"verify: the wrist cannot run strategy {strategy.name!r} (it has "
                         "neither a rigid joint nor a stiffness that changes at once)")
    setup.check()
    fractions = np.asarray(instants, dtype=float)
    if fractions.ndim != 1 or not len(fractions) or np.any(fractions <= 0) \
            or np.any(fractions >= 1):
        raise InputError(f"verify: instants must be fractions of the motion's time in "
                         f"(0, 1), got {instants!r}")
    model = model or axis_model(params)
    drive = "velocity" if strategy.name == "schedule" else "dc"

    def network(contacts=()):
        net = build_wrist(params, WristOptions(motors="dc", pivot_drive=drive))
        env = Environment(link=setup.link, tip_mass=setup.tip_mass, contacts=contacts)
        return add_environment(net, env).assemble()

    free = network()
    kin = wrist_kinematics(free) if drive == "dc" else None
    if kin is None:
        kin = wrist_kinematics(build_wrist(params, WristOptions(motors="dc", pivot_drive="dc"))
                               .assemble())
    inputs, q0 = _commands(strategy, free, kin, params)
    T = strategy.T
    options = SimulationOptions(friction=friction, rtol=1e-9, atol=1e-11, output_step=1e-5)
    run = simulate(free, inputs, T + SETTLE, initial=InitialState(q=q0), options=options,
                   ports=False)
    if not run.success:
        raise SimulationError(f"verify {strategy.name}: the free run failed: {run.message}")
    angle, speed = run["theta_x"], run["theta_x.speed"]
    w = kin.to_wrist[0, :2]
    after = run.time >= T
    Theta = setup.distance
    final_error = float(np.interp(T, run.time, angle) - Theta)
    residual = float(np.max(np.abs(angle[after] - Theta)))
    firsts, peaks, pred_first, pred, touch = [], [], [], [], []
    for frac in fractions:
        t_hit = frac * T
        target = float(np.interp(t_hit, run.time, angle))
        v_link = float(np.interp(t_hit, run.time, speed))
        if v_link <= 0:
            raise InputError(f"verify: the link is not moving forward at {frac:g} T")
        body = Body("hand", angle=target, mass=setup.body.mass, stiffness=setup.body.stiffness)
        hit = simulate(network((body,)), inputs, T + SETTLE, initial=InitialState(q=q0),
                       options=options, ports=False)
        if not hit.success:
            raise SimulationError(f"verify {strategy.name}: the strike at {t_hit:g} s failed: "
                                  f"{hit.message}")
        force = hit["contact.hand.force"]
        on = np.flatnonzero(force > 0)
        if not len(on):
            raise SimulationError(f"verify {strategy.name}: the link never reached the body "
                                  f"placed at {target:g} rad")
        gaps = np.flatnonzero(np.diff(on) > 1)
        first_end = on[gaps[0]] + 1 if len(gaps) else on[-1] + 1
        firsts.append(float(np.max(force[on[0]:first_end + 1])))
        peaks.append(float(np.max(force)))
        # the state at the last sample before the touch (the runs are the same up to it)
        i = max(on[0] - 1, 0)
        K = float(model.joint.stiffness(float(hit["q"][i])))
        hit_motor = w[0] * hit["motor_1.rotor.speed"][i] + w[1] * hit["motor_2.rotor.speed"][i]
        hit_motor_angle = w[0] * hit["motor_1.rotor"][i] + w[1] * hit["motor_2.rotor"][i]
        reduced = impact(model.mass, K, setup.link, setup.body,
                         speed_motor=float(hit_motor), speed_link=float(hit["theta_x.speed"][i]),
                         deflection=float(hit_motor_angle - hit["theta_x"][i]),
                         tip_mass=setup.tip_mass)
        pred_first.append(reduced.first_peak)
        pred.append(reduced.peak_force)
        touch.append(float(hit["theta_x.speed"][i]))
    return Verification(strategy=strategy.name, time=run.time, angle=angle, speed=speed,
                        q=run["q"], final_error=final_error, residual=residual,
                        instants=fractions * T, first_peak=np.array(firsts),
                        peak=np.array(peaks), predicted_first=np.array(pred_first),
                        predicted=np.array(pred), touch_speed=np.array(touch))


__all__ = ["STRATEGIES", "SafeMotion", "SafeSpeed", "Strategy", "Verification",
           "integrated_error", "optimise", "safe_speeds", "verify", "with_tip"]

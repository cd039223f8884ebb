"""The step function (vsj.stepper) against the simulator, in Python and compiled loops."""

import math

import numpy as np
import pytest

from vsj.engine.core import IMPULSE_REL
from vsj.errors import InputError, SimulationError
from vsj.inputs import Constant, Table
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import Stepper
from vsj.wrist import WristOptions, build_wrist

EPS = np.finfo(float).eps
#: Cancellation of ``p - M_su u`` when the stepper turns momenta into speeds: the engine
#: rounds it to 8 ulp of its terms (``to_engine`` in engine/c/stepper.c).
CANCELLATION_ULPS = 8
#: Rounding of one Dormand-Prince step in each of two runs that take the same steps from
#: states an ulp apart: up to an ulp of each state per run (the update sums seven stages
#: into the state); a dissipative network does not grow the difference over the period.
ULPS_PER_STEP = 2

PERIOD = 1e-3
#: The stiffest pivot setting, a tenth of a millimetre inside its range (the Jacobian
#: turns the pivot drive a little either way).
RK4_Q = -0.0219
#: Tolerance of the 200-period comparison: at 1e-10 the solver's global error stands
#: well above the round-off of a few hundred steps, so what is compared is the solvers'.
MANY_STEPS_RTOL = 1e-10


def period_roundoff(stepper, state, u, steps):
    """How far rounding alone may move one stepper period from ``simulate``'s run of it:
    the same Dormand-Prince steps from speeds converted to momenta and back. Returns the
    bounds on the free flanges' (angles, speeds) [rad, rad/s]."""
    n, m = stepper.layout.n, stepper.model
    coupling = m.mass[:n, n:] @ np.diag(u[m.src_ch]) if m.src_ch.size else np.zeros((n, 0))
    terms = np.abs(state[n:2 * n]) + np.abs(coupling).sum(axis=1)
    speed_scale = np.abs(m.Minv) @ terms  # the size of what cancels in each speed
    ulps = (CANCELLATION_ULPS + ULPS_PER_STEP * steps) * EPS
    speeds = ulps * speed_scale
    angles = ulps * (np.abs(state[:n]) + PERIOD * speed_scale)
    return angles, speeds


CASES = {
    "velocity motors, geometric": (WristOptions(), {"motor_1": 0.7, "motor_2": -0.4,
                                                    "motor_s": 0.3, "tau_x": 0.02,
                                                    "tau_y": -0.01}),
    "dc motors and pivot drive": (WristOptions(motors="dc", pivot_drive="dc"),
                                  {"voltage_1": 2.0, "voltage_2": -1.0, "voltage_s": 3.0,
                                   "tau_x": 0.02}),
    "exponential, viscous friction": (WristOptions(elastic="exponential"),
                                   {"motor_1": 0.5, "tau_y": 0.03}),
}


@pytest.mark.parametrize("case", list(CASES))
def test_one_step_agrees_with_simulate(params, case):
    wrist_options, values = CASES[case]
    options = SimulationOptions(friction="viscous" if "viscous" in case else "arctan")
    stepper = Stepper.wrist(params, wrist_options, PERIOD, options=options)
    initial = InitialState(q=-0.004, angles={"vsm_1.ring": 0.05, "vsm_2.ring": -0.02},
                           speeds={"vsm_2.ring": 0.3})
    state = stepper.initial_state(initial, values)
    after = stepper.step(state, values)
    result = simulate(build_wrist(params, wrist_options).assemble(),
                      {k: Constant(v) for k, v in values.items()}, PERIOD, initial=initial,
                      options=options, ports=False)
    assert result.success, result.message
    u = stepper.input_vector(values)
    speeds = stepper.speeds(after, u)
    steps = result.solver["steps"]
    angle_tol, speed_tol = period_roundoff(stepper, after, u, steps)
    for k, flange in enumerate(stepper.structure.free):
        name = {"vsm_1.ring": "phi_1", "vsm_2.ring": "phi_2"}.get(flange, flange)
        assert abs(after[k] - result[name][-1]) <= angle_tol[k], name
        assert abs(speeds[k] - result[f"{name}.speed"][-1]) <= speed_tol[k], name
    names = ["theta_x", "theta_y", "motor_1", "motor_2"]
    rows = stepper.angle_rows(names)
    n = stepper.layout.n
    # the free angles' rounding through the rows, and the rows' own sums (a few terms)
    tol = (np.abs(rows[:, :n]) @ angle_tol
           + CANCELLATION_ULPS * EPS * (np.abs(rows) @ np.abs(after)))
    for name, value, bound in zip(names, rows @ after, tol):
        assert abs(value - result[name][-1]) <= bound, name
    for motor in stepper.structure.motors:
        k = stepper.state_names.index(f"{motor.name}.current")
        bound = (CANCELLATION_ULPS + ULPS_PER_STEP * steps) * EPS * abs(after[k])
        assert abs(after[k] - result[f"motor.{motor.name}.current"][-1]) <= bound, motor.name
    assert np.max(np.abs(after - state)) > 1e-4  # the period did something


def _periods_and_one_run(params, rtol):
    """200 stepper periods and one simulate call over the same time, at ``rtol``."""
    options = SimulationOptions(rtol=rtol, atol=rtol / 100)
    stepper = Stepper.wrist(params, period=PERIOD, options=options)
    values = {"motor_1": 0.5, "motor_2": 0.2, "tau_x": 0.03}
    initial = InitialState(q=0.005, angles={"vsm_1.ring": 0.1})
    state = stepper.initial_state(initial, values)
    u = stepper.input_vector(values)
    for _ in range(200):
        stepper.step(state, u, out=state)
    result = simulate(build_wrist(params).assemble(),
                      {k: Constant(v) for k, v in values.items()}, 200 * PERIOD,
                      initial=initial, options=options, ports=False)
    assert result.success, result.message
    return stepper, state, u, result


def test_many_steps_agree_with_one_simulation(params):
    """The stepper restarts the solver every period, simulate does not: each lies within
    its own global error of the exact solution. Each error is measured against the same
    computation at rtol / 100 (an error-per-step controller's global error follows its
    tolerance, so that rerun's error is a hundredth), and the two may differ by the sum."""
    stepper, state, u, result = _periods_and_one_run(params, MANY_STEPS_RTOL)
    _, fine_state, _, fine = _periods_and_one_run(params, MANY_STEPS_RTOL / 100)
    named, fine_named = stepper.signals(state, u), stepper.signals(fine_state, u)
    # each dopri step rounds the state to an ulp in each run; the finer run takes more steps
    roundoff = 2 * fine.solver["steps"] * EPS
    for name in ("theta_x", "theta_y.speed", "phi_1", "phi_2", "phi_1.speed", "phi_2.speed",
                 "motor_1.speed", "q"):
        errors = abs(named[name] - fine_named[name]) + abs(result[name][-1] - fine[name][-1])
        bound = errors + roundoff * abs(result[name][-1])
        assert abs(named[name] - result[name][-1]) <= bound, name
        if name == "theta_x":  # the estimator's matrix gives the same angle
            theta = stepper.angle_rows(["theta_x"]) @ state
            assert abs(theta[0] - result[name][-1]) <= bound, name
    # the state by the names and units of a run's signals
    assert set(named) <= set(result.signals)
    assert stepper.signal_units() == {name: result.units[name] for name in named}


def _zoh_and_ramps(params, eps):
    """Inputs held per period, against simulate with the jumps as centred ramps of ``eps``."""
    stepper = Stepper.wrist(params, period=PERIOD)
    rng = np.random.default_rng(1)
    n = 30
    U = np.zeros((n, stepper.n_inputs))
    U[:, 0] = rng.normal(0.0, 0.3, n)
    U[:, 1] = rng.normal(0.0, 0.3, n)
    U[:, 3] = rng.normal(0.0, 0.01, n)
    initial = InitialState(q=-0.004)
    state = stepper.initial_state(initial, U[0])
    trajectory = [state.copy()]
    for k in range(n):
        state = stepper.step(state, U[k])
        trajectory.append(state.copy())

    def table(col):
        times, values = [0.0], [U[0, col]]
        for k in range(1, n):
            times += [k * PERIOD - eps / 2, k * PERIOD + eps / 2]
            values += [U[k - 1, col], U[k, col]]
        return Table(tuple(times + [(n + 1) * PERIOD]), tuple(values + [U[-1, col]]))

    result = simulate(build_wrist(params).assemble(),
                      {ch: table(i) for i, ch in enumerate(stepper.input_names)}, n * PERIOD,
                      initial=initial, options=SimulationOptions(rtol=1e-10, atol=1e-12),
                      ports=False)
    assert result.success, result.message
    m, n_free = stepper.model, stepper.layout.n
    coupling = m.Minv @ m.mass[:n_free, n_free:]  # speed jump of the free flanges per du
    jumps = np.abs(np.diff(U[:, m.src_ch], axis=0) @ coupling.T)
    return np.max(np.abs(np.array(trajectory)[:, 0] - result["phi_1"])), float(jumps.max())


def test_input_jumps_conserve_momentum(params):
    """A jump of a source's speed is the limit of ever faster ramps.

    With the momentum continuous across the jump, the held-input steps and
    simulate with centred ramps of width eps differ by O(eps) (halving eps
    halves the difference); were the speeds continuous instead, the ring
    speeds would be off by M^-1 M_su du, about 0.1 rad/s here.
    """
    (wide, jump), (narrow, _) = _zoh_and_ramps(params, 2e-4), _zoh_and_ramps(params, 1e-4)
    # a ramp moves the flanges unlike the jump only within its width, by less than the
    # largest speed jump (centred, it cancels most of that); with the speeds continuous
    # the jump would act over whole periods, ten times longer
    assert narrow < jump * 1e-4
    # first order in eps: ratio 2 (geometric means separate it from orders 0 and 2)
    assert 2 ** 0.5 < wide / narrow < 2 ** 1.5


def _rk4_against_dopri(params, friction, substeps_list, periods=50):
    """Largest differences (angles, speeds) over ``periods`` periods of rk4 steppers with
    each number of substeps against dopri at rtol 1e-12, and the largest angle and speed."""
    options = SimulationOptions(friction=friction)
    tight = Stepper.wrist(params, period=PERIOD,
                          options=SimulationOptions(friction=friction, rtol=1e-12, atol=1e-14))
    values = {"motor_1": 0.5, "motor_2": -0.3, "tau_x": 0.02}
    start = tight.initial_state(InitialState(q=RK4_Q, angles={"vsm_1.ring": 0.05}), values)
    a, exact = start.copy(), []
    for _ in range(periods):
        exact.append(tight.step(a, values, out=a).copy())
    exact = np.array(exact)
    errors = []
    for substeps in substeps_list:
        rk4 = Stepper.wrist(params, period=PERIOD, method="rk4", substeps=substeps,
                            options=options)
        b, steps = start.copy(), []
        for _ in range(periods):
            steps.append(rk4.step(b, values, out=b).copy())
        diff = np.abs(np.array(steps) - exact)
        errors.append((diff[:, :2].max(), diff[:, 2:4].max()))
    rate = max(np.max(np.abs(np.linalg.eigvals(tight.jacobian(s, values)[0])))
               for s in [start, *exact])  # the fastest rate along the motion [1/s]
    return np.array(errors), np.abs(exact[:, :2]).max(), np.abs(exact[:, 2:4]).max(), rate


def test_rk4_is_accurate_at_four_substeps(params):
    """Classical RK4 misses e^z by about |z|^5/120 per step in a mode of rate lambda
    (z = lambda h, the local error of a fourth-order step): over the 200 substeps of 50
    periods the states drift by at most 200 |z|^5/120 of their size, with the fastest
    rate met along the motion (the Jacobian's largest eigenvalue)."""
    (error,), angle, momentum, rate = _rk4_against_dopri(params, "arctan", [4])
    h = PERIOD / 4
    drift = 50 * 4 * (rate * h) ** 5 / 120
    assert error[0] < drift * angle
    assert error[1] < drift * momentum


def test_rk4_converges_at_fourth_order(params):
    """Twice the substeps, 16 times less error (2^3.5 separates it from third order). With
    viscous friction the right-hand side is smooth and 4 substeps already converge at that
    rate; with the arctan law the error at 4 substeps is not yet in its asymptotic range."""
    errors, *_ = _rk4_against_dopri(params, "viscous", [4, 8])
    assert np.all(errors[0] / errors[1] > 2 ** 3.5), errors


def test_rk4_substeps_beyond_its_stability_limit_are_refused(params):
    """A 10 ms period in one or two rk4 substeps puts the wrist's fastest mode at rest
    (the arctan friction's slope at zero speed, about 830 1/s) outside RK4's stability
    region: refused, naming the least count that is stable. At that count a perturbed
    rest settles; one substep fewer (the same plan, its substeps changed) carries it a
    million times further, and the engine calls every step a success."""
    period = 0.01
    for substeps in (1, 2):
        with pytest.raises(InputError, match=r"beyond RK4's stability limit .* use at least "
                                             r"3 substeps"):
            Stepper.wrist(params, period=period, method="rk4", substeps=substeps)
    with pytest.raises(InputError, match="no count up to 10000000 is: shorten the period"):
        Stepper.wrist(params, period=1e5, method="rk4")
    # the count named is the least: one fewer is refused
    with pytest.raises(InputError, match="use at least 299 substeps"):
        Stepper.wrist(params, period=1.0, method="rk4", substeps=298)
    Stepper.wrist(params, period=1.0, method="rk4", substeps=299)
    # a pivot range without q = 0: judged at rest in the middle of the range
    narrow = params.with_overrides({"pivot.q_min": "2 mm"}, origin="a narrow range")
    with pytest.raises(InputError, match="use at least 3 substeps"):
        Stepper.wrist(narrow, period=period, method="rk4", substeps=1)
    stable = Stepper.wrist(params, period=period, method="rk4", substeps=3)
    start = np.zeros(stable.n_state)
    start[stable.state_names.index("vsm_1.ring.momentum")] = 1e-9  # [N m s]
    y = start.copy()
    for _ in range(200):
        stable.step(y, None, out=y)
    assert np.all(np.abs(y) <= np.abs(start).max())
    fewer = stable.plan.with_scheme(substeps=2)
    y = start.copy()
    work = fewer.engine().work
    for _ in range(200):
        assert fewer.hold(work, y, np.zeros(stable.n_inputs)) == 0  # "OK" all the same
    assert np.abs(y).max() > 1e6 * np.abs(start).max()


def test_time_stepper_steps_agree_with_simulate(params):
    """Stiction through the step function: periods of the time-stepper with constant
    inputs against one time-stepping simulation (the same steps; each period
    refactors its step matrix once, which moves results in the last bits)."""
    options = SimulationOptions(friction="stiction", step=2.5e-4)
    stepper = Stepper.wrist(params, period=PERIOD, options=options, method="timestep")
    values = {"motor_1": 0.4, "motor_2": -0.2, "tau_x": 0.03}
    initial = InitialState(q=-0.01)
    state = stepper.initial_state(initial, values)
    for _ in range(300):
        stepper.step(state, values, out=state)
    result = simulate(build_wrist(params).assemble(),
                      {k: Constant(v) for k, v in values.items()}, 300 * PERIOD,
                      initial=initial, options=options, ports=False)
    assert result.success and sum(result.transitions.values()) > 0  # elements stuck and slipped
    # round-off may tip each element's impulse by IMPULSE_REL of its scale at each step
    # (as in tests/test_regression.py): the state drifts by at most steps x elements x
    # IMPULSE_REL of its range
    drift = result.solver["steps"] * len(stepper.structure.frictions) * IMPULSE_REL
    theta = stepper.angle_rows(["theta_x", "theta_y"]) @ state
    for name, value in (("theta_x", theta[0]), ("theta_y", theta[1]), ("phi_1", state[0])):
        assert abs(value - result[name][-1]) <= drift * np.ptp(result[name]), name


def test_discrete_jacobian_predicts_a_perturbed_step(params):
    """``discretize`` holds the Jacobian of the period's start over the period, so its
    prediction of a perturbed step misses what the Jacobian changes along the motion.
    Against what the Jacobian adds to the perturbation (about period x J), that miss is
    at least of first order in the period (period^2 x dJ/dt); a wrong Jacobian or a wrong
    hold would leave a miss of the same order as the prediction, whatever the period."""
    values = {"motor_1": 0.2, "tau_x": 0.04}
    misses, rate = [], None
    periods = (PERIOD / 4, PERIOD / 8)  # the fastest rate times the period below 0.2
    for period in periods:
        stepper = Stepper.wrist(params, period=period)
        state = stepper.initial_state(InitialState(q=-0.004, angles={"vsm_1.ring": 0.1},
                                                   speeds={"vsm_1.ring": 0.05}), values)
        F, G = stepper.discretize(state, values)
        delta = np.zeros(stepper.n_state)
        delta[0], delta[3] = 1e-6, 1e-9
        du = np.zeros(stepper.n_inputs)
        du[3] = 1e-5
        u = stepper.input_vector(values)
        change = stepper.step(state + delta, u + du) - stepper.step(state, u)
        predicted = F @ delta + G @ du
        misses.append(np.max(np.abs(change - predicted)) / np.max(np.abs(predicted - delta)))
        if rate is None:
            rate = np.max(np.abs(np.linalg.eigvals(stepper.jacobian(state, u)[0])))
    # first order: the Jacobian changes by at most its fastest rate times the period
    assert misses[0] < rate * periods[0], (misses, rate)
    # first order: ratio 2 when the period halves, a wrong Jacobian 1: their geometric mean
    assert misses[0] / misses[1] > 2 ** 0.5, misses


def test_state_and_input_names(params):
    stepper = Stepper.wrist(params, WristOptions(motors="dc"), PERIOD)
    assert stepper.input_names == ("motor_s", "tau_x", "tau_y", "voltage_1", "voltage_2")
    assert stepper.input_units == ("rad/s", "N m", "N m", "V", "V")
    assert "motor_1.current" in stepper.state_names
    assert stepper.state_names[-1] == "motor_s.flange.angle"
    assert len(stepper.state_names) == stepper.n_state == len(stepper.state_units)


def test_pivot_leaving_its_range_fails_with_the_state(params):
    stepper = Stepper.wrist(params, period=0.05)
    state = stepper.initial_state(InitialState(q=0.0199))
    with pytest.raises(SimulationError, match="pivot position left"):
        for _ in range(20):
            state = stepper.step(state, {"motor_s": 20.0})


@pytest.mark.parametrize("kwargs, match", [
    ({"options": SimulationOptions(friction="stiction")}, "time-stepping"),
    ({"method": "euler"}, "method must be"),
    ({"substeps": 0}, "substeps"),
    ({"period": -1.0}, "period"),
])
def test_bad_construction(params, kwargs, match):
    period = kwargs.pop("period", PERIOD)
    with pytest.raises(InputError, match=match):
        Stepper.wrist(params, period=period, **kwargs)


def test_bad_calls(params):
    stepper = Stepper.wrist(params, period=PERIOD)
    state = stepper.initial_state()
    with pytest.raises(InputError, match="expected 5 inputs"):
        stepper.step(state, [0.0, 0.0])
    with pytest.raises(InputError, match="unknown input"):
        stepper.step(state, {"voltage_1": 1.0})
    with pytest.raises(InputError, match="state of 7"):
        stepper.step(state[:3], None)
    with pytest.raises(InputError, match="unknown signal"):
        stepper.angle_rows(["theta_z"])
    with pytest.raises(InputError, match="tau_x must be finite"):
        stepper.step(state, [0.0, 0.0, 0.0, math.nan, 0.0])
    bad = state.copy()
    bad[0] = math.inf
    with pytest.raises(InputError, match="vsm_1.ring.angle must be finite"):
        stepper.step(bad, None)
    assert math.isfinite(stepper.step(state, None)[0])


@pytest.mark.parametrize("motors", ["velocity", "dc"])
def test_a_failed_period_leaves_the_stepper_able_to_step_on(params, motors):
    """A period that fails (a load torque of 1e306 N m overflows the model) leaves its
    state unchanged; the periods after it step that state as a new stepper does. The
    failed period's impulses, the next one's warm start, were not finite and failed every
    later period of the same work."""
    wrist = WristOptions(motors="dc", pivot_drive="dc") if motors == "dc" else None

    def stepper():
        return Stepper.wrist(params, wrist, period=1e-3, method="timestep",
                             options=SimulationOptions(friction="stiction"))

    used = stepper()
    u = np.zeros(used.n_inputs)
    u[list(used.input_names).index("tau_x")] = 0.01
    x = used.initial_state(InitialState(q=-0.004), u)
    for _ in range(20):
        used.step(x, u, out=x)
    before = x.copy()
    overflow = u.copy()
    overflow[list(used.input_names).index("tau_x")] = 1e306
    with pytest.raises(SimulationError, match="non-finite"):
        used.step(x, overflow, out=x)
    assert np.array_equal(x, before)
    fresh, y = stepper(), x.copy()
    for _ in range(20):
        used.step(x, u, out=x)
        fresh.step(y, u, out=y)
    assert np.all(np.isfinite(x))
    # the same steps from the same state: a warm start changes at most the impulse
    # solver's last rounding, IMPULSE_REL of the impulses
    assert np.allclose(x, y, rtol=IMPULSE_REL, atol=IMPULSE_REL * np.max(np.abs(y)))

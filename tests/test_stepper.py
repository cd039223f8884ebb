"""The step function (vsj.stepper) against the simulator, in Python and compiled loops."""

import math

import numpy as np
import pytest

from vsj.errors import InputError, SimulationError
from vsj.inputs import Constant, Table
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.stepper import Stepper
from vsj.wrist import WristOptions, build_wrist

#: One period, same integrator and tolerances as simulate: the same computation
#: up to the round-off of converting momenta to speeds and back.
ONE_STEP_TOL = 1e-9
#: 200 periods against one simulate call, both at rtol 1e-12: each is within about
#: 1e-11 of the exact solution.
MANY_STEPS_TOL = 1e-9
#: RK4 with 4 substeps of 0.25 ms at the stiffest pivot position (the fastest mode
#: near 210 rad/s with table 4.1's inertias, omega h = 0.05): after 50 periods the
#: angles stay within 2e-5 of the 0.05 rad deflection.
RK4_TOL = 1e-6

PERIOD = 1e-3


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
    for k, flange in enumerate(stepper.structure.free):
        name = {"vsm_1.ring": "phi_1", "vsm_2.ring": "phi_2"}.get(flange, flange)
        assert abs(after[k] - result[name][-1]) < ONE_STEP_TOL
        assert abs(speeds[k] - result[f"{name}.speed"][-1]) < ONE_STEP_TOL
    names = ["theta_x", "theta_y", "motor_1", "motor_2"]
    angles = stepper.angle_rows(names) @ after
    for name, value in zip(names, angles):
        assert abs(value - result[name][-1]) < ONE_STEP_TOL
    for motor in stepper.structure.motors:
        k = stepper.state_names.index(f"{motor.name}.current")
        assert abs(after[k] - result[f"motor.{motor.name}.current"][-1]) < ONE_STEP_TOL
    assert np.max(np.abs(after - state)) > 1e-4  # the period did something


def test_many_steps_agree_with_one_simulation(params):
    options = SimulationOptions(rtol=1e-12, atol=1e-14)
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
    assert abs(state[0] - result["phi_1"][-1]) < MANY_STEPS_TOL
    assert abs(state[1] - result["phi_2"][-1]) < MANY_STEPS_TOL
    assert np.max(np.abs(stepper.speeds(state, u)
                         - [result["phi_1.speed"][-1], result["phi_2.speed"][-1]])) \
        < MANY_STEPS_TOL
    theta = stepper.angle_rows(["theta_x"]) @ state
    assert abs(theta[0] - result["theta_x"][-1]) < MANY_STEPS_TOL
    # the state by the names and units of a run's signals
    named = stepper.signals(state, u)
    for name in ("theta_x", "theta_y.speed", "phi_1", "phi_2.speed", "motor_1.speed", "q"):
        assert abs(named[name] - result[name][-1]) < MANY_STEPS_TOL * max(
            1.0, abs(result[name][-1])), name
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
    return np.max(np.abs(np.array(trajectory)[:, 0] - result["phi_1"]))


def test_input_jumps_conserve_momentum(params):
    """A jump of a source's speed is the limit of ever faster ramps.

    With the momentum continuous across the jump, the held-input steps and
    simulate with centred ramps of width eps differ by O(eps) (halving eps
    halves the difference); were the speeds continuous instead, the ring
    speeds would be off by M^-1 M_su du, about 0.1 rad/s here.
    """
    wide, narrow = _zoh_and_ramps(params, 2e-4), _zoh_and_ramps(params, 1e-4)
    assert narrow < 0.1 * 1e-4
    assert narrow == pytest.approx(wide / 2, rel=0.1)


def test_rk4_is_accurate_at_four_substeps(params):
    tight = Stepper.wrist(params, period=PERIOD,
                          options=SimulationOptions(rtol=1e-12, atol=1e-14))
    values = {"motor_1": 0.5, "motor_2": -0.3, "tau_x": 0.02}
    start = tight.initial_state(InitialState(q=-0.022, angles={"vsm_1.ring": 0.05}), values)
    a = start.copy()
    for _ in range(50):
        tight.step(a, values, out=a)
    errors = []
    for substeps in (4, 8):
        rk4 = Stepper.wrist(params, period=PERIOD, method="rk4", substeps=substeps)
        b = start.copy()
        for _ in range(50):
            rk4.step(b, values, out=b)
        errors.append(np.max(np.abs(a[:2] - b[:2])))
        if substeps == 4:
            assert errors[0] < RK4_TOL
            assert np.max(np.abs(a[2:4] - b[2:4])) < 1e-4 * np.max(np.abs(a[2:4]))
    # fourth order: twice the substeps, about 16 times less error
    assert errors[1] < errors[0] / 5


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
    theta = stepper.angle_rows(["theta_x", "theta_y"]) @ state
    assert abs(theta[0] - result["theta_x"][-1]) < ONE_STEP_TOL
    assert abs(theta[1] - result["theta_y"][-1]) < ONE_STEP_TOL
    assert abs(state[0] - result["phi_1"][-1]) < ONE_STEP_TOL


def test_discrete_jacobian_predicts_a_perturbed_step(params):
    """``discretize`` holds the Jacobian of the period's start over the period, so its
    prediction of a perturbed step misses what the Jacobian changes along the motion:
    small, and shrinking faster than the period squared."""
    values = {"motor_1": 0.2, "tau_x": 0.04}
    misses = []
    for period in (PERIOD, PERIOD / 2):
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
        misses.append(np.max(np.abs(change - predicted)) / np.max(np.abs(predicted)))
    assert misses[0] < 5e-3
    assert misses[1] < misses[0] / 4


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

"""The Rosenbrock scheme (engine/c/rosenbrock.c): its linearisation (`vsj_jacobian`,
engine/c/eval.c) and its steps through an input's corners.

Its accuracy is checked elsewhere: the observed order and the error's proportion to
the tolerance in test_convergence.py, the reference tubes and energy ledger in
test_regression.py, streaming in test_streaming.py, the C program in test_c_api.py.
"""

import numpy as np
import pytest

from vsj import scenario as scenarios
from vsj.components import Brake, Clutch, Inertia, TorqueSource
from vsj.inputs import Sine, Table
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, prepare, simulate
from vsj.wrist import WristOptions, build_wrist

EPS = np.finfo(float).eps
#: central differences: steps h and h/2 per component, relative to its size
STEP = 1e-5


def scenario_plan(name, params, duration=2.0):
    scen = scenarios.load(name)
    case = scen.cases[0]
    prep = scenarios.prepare_case(scen, case, params)
    return prepare(prep.structure, prep.inputs, duration, SimulationOptions(), case.initial)


def dc_motor_plan(params):
    structure = build_wrist(params, WristOptions(motors="dc", pivot_drive="fixed",
                                                       fixed_q=-0.01)).assemble()
    inputs = {"voltage_1": Table((0.0, 0.5, 2.0), (0.0, 4.0, -2.0)),
              "voltage_2": Table((0.0, 0.5, 2.0), (0.0, -3.0, 5.0))}
    return prepare(structure, inputs, 2.0, SimulationOptions(), InitialState(q=-0.01))


def moving_pivot_plan(params, drive="velocity"):
    """The wrist changing its stiffness: the pivot mechanism turning (its speed source
    ramped, or its DC motor driven) while the suns turn."""
    options = (WristOptions(elastic="geometric") if drive == "velocity"
               else WristOptions(motors="dc", pivot_drive="dc"))
    structure = build_wrist(params, options).assemble()
    ramp = (0.0, 0.5, 2.0)
    if drive == "velocity":
        inputs = {"motor_1": Table(ramp, (0.0, 1.5, -1.0)), "motor_2": Table(ramp, (0.0, -1.0, 2.0)),
                  "motor_s": Table(ramp, (0.0, 3.0, 1.0))}
    else:
        inputs = {"voltage_1": Table(ramp, (0.0, 4.0, -2.0)),
                  "voltage_2": Table(ramp, (0.0, -3.0, 5.0)),
                  "voltage_s": Table(ramp, (0.0, 6.0, 2.0))}
    return prepare(structure, inputs, 2.0, SimulationOptions(), InitialState(q=-0.01))


def clutch_plan(params, forces=None):
    """Friction whose level varies: two clutches and a brake with speed-dependent
    coefficients (tables) and normal forces that change in time (by default 0.5 +- 0.3,
    never clipped), so that their torques depend on the slip through the table as well
    as the law, and on time through the force."""
    net = Network("clutches")
    net.add(TorqueSource("torque", "torque"), *(Inertia(f"J{i}", 0.2 * i) for i in (1, 2, 3)),
            Clutch("c1", fn_max=20.0, mu=((0.0, 0.5), (1.0, 0.3), (30.0, 0.25))),
            Clutch("c2", fn_max=30.0, mu=((0.5, 0.6), (8.0, 0.2))),
            Brake("b", fn_max=15.0, mu=((0.0, 0.4), (3.0, 0.45), (20.0, 0.3))))
    net.connect("torque.flange", "J1.flange")
    net.connect("J1.flange", "c1.a").connect("c1.b", "J2.flange")
    net.connect("J2.flange", "c2.a").connect("c2.b", "J3.flange")
    net.connect("J3.flange", "b.flange")
    inputs = {"torque": Sine(3.0, 2.0), "c1_force": Sine(0.3, 1.3, offset=0.5),
              "c2_force": Sine(0.3, 0.7, phase=1.0, offset=0.5),
              "b_force": Sine(0.3, 0.4, phase=2.0, offset=0.5), **(forces or {})}
    return prepare(net.assemble(), inputs, 2.0, SimulationOptions(),
                   InitialState(speeds={"J1.flange": 6.0, "J2.flange": 2.0, "J3.flange": -1.5}))


PLANS = {"fig-4.15": lambda p: scenario_plan("fig-4.15", p),
         "planetary-fixed-sun": lambda p: scenario_plan("planetary-fixed-sun", p),
         "dc motors": dc_motor_plan,
         "moving pivot": moving_pivot_plan,
         "dc-driven pivot": lambda p: moving_pivot_plan(p, "dc"),
         "clutches with tables": clutch_plan}


def central(fun, x, h):
    return (fun(x + h) - fun(x - h)) / (2.0 * h)


@pytest.mark.parametrize("ledger", [False, True], ids=["state", "with the ledger"])
@pytest.mark.parametrize("name", list(PLANS))
def test_the_jacobian_is_the_derivative_of_the_dynamics(name, ledger, params):
    """J and df/dt against central differences of the derivatives, at a state off
    equilibrium and a time between the inputs' knots; with the ledger, the rows of
    every energy accumulator's rate too (the sources' work through the accelerations,
    the friction, spring, load and motor powers). The differences' own error is
    measured, not assumed: the gap between steps h and h/2 (truncation, falling as h^2)
    plus the round-off of a difference, 4 eps / h times the size of the terms that make
    each component (its value, and its linear part sum_j |J_ij y_j| + |ft_i t|)."""
    plan = PLANS[name](params)
    engine = plan.engine()
    ns = engine.n_state
    rng = np.random.default_rng(7)
    y = np.asarray(plan.y0[:ns], dtype=float) + rng.normal(scale=0.05, size=ns)
    if ledger:
        y = np.concatenate([y, np.zeros(len(plan.y0) - ns)])
    t = 0.3123  # in every input's first ramp, between knots (the curvature may jump at one)
    status, jac, ft = engine.jacobian(t, y, ledger=ledger)
    assert status == 0
    f0 = engine.derivatives(t, y)[1]
    assert np.abs(jac).max() > 0 and np.abs(ft).max() > 0  # something to compare
    terms = np.abs(f0) + np.abs(jac) @ np.abs(y[:ns]) + np.abs(ft) * t
    for j in range(ns + 1):
        size = max(1.0, abs(y[j])) if j < ns else max(1.0, t)

        def f(s, j=j):
            if j == ns:
                return engine.derivatives(s, y)[1]
            moved = y.copy()
            moved[j] = s
            return engine.derivatives(t, moved)[1]

        at = y[j] if j < ns else t
        coarse, fine = central(f, at, STEP * size), central(f, at, STEP * size / 2)
        allowed = np.abs(coarse - fine) + 4 * EPS * terms / (STEP * size / 2)
        got = jac[:, j] if j < ns else ft
        assert np.all(np.abs(got - fine) <= 2 * allowed), (j, got, fine, allowed)


def test_the_steps_follow_a_table_input_through_its_corners(params):
    """A table's corners are kinks of the input (its slope jumps), which the steps see
    only through their error estimate. The Rosenbrock run and a dopri run each lie
    within their own global error of the exact solution, each measured as the
    regression tubes measure it (test_regression.py): its distance from a rerun at a
    hundredth of its tolerance, plus that rerun's from one at a ten-thousandth. Their
    distance stays within the sum, and the ledger closes to the tolerance (its terms
    are integrated by the same error-controlled steps as the state)."""
    net = build_wrist(params, WristOptions(pivot_drive="fixed", fixed_q=-0.01)).assemble()
    corners = (0.0, 0.31, 0.77, 1.5, 4.0, 4.05, 6.0)
    inputs = {"motor_1": Table(corners, (0.0, 2.0, -1.0, -1.0, -1.0, 3.0, 3.0)),
              "motor_2": Table(corners, (0.0, -1.0, 1.5, 1.5, 1.5, -2.0, -2.0))}
    signals = ("theta_x", "theta_x.speed", "theta_y", "theta_y.speed")

    def run(solver, rtol):
        result = simulate(net, inputs, 6.0, initial=InitialState(q=-0.01), ports=False,
                          options=SimulationOptions(solver=solver, rtol=rtol,
                                                    atol=1e-3 * rtol, output_step=0.01))
        assert result.success and result.solver["name"] == solver, result.message
        return result

    def measured(solver, rtol):
        runs = [run(solver, rtol * refine) for refine in (1.0, 1e-2, 1e-4)]
        return runs[0], {s: np.max(np.abs(runs[0][s] - runs[1][s]))
                         + np.max(np.abs(runs[1][s] - runs[2][s])) for s in signals}

    rosenbrock, error = measured("rosenbrock", 1e-6)
    dopri, reference_error = measured("dopri", 1e-8)
    for signal in signals:
        assert np.max(np.abs(rosenbrock[signal] - dopri[signal])) \
            <= error[signal] + reference_error[signal], signal
    assert rosenbrock.ledger["relative_residual"] <= 1e-6


@pytest.mark.parametrize("rtol", [1e-2, 1e-3])
def test_the_error_stays_within_the_tolerance_at_steps_and_between_them(rtol, params):
    """Fig 4.15 (arctan friction on every element, the friction laws' steep slopes
    switching twice a period): a run samples every millisecond, at its steps' ends and
    between them, within the scale its tolerance sets for the ring angles, atol +
    rtol max|x|. The embedded estimate alone lets long steps through that bend inside
    (their ends and their middles off by several times that scale); the interpolant's
    error at mid-step, held to the same norm, catches them."""
    plan = scenario_plan("fig-4.15", params, duration=4.0)
    atol = 1e-3 * rtol
    run = plan.with_scheme(name="rosenbrock", rtol=rtol, atol=atol).start(ledger=False)
    grid = np.arange(1, 4001) * 1e-3
    samples, ends = [], {}
    for t in grid:  # one sample a call: the run stands at a step's end after each
        samples.append(run.advance(np.array([t]), finish=False)[0][0, :2])
        ends[run.t] = run.y[:2].copy()
    times = np.array(sorted(ends))
    reference = plan.with_scheme(name="rosenbrock", rtol=1e-12, atol=1e-15)
    at_grid = reference.start(ledger=False).advance(grid, finish=False)[0][:, :2]
    at_ends = reference.start(ledger=False).advance(times, finish=False)[0][:, :2]
    scale = atol + rtol * np.max(np.abs(at_grid))
    # each accepted step's error is at most the tolerance in the RMS norm over the 4
    # states (one component: twice it); the wrist's modes decay within a step (eigenvalues
    # below -280 1/s, steps over 5 ms here), so the errors do not add up across steps
    assert np.max(np.abs(np.array(samples) - at_grid)) <= 2.0 * scale
    assert np.max(np.abs(np.array([ends[t] for t in times]) - at_ends)) <= 2.0 * scale
    assert len(times) < 0.1 * len(grid)  # steps many samples long: the interpolant is tested


def test_a_normal_force_leaving_its_limit_has_its_rate_in_the_time_derivative(params):
    """A clutch's normal force ramping up from 0 and a brake's ramping down from 1, both
    from t = 0: the forces stand on their clipping limits there, but move inside at
    once, so df/dt (the derivative after t, as at any corner of an input) has their
    rates. Forward differences at steps h and h/2 check it: their truncation error
    falls as h, so their gap bounds the finer one's, plus the round-off of a
    difference, 4 eps / h times the size of the terms."""
    plan = clutch_plan(params, {"c1_force": Table((0.0, 0.4, 2.0), (0.0, 1.0, 1.0)),
                                "b_force": Table((0.0, 0.3, 2.0), (1.0, 0.2, 0.2))})
    engine = plan.engine()
    ns = engine.n_state
    y = np.asarray(plan.y0[:ns], dtype=float)
    status, jac, ft = engine.jacobian(0.0, y, ledger=False)
    assert status == 0
    f0 = engine.derivatives(0.0, y)[1]
    h = STEP

    def forward(step):
        return (engine.derivatives(step, y)[1] - f0) / step

    coarse, fine = forward(h), forward(h / 2)
    allowed = np.abs(coarse - fine) + 4 * EPS * (np.abs(f0) + np.abs(ft) * h) / (h / 2)
    assert np.abs(fine).max() > 0  # the forces move
    assert np.all(np.abs(ft - fine) <= 2 * allowed), (ft, fine, allowed)


@pytest.mark.parametrize("rtol", [1e-5, 1e-6])
def test_friction_whose_level_varies_is_integrated_to_the_tolerance(rtol, params):
    """Clutches and a brake whose level follows speed tables and time-varying normal
    forces (`clutch_plan`): the Rosenbrock samples every millisecond lie within the
    scale the tolerance sets for each state, atol + rtol max|y|, of a tight dopri run
    (a scheme that uses no Jacobian), to within the bound of one step: each accepted
    step's error is at most the tolerance in the RMS norm over the ns states, so one
    component at most sqrt(ns) times it. This is a local bound used as a global one:
    the speeds' errors are damped by the friction, but the angles' add up, and the runs
    stay well inside it (an order of magnitude at these tolerances). The steps' second
    derivatives, which the interpolant between them uses, come from the Jacobian: with
    the level's derivatives missing there, the samples were off by up to twenty times
    the scale at rtol 1e-6, eight times the bound."""
    plan = clutch_plan(params)
    ns = plan.layout.n_state
    grid = np.arange(0, 2001) * 1e-3
    atol = 1e-3 * rtol
    states = plan.with_scheme(name="rosenbrock", rtol=rtol, atol=atol).sample(
        grid, ledger=False)[1][:, :ns]
    reference = plan.with_scheme(name="dopri", rtol=1e-12, atol=1e-15).sample(
        grid, ledger=False)[1][:, :ns]
    scale = atol + rtol * np.max(np.abs(reference), axis=0)
    assert np.all(np.max(np.abs(states - reference), axis=0) <= np.sqrt(ns) * scale)

"""One plan, one entry point: every driver runs `vsj.engine.plan.Plan` objects, and they
reach the engine through ``vsj._core.run`` alone (issue 32).

Each test counts the calls of ``_core.run`` while a driver works and checks that what the
driver returns is what a plan of the same run gives when run directly, bit for bit: a
driver with its own path to the engine, or its own copy of a plan's settings, fails one
or the other.
"""

import numpy as np
import pytest

from vsj import _core
from vsj import scenario as scenarios
from vsj.engine.plan import METHODS, Plan, Scheme, run_batch
from vsj.simulate import InitialState, SimulationOptions, prepare, simulate, simulate_batch
from vsj.simulate.driver import sample_times
from vsj.simulate.signals import collect


@pytest.fixture
def calls(monkeypatch):
    """The scheme codes of the ``_core.run`` calls made while the test runs."""
    seen = []
    real = _core.run

    def counted(model, work, y, scheme, until, **kwargs):
        seen.append(scheme[0])
        return real(model, work, y, scheme, until, **kwargs)

    monkeypatch.setattr(_core, "run", counted)
    return seen


@pytest.fixture(scope="module")
def case(params):
    scen = scenarios.load("fig-4.15")
    prep = scenarios.prepare_case(scen, scen.cases[0], params)
    return prep.structure, prep.inputs


def test_the_binding_has_one_function_that_advances_time():
    # everything else in the binding evaluates the model at one instant (or, for the
    # input splines, solves their slopes)
    instant = {"derivatives", "friction_torque", "jacobian", "observation_width", "observe",
               "solve_impulses", "source_signals", "spring_extensions", "spring_geometry",
               "spring_law", "status_text", "step_rate", "stored_energy", "transitions",
               "solve_tridiagonal", "control_values", "control_reset",
               "ts_prepare"}
    functions = {n for n in dir(_core) if callable(getattr(_core, n)) and not n[0].isupper()
                 and not n.startswith("_")}
    assert functions - instant == {"run"}


@pytest.mark.parametrize("friction", ["arctan", "stiction"])
def test_simulate_runs_its_plan(case, calls, friction):
    structure, inputs = case
    options = SimulationOptions(friction=friction, output_step=0.01)
    initial = InitialState(q=0.0)
    result = simulate(structure, inputs, 0.5, initial=initial, options=options, ports=False)
    plan = prepare(structure, inputs, 0.5, options, initial)
    assert result.success and calls and set(calls) == {METHODS[plan.scheme.name]}
    # the plan run directly, its samples named as the driver names them
    times = sample_times(0.5, 0.01)
    run, states, coulomb, stuck = plan.sample(times)
    assert run.status == 0
    signals, _ = collect(structure, plan.engine(), plan.layout, times, states, coulomb, stuck,
                         ports=False)
    for name in ("theta_x", "theta_y", "phi_1.speed"):
        assert np.array_equal(signals[name], result[name]), name


def test_batches_run_plans(case, calls):
    structure, inputs = case
    options = SimulationOptions(output_step=0.01)
    qs = [-0.01, 0.01]
    batch = simulate_batch(structure, inputs, 0.5, initials=[InitialState(q=q) for q in qs],
                           options=options)
    assert len(calls) >= len(qs)
    plans = [prepare(structure, inputs, 0.5, options, InitialState(q=q)) for q in qs]
    direct = run_batch(plans, sample_times(0.5, 0.01), threads=1)
    assert np.array_equal(direct.states, batch.states)


def test_the_step_function_holds_its_plans_inputs(params, calls):
    from vsj.stepper import Stepper

    stepper = Stepper.wrist(params, period=1e-3)
    x = stepper.initial_state()
    u = np.zeros(stepper.n_inputs)
    u[0] = 0.5
    after = stepper.step(x, u)
    assert len(calls) == 1 and calls[0] == METHODS[stepper.plan.scheme.name]
    again = np.array(x, dtype=float)
    status = stepper.plan.hold(_core.Work(stepper.plan.native), again, u)
    assert status == 0 and np.array_equal(again, after)


def test_exports_write_the_plans_model(params):
    from vsj import export

    stepper = export.wrist_stepper(params)
    blob = stepper.plan.native.to_bytes()
    data = export.program_bytes(export.model_document(stepper, params=params), stepper)
    assert blob in data


def test_a_sweep_chunk_runs_its_plans(calls, tmp_path, params):
    from vsj import sweep
    from vsj.sweep import runner

    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nscenario = "fig-4.15"\nduration = "0.3 s"\n[vary]\n'
                    'q = { values = ["-1 cm", "1 cm"] }\n'
                    '[metrics]\npeak = { kind = "peak", signal = "theta_x" }\n'
                    '[output]\nkeep = ["theta_x"]\nevery = "10 ms"\n')
    job = runner.job_for(sweep.load(path))
    p = runner.prepared(job)
    values = np.array([[-0.01], [0.01]])
    chunk = runner.run_chunk(job, 0, values, threads=1)
    assert chunk.status.tolist() == [0, 0]
    assert len(calls) >= 2 and set(calls) == {METHODS[p.scheme.name]}


def test_the_identification_runs_plans(params, calls):
    from vsj import synth
    from vsj.identification import wrist_experiment as WE
    from vsj.identification.wrist_model import Setup, WristModel
    from vsj.measurements import Measurement

    e = WE.Experiment(duration=3.0, step=1e-3, q=-0.004, signals={
        "motor_1": (("sine", {"frequency": 0.7, "amplitude": 2.0}),),
        "motor_2": (("sine", {"frequency": 1.1, "amplitude": 2.0}),)})
    data = synth.wrist(e, params, seed=1)
    log = Measurement("log.csv", {k: v[0] for k, v in data.columns.items()},
                      {k: v[1] for k, v in data.columns.items()}, data.comments)
    model = WristModel([log], params, Setup(free=("differential.inertia_x",)))
    calls.clear()
    model.simulate(np.array([params["differential.inertia_x"]]), "stiction")
    assert len(calls) >= len(model.windows)
    assert set(calls) == {METHODS["timestep"]}


def test_a_scheme_names_a_method_the_engine_has():
    with pytest.raises(KeyError):
        Scheme("euler").code(3, False)
    assert Scheme("dopri").code(3, True)[0] == 0 and Scheme("timestep").code(3, True)[0] == 1


def test_a_retuned_plan_leaves_the_original_untouched(case):
    structure, inputs = case
    options = SimulationOptions(output_step=0.01)
    plan = prepare(structure, inputs, 0.3, options, InitialState(q=0.0))
    heavier = plan.retuned(mass=plan.model.mass * 2.0, Minv=plan.model.Minv / 2.0)
    assert not np.array_equal(heavier.model.mass, plan.model.mass)
    times = sample_times(0.3, 0.01)
    _, a, _, _ = plan.sample(times)
    _, b, _, _ = heavier.sample(times)
    _, c, _, _ = plan.sample(times)
    assert np.array_equal(a, c) and not np.array_equal(a, b)
    assert isinstance(heavier, Plan)


@pytest.mark.parametrize("method", ["dopri", "rosenbrock"])
def test_a_sample_at_a_steps_end_is_the_state_there(case, method):
    """The adaptive schemes sample between their steps by an interpolant, which at a
    step's end equals the end state only to round-off (Dormand-Prince's y0 + (y1 - y0)
    loses the last bit where the state changes sign or size within the step). A sample
    that falls on a step's end (a controller's sample, the run's end) is the state
    itself, bit for bit: at each of a run's steps, the run stopped there and sampled at
    that very time."""
    structure, inputs = case
    plan = prepare(structure, inputs, 2.0,
                   SimulationOptions(solver=method, rtol=1e-6, atol=1e-9), InitialState())
    run = plan.start(ledger=True)
    ends, samples = [], []
    for t in np.linspace(0.01, plan.duration, 200):
        if t <= run.t:
            continue
        run.advance(np.array([t]), finish=False)  # stops at the step that passes t
        ends.append(run.y.copy())
        samples.append(run.advance(np.array([run.t]), finish=False)[0][0])
    assert len(ends) > 50
    assert np.array_equal(np.array(samples), np.array(ends))

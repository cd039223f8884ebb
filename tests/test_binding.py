"""The engine's binding refuses what it cannot compute, with an error, never a crash.

Each case here was found by probing the binding with bad arguments (a crash,
a hang, or a wrong result reported as success); each must stay an error.
"""

import math

import numpy as np
import pytest

from vsj import scenario as scenarios
from vsj import _core
from vsj.engine import Engine
from vsj.engine.core import native
from vsj.simulate import SimulationOptions, prepare
from vsj.stepper import Stepper


@pytest.fixture(scope="module")
def model(params):
    scen = scenarios.load("fig-4.15")
    case = scen.cases[0]
    prep = scenarios.prepare_case(scen, case, params)
    return prepare(prep.structure, prep.inputs, 1.0, SimulationOptions(), case.initial).model


def test_spline_ranges_that_overflow_are_refused(model):
    first, count = model.first.copy(), model.count.copy()
    first[-1], count[-1] = 2 ** 60, 2 ** 63 - 2 ** 60  # first + count overflows
    with pytest.raises(ValueError, match="outside"):
        native(model._replace(first=first, count=count))


@pytest.mark.parametrize("change, match", [
    (lambda m: {"mass": -m.mass}, "diagonal entry 0 must be > 0"),
    (lambda m: {"mass": m.mass + np.triu(np.ones_like(m.mass), 1)}, "not symmetric"),
    (lambda m: {"Minv": 2.0 * m.Minv}, "not the inverse"),
])
def test_an_inconsistent_mass_matrix_is_refused(model, change, match):
    with pytest.raises(ValueError, match=match):
        native(model._replace(**change(model)))


def _held(model, method, h=1e-3, substeps=1):
    """The scheme tuple of ``vsj._core.run`` for a held period."""
    return (method, 1e-8, 1e-10, 1e300, 0, h, 10, False, substeps)


def test_arguments_are_converted_one_at_a_time(model):
    """A failed conversion raises its own error (not SystemError from the next one)."""
    engine = Engine(model)
    state = np.zeros(int(2 * model.dims[0] + model.dims[5] + model.dims[1]))
    inputs = np.zeros(int(model.dims[6]))

    class Bad:
        def __float__(self):
            raise KeyError("boom")

    with pytest.raises(TypeError):
        _core.run(engine.c, engine.work, state, ("x",) + _held(model, 0)[1:], 1e-3,
                  held=inputs)
    with pytest.raises(KeyError, match="boom"):
        _core.run(engine.c, engine.work, state, _held(model, 0), Bad(), held=inputs)
    with pytest.raises(ValueError, match="method"):
        _core.run(engine.c, engine.work, state, _held(model, 2 ** 32), 1e-3, held=inputs)


@pytest.mark.parametrize("dt, substeps, h", [(1e300, 1, 1e-4), (1e-3, 10 ** 15, 1e-3),
                                             (1e3, 1, 1e-12)])
def test_absurd_step_counts_are_refused_not_run(model, dt, substeps, h):
    engine = Engine(model)
    state = np.zeros(int(2 * model.dims[0] + model.dims[5] + model.dims[1]))
    inputs = np.zeros(int(model.dims[6]))
    method = 2 if substeps > 1 else 1
    with pytest.raises(ValueError, match="steps"):
        _core.run(engine.c, engine.work, state, _held(model, method, h, substeps), dt,
                  held=inputs)


def test_a_step_longer_than_the_period_takes_one_shortened_step(params):
    """Not zero steps reported as success."""
    stepper = Stepper.wrist(params, period=1e-3, method="timestep",
                            options=SimulationOptions(friction="stiction", step=0.05))
    state = stepper.initial_state()
    after = stepper.step(state, {"tau_x": 0.5})
    assert np.max(np.abs(after[:4] - state[:4])) > 0.0


def test_a_work_prepared_for_another_model_is_prepared_again(model):
    """The time-stepper analyses a model (friction groups, end stops) in its work; a
    held period on a work analysed for another model of the same sizes analyses this
    one first, so the step equals one on a fresh work, bit for bit."""
    heavier = model._replace(mass=model.mass * 2.0, Minv=model.Minv / 2.0)
    a, b = Engine(model), Engine(heavier)
    state = np.zeros(int(2 * model.dims[0] + model.dims[5] + model.dims[1]))
    state[0] = 0.01
    inputs = np.full(int(model.dims[6]), 0.2)
    first = state.copy()
    assert _core.run(a.c, a.work, first, _held(model, 1), 1e-3, held=inputs)[0] == 0
    reused, fresh = state.copy(), state.copy()
    assert _core.run(b.c, a.work, reused, _held(model, 1), 1e-3, held=inputs)[0] == 0
    assert _core.run(b.c, b.work, fresh, _held(model, 1), 1e-3, held=inputs)[0] == 0
    assert np.array_equal(reused, fresh)
    assert not np.array_equal(reused, first)  # the heavier model moved otherwise


def test_a_work_that_stepped_another_model_reads_this_ones_rows(model):
    """The evaluation notes in its work which friction elements share a slip row (a
    bearing and a lever on one shaft: fig 4.15 has four such pairs) and evaluates such a
    slip once. A held period (the step function, which keeps its work's notes from one
    call to the next) of a model whose rows differ, on a work that stepped the other
    model, equals one on a fresh work, bit for bit: no element takes a slip that its row
    no longer shares."""
    xp, xv, uv = (np.asarray(a) for a in (model.xp, model.xv, model.uv))
    f = int(model.dims[2])
    rows = [(tuple(model.xc[xp[e]:xp[e + 1]]), tuple(xv[xp[e]:xp[e + 1]]),
             tuple(model.uc[model.up[e]:model.up[e + 1]]),
             tuple(uv[model.up[e]:model.up[e + 1]])) for e in range(f)]
    pairs = [(a, b) for b in range(f) for a in range(b) if rows[a] == rows[b] and rows[a][0]]
    assert len(pairs) >= 4
    split = xv.copy()
    for _, b in pairs:  # each pair's second element on a slip of its own
        split[xp[b]:xp[b + 1]] *= 1.25
    other = model._replace(xv=split)
    state = np.zeros(int(2 * model.dims[0] + model.dims[5] + model.dims[1]))
    state[2:4] = (0.3, -0.2)
    inputs = np.full(int(model.dims[6]), 0.2)
    for method in (0, 2, 3):  # dopri, rk4, rosenbrock
        scheme = (method, 1e-8, 1e-10, 1e300, 0, 1e-3, 10 ** 5, False, 4)
        a, b = Engine(model), Engine(other)
        first = state.copy()
        assert _core.run(a.c, a.work, first, scheme, 1e-3, held=inputs)[0] == 0
        reused, fresh = state.copy(), state.copy()
        assert _core.run(b.c, a.work, reused, scheme, 1e-3, held=inputs)[0] == 0
        assert _core.run(b.c, b.work, fresh, scheme, 1e-3, held=inputs)[0] == 0
        assert np.array_equal(reused, fresh), method
        assert not np.array_equal(reused, first)  # the split rows moved otherwise


def test_a_step_that_failed_fails_again_when_tried_again(model):
    """A step whose matrix is not positive definite fails (a viscous coefficient made
    negative enough that M + h B is indefinite at the period's step but not at half of
    it). Tried again from the same state, it must fail again: the failed attempt's half
    written factor is not a factor of this matrix, and a step from it is not a result."""
    rows = np.asarray(model.rows)
    n = int(model.dims[0])
    e = next(i for i in range(int(model.dims[2])) if np.any(model.xv[model.xp[i]:model.xp[i + 1]]))
    state = np.zeros(int(2 * n + model.dims[5] + model.dims[1]))
    inputs = np.zeros(int(model.dims[6]))
    h = 1e-3

    def statuses(viscous, periods):
        par = np.array(model.par, dtype=float).reshape(len(rows), -1)
        par[e, 0] = viscous
        engine = Engine(model._replace(par=par.reshape(np.shape(model.par))))
        y = state.copy()
        return [_core.run(engine.c, engine.work, y, _held(model, 1, h), dt, held=inputs)[0]
                for dt in periods]

    # the least negative coefficient with which a step of h fails, to a part in 1e6
    works, fails = 0.0, -1.0
    while statuses(fails, [h])[0] == 0:
        works, fails = fails, 2.0 * fails
    while fails - works < -1e-6 * abs(fails):
        middle = 0.5 * (works + fails)
        works, fails = (middle, fails) if statuses(middle, [h])[0] == 0 else (works, middle)
    # 1.3 times it: the step of h fails, one of h / 2 (half the damping's weight) does not
    first, *again = statuses(1.3 * fails, [h / 2, h, h, h])
    assert first == 0
    assert all(status != 0 for status in again), again


def test_a_work_that_served_another_model_evaluates_this_ones_inputs(model):
    """The engine keeps the inputs it evaluated last (a Rosenbrock step evaluates its
    last stages and its end at one time). On a work that evaluated another model's
    inputs at the same time, a run and a one-off evaluation of this model equal those
    on a fresh work, bit for bit: nothing of the other model's inputs is reused."""
    faster = model._replace(coef=model.coef * 1.5, cum=model.cum * 1.5)
    a, b = Engine(model), Engine(faster)
    y = np.zeros(4)
    scheme = (3, 1e-6, 1e-9, 1e300, 4, 1e-3, 10 ** 6, False, 1)  # rosenbrock
    times = np.linspace(0.0, 1.0, 11)
    runs = {}
    for name, work in (("reused", a.work), ("fresh", b.work)):
        if name == "reused":  # the other model's run, to its end at t = 1
            assert _core.run(a.c, work, y.copy(), scheme, 0.0, begin=(0.0, 1.0))[0] == 0
            assert _core.run(a.c, work, y.copy(), scheme, 1.0, finish=True)[0] == 0
        state, out = y.copy(), np.full((len(times), 4), np.nan)
        assert _core.run(b.c, work, state, scheme, 0.0, begin=(0.0, 1.0))[0] == 0
        assert _core.run(b.c, work, state, scheme, 1.0, finish=True, t_out=times,
                         out=out)[0] == 0
        runs[name] = out
    assert np.array_equal(runs["reused"], runs["fresh"])
    # one-off evaluations at one time, alternating between the two models on one work
    state = np.array([0.001, -0.002, 0.05, -0.03])
    a.work = b.work
    _, slow = a.derivatives(0.7, state)
    _, fast = b.derivatives(0.7, state)
    assert np.array_equal(fast, Engine(faster).derivatives(0.7, state)[1])
    assert np.array_equal(slow, Engine(model).derivatives(0.7, state)[1])
    assert not np.array_equal(fast, slow)  # the inputs differ, so must the accelerations


def test_observation_times_must_be_finite(model):
    engine = Engine(model)
    out = np.zeros((2, int(2 * model.dims[0] + model.dims[5])))
    with pytest.raises(ValueError, match="finite"):
        engine.observe(np.array([0.0, math.nan]), out)


def test_the_impulse_problem_refuses_non_finite_data():
    YT = np.eye(2)
    qs = np.zeros((1, 2))
    out = (np.zeros((1, 2)), np.zeros((1, 2), np.int64), np.zeros(1, np.int64))
    active = np.ones(2, bool)
    for cap in (np.array([math.nan, 1.0]), np.array([-1.0, 1.0]), np.array([math.inf, 1.0])):
        with pytest.raises(ValueError, match="caps finite"):
            _core.solve_impulses(YT, qs, cap, active, *out)
    with pytest.raises(ValueError, match="at most 1024 rows"):
        _core.solve_impulses(np.zeros((2000, 2)), qs, np.ones(2), active, *out)


def test_samples_of_the_time_stepper_fall_on_its_steps(model):
    engine = Engine(model)
    ny = int(2 * model.dims[0] + model.dims[5])
    scheme = (1, 1e-8, 1e-10, 1e300, ny, 1e-3, 1000, False, 1)
    y = np.zeros(ny)
    with pytest.raises(ValueError, match="multiples of the step"):
        _core.run(engine.c, engine.work, y, scheme, 0.01, begin=(0.0, 0.01),
                  t_out=np.array([0.0, 0.0015]), out=np.zeros((2, ny)))


def test_a_run_cannot_be_advanced_past_its_end(model):
    engine = Engine(model)
    ny = int(2 * model.dims[0] + model.dims[5])
    scheme = (0, 1e-8, 1e-10, 1e300, ny, 1e-3, 1000, False, 1)
    y = np.zeros(ny)
    assert _core.run(engine.c, engine.work, y, scheme, 0.0, begin=(0.0, 0.01))[0] == 0
    status = _core.run(engine.c, engine.work, y, scheme, 0.02)[0]
    assert status == 6 and np.all(y == 0.0)  # VSJ_BAD_ARGUMENT, the state untouched


def test_a_retuned_model_equals_one_built_whole_and_keeps_what_it_shares_alive(model):
    """Model.retuned replaces real arrays and shares the rest with its parent: the result
    is the model built from all the arrays (same binary form), it is checked like one,
    and it outlives the parent object it shares arrays with."""
    import gc

    from vsj.engine.core import native

    par = model.par.copy()
    par[:, 0] *= 1.01  # the viscous coefficients (the other columns hold codes and flags)
    heavier = model._replace(mass=model.mass * 2.0, Minv=model.Minv / 2.0, par=par)
    retuned = native(model).retuned({"mass": heavier.mass, "Minv": heavier.Minv,
                                     "par": heavier.par})
    gc.collect()  # the parent made above is referenced by nothing but the retuned model
    assert retuned.to_bytes() == native(heavier).to_bytes()
    again = retuned.retuned({"src_pos0": heavier.src_pos0 + 0.1})
    del retuned
    gc.collect()
    assert again.to_bytes() == native(heavier._replace(src_pos0=heavier.src_pos0 + 0.1)).to_bytes()
    with pytest.raises(ValueError, match="Minv"):  # checked as a whole
        native(model).retuned({"mass": heavier.mass})
    with pytest.raises(KeyError, match="code"):  # integer arrays set the structure
        native(model).retuned({"code": model.code})
    with pytest.raises(ValueError):
        native(model).retuned({"mass": heavier.mass[:-1]})

"""Batch simulation: many runs in parallel give what single runs give."""

import numpy as np
import pytest

from vsj import scenario as scenarios
from vsj.errors import InputError
from vsj.simulate import InitialState, SimulationOptions, simulate, simulate_batch
from vsj.simulate.signals import rows
from vsj.wrist import build_wrist


@pytest.mark.parametrize("friction", ["arctan", "stiction"])
def test_batch_runs_equal_single_runs(params, friction):
    scen = scenarios.load("fig-4.15")
    case = scen.cases[0]
    prep = scenarios.prepare_case(scen, case, params)
    structure, inputs = prep.structure, prep.inputs
    qs = [-0.02, -0.005, 0.01]
    options = SimulationOptions(friction=friction, output_step=0.01)
    batch = simulate_batch(structure, inputs, 2.0, initials=[InitialState(q=q) for q in qs],
                           options=options)
    assert batch.success.all()
    for r, q in enumerate(qs):
        single = simulate(structure, inputs, 2.0, initial=InitialState(q=q), options=options,
                          ports=False)
        assert np.array_equal(batch.angle("diff.theta_x")[r], single["theta_x"])
        assert np.array_equal(batch.speed("vsm_1.ring")[r], single["phi_1.speed"])
    # the pivot position matters: softer settings deflect more
    peak = np.max(np.abs(batch.angle("vsm_1.ring")), axis=1)
    assert peak[0] < peak[1] < peak[2]


def test_batch_over_parameter_sets(params):
    sets = [params.with_overrides({"differential.inertia_x": f"{v} kg m^2"}, origin="t")
            for v in (1e-4, 1e-3)]
    structures = [build_wrist(p).assemble() for p in sets]
    from vsj.inputs import Sine

    inputs = {"tau_x": Sine(0.05, 3.0)}
    batch = simulate_batch(structures[0], inputs, 1.0, structures=structures,
                           initials=[InitialState(q=0.0)] * 2,
                           options=SimulationOptions(output_step=0.01))
    for r, s in enumerate(structures):
        single = simulate(s, inputs, 1.0, initial=InitialState(q=0.0),
                          options=SimulationOptions(output_step=0.01), ports=False)
        assert np.array_equal(batch.angle("diff.theta_x")[r], single["theta_x"])
    # the inertia matters: the two runs differ beyond what either solver's tolerance
    # allows (an error-per-step controller's global error follows its rtol)
    a, b = batch.angle("diff.theta_x")
    assert np.max(np.abs(a - b)) > SimulationOptions().rtol * np.max(np.abs(a))


def test_time_stepper_checks_the_shapes_of_its_sample_arrays(params):
    from vsj import _core
    from vsj.simulate import prepare

    scen = scenarios.load("fig-4.15")
    case = scen.cases[0]
    prep = scenarios.prepare_case(scen, case, params)
    structure, inputs = prep.structure, prep.inputs
    options = SimulationOptions(friction="stiction")
    plan = prepare(structure, inputs, 0.05, options, case.initial)
    y0, layout = plan.y0, plan.layout
    t_out = np.arange(6) * 0.01
    nf = layout.n_frictions
    scheme = plan.scheme.code(layout.n_state, True)

    def run(n_out, coulomb_rows, columns):
        out = np.full((n_out, y0.shape[0]), np.nan)
        coulomb = np.zeros((coulomb_rows, columns)) if coulomb_rows else None
        stuck = np.zeros((coulomb_rows, columns), dtype=bool) if coulomb_rows else None
        work = _core.Work(plan.native)
        status = _core.run(plan.native, work, y0.copy(), scheme, 0.05, begin=(0.0, 0.05),
                           finish=True, t_out=t_out, out=out, coulomb=coulomb,
                           stuck=stuck)[0]
        return status, out, coulomb

    status, out, coulomb = run(6, 0, nf)  # no friction samples: states only
    assert status == 0 and not np.isnan(out).any()
    status, out, coulomb = run(6, 6, nf)
    assert status == 0 and np.any(coulomb != 0.0)
    for bad, match in [((5, 6, nf), "one row per sample"), ((6, 5, nf), "coulomb"),
                       ((6, 6, nf - 1), "coulomb")]:
        with pytest.raises(ValueError, match=match):
            run(*bad)


@pytest.mark.parametrize("friction", ["arctan", "stiction"])
def test_batch_results_do_not_depend_on_the_number_of_threads(params, friction):
    scen = scenarios.load("fig-4.15")
    case = scen.cases[0]
    prep = scenarios.prepare_case(scen, case, params)
    structure, inputs = prep.structure, prep.inputs
    options = SimulationOptions(friction=friction, output_step=0.01)
    initials = [InitialState(q=q) for q in np.linspace(-0.02, 0.015, 7)]
    one, two = (simulate_batch(structure, inputs, 1.0, initials=initials, options=options,
                               threads=k) for k in (1, 2))
    assert one.success.all() and two.success.all()
    assert np.array_equal(one.states, two.states)
    assert np.array_equal(one.transitions, two.transitions)


def test_batch_signals_carry_the_names_and_units_of_a_single_run(params):
    scen = scenarios.load("fig-4.15")
    prep = scenarios.prepare_case(scen, scen.cases[0], params)
    options = SimulationOptions(output_step=0.01)
    qs = [-0.01, 0.005]
    batch = simulate_batch(prep.structure, prep.inputs, 0.5,
                           initials=[InitialState(q=q) for q in qs], options=options)
    ds = batch.to_xarray()
    single = simulate(prep.structure, prep.inputs, 0.5, initial=InitialState(q=qs[1]),
                      options=options, ports=False)
    alone = single.to_xarray()
    for name in batch.columns():
        assert name in single.signals, name
        assert ds[name].attrs["units"] == single.units[name]
        # unit and description, as the single run's dataset (and trajectory.nc) give them
        assert ds[name].attrs == alone[name].attrs and "long_name" in alone[name].attrs
        assert np.array_equal(ds[name].values[1], single[name])
    assert "theta_x.speed" in batch.columns() and list(ds["success"].values) == [1, 1]
    with pytest.raises(KeyError, match="no signal"):
        batch["theta_z"]


@pytest.mark.parametrize("density", [0.1, 1.0])
def test_rows_give_each_sample_the_same_bits_however_the_samples_are_grouped(density):
    """`rows`, the products behind the signals: a sample gives the same bits alone, in a
    block of any height or in a batch, with a sparse matrix (applied term by term) and a
    dense one (einsum). A BLAS product fails this (OpenBLAS sums edge rows otherwise)."""
    rng = np.random.default_rng(5)
    matrix = rng.normal(size=(23, 21)) * (rng.random((23, 21)) < density)
    samples = rng.normal(size=(3, 1001, 23))
    whole = rows(samples, matrix)
    for r in range(3):
        assert np.array_equal(rows(samples[r], matrix), whole[r])
        for start, stop in ((0, 1), (11, 29), (500, 1001)):
            assert np.array_equal(rows(samples[r, start:stop], matrix), whole[r, start:stop])
        if density < 1.0:  # term by term, a column alone is summed alike
            for c in range(matrix.shape[1]):
                assert np.array_equal(rows(samples[r], matrix[:, c]), whole[r, :, c])
    # 23 products of unit normals: their sum's round-off stays far below 1e-12
    np.testing.assert_allclose(whole, samples @ matrix, rtol=0, atol=1e-12)


@pytest.mark.parametrize("duration, options, match", [
    (1e9, SimulationOptions(), "GiB in memory"),
    (0.1, SimulationOptions(solver="timestep", step=3e-3), "whole multiple of the time step"),
    (1e-5, SimulationOptions(solver="timestep"), "longer than the duration"),
    (0.1, SimulationOptions(solver="timestep", max_steps=10), "more than max_steps"),
], ids=["memory", "grid", "short", "max_steps"])
def test_a_batch_refuses_what_a_single_run_refuses(params, duration, options, match):
    """A batch is the same runs as `simulate` makes: what `simulate` refuses before it
    runs (steps, sample grid, memory), the batch refuses alike, before it allocates."""
    wrist = build_wrist(params).assemble()
    with pytest.raises(InputError, match=match):
        simulate(wrist, {}, duration, options=options)
    with pytest.raises(InputError, match=match):
        simulate_batch(wrist, {}, duration, initials=[InitialState()], options=options)


def test_a_batch_takes_its_initial_states_from_any_iterable_and_checks_threads(params):
    wrist = build_wrist(params).assemble()
    options = SimulationOptions(output_step=0.01)
    listed = simulate_batch(wrist, {}, 0.1, initials=[InitialState(q=q) for q in (0.0, 0.004)],
                            options=options)
    made = simulate_batch(wrist, {}, 0.1, initials=(InitialState(q=q) for q in (0.0, 0.004)),
                          options=options)
    assert np.array_equal(listed.states, made.states)
    for threads in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="threads must be a whole number >= 1"):
            simulate_batch(wrist, {}, 0.1, initials=[InitialState()], threads=threads)


def test_a_batch_with_a_controller_gives_its_signals_the_units_of_a_single_run(params):
    """The controller's bus and actuators carry their units and descriptions in a
    batch's dataset as in a single run's (they were all "1")."""
    from vsj.control import PID, Actuator, Controller, Sensor
    from vsj.inputs import Step
    from vsj.wrist import WristOptions

    wrist = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc")).assemble()
    controller = Controller(
        period=1e-3, references={"m1": Step(0.2), "m2": 0.0, "ms": 0.0},
        sensors=[Sensor.encoder(f"motor_{i}", 4096) for i in "12s"],
        blocks=[PID(f"u{i}", f"m{i}", f"motor_{i}", k=100.0, Ti=0.2) for i in "12s"],
        actuators=[Actuator(f"voltage_{i}", f"u{i}") for i in "12s"])
    single = simulate(wrist, {}, 0.1, controller=controller, ports=False).to_xarray()
    batch = simulate_batch(wrist, {}, 0.1, initials=[InitialState()],
                           controller=controller).to_xarray()
    assert batch["actuator.voltage_1"].attrs["units"] == "V"
    for name in batch.data_vars:
        if name.startswith(("control.", "actuator.")):
            assert batch[name].attrs == single[name].attrs, name

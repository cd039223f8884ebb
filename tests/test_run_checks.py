"""A run whose energy ledger does not close says what would (issue 31, item 15); a run
that crosses a physical limit stops where it crosses it."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from vsj.engine import core
from vsj.inputs import Constant, Table
from vsj.simulate import InitialState, SimulationOptions, prepare, simulate
from vsj.wrist import WristOptions, build_wrist


def test_a_failed_ledger_names_a_step_that_closes_it(params):
    """DC motors with true stiction under fast sine voltages: the residual the
    time-stepper leaves at the default step (its laws linearised about each step's
    predicted end, and the Coulomb impulses' round-off over 2000 steps) exceeds a ledger
    tolerance set near round-off; the message names a step, and that step closes the
    ledger."""
    times = np.linspace(0, 2, 2001)
    inputs = {"voltage_1": Table(times, 3.0 * np.sin(2 * np.pi * 5 * times)),
              "voltage_2": Table(times, 3.0 * np.sin(2 * np.pi * 3 * times))}
    structure = build_wrist(params, WristOptions(motors="dc")).assemble()
    tolerance = 1e-11
    r = simulate(structure, inputs, 2.0, initial=InitialState(q=-0.01), ports=False,
                 options=SimulationOptions(friction="stiction", ledger_tolerance=tolerance))
    assert not r.success and "does not close" in r.message
    step = float(re.search(r'try step = "([0-9.e+-]+) s"', r.message).group(1))
    assert step < 1e-3 and abs(1e-3 / step - round(1e-3 / step)) < 1e-9  # divides 1 ms
    again = simulate(structure, inputs, 2.0, initial=InitialState(q=-0.01), ports=False,
                     options=SimulationOptions(friction="stiction", ledger_tolerance=tolerance,
                                               step=step))
    assert again.success, again.message


def test_a_failed_dopri_ledger_names_an_rtol_that_closes_it(params):
    structure = build_wrist(params).assemble()
    inputs = {"motor_1": Table((0, 0.5, 1.0), (0, 3.0, -3.0))}
    options = SimulationOptions(rtol=1e-4, atol=1e-8, ledger_tolerance=1e-9)
    r = simulate(structure, inputs, 1.0, initial=InitialState(q=-0.01), options=options,
                 ports=False)
    assert not r.success and "does not close" in r.message
    rtol = float(re.search(r"try rtol = ([0-9.e+-]+)", r.message).group(1))
    again = simulate(structure, inputs, 1.0, initial=InitialState(q=-0.01), ports=False,
                     options=SimulationOptions(rtol=rtol, atol=1e-8 * rtol / 1e-4,
                                               ledger_tolerance=1e-9))
    assert again.success, again.message


@pytest.mark.parametrize("solver", ["dopri", "rosenbrock"])
def test_a_pivot_leaving_its_range_stops_the_run_where_it_leaves(params, solver):
    """The pivot alone turned at 100 rad/s, the rest at rest: the adaptive schemes took
    one long step from rest and reported its end (1.11 s) as the failure, its samples
    lost. The step that crosses the limit is halved until the crossing is located to
    the engine's resolution (VSJ_LIMIT_RESOLUTION, 1e-9 of the time reached): the run
    stops where the pivot's sine reaches q_max, its samples kept up to there."""
    structure = build_wrist(params).assemble()
    speeds = np.array([100.0 if s.channel == "motor_s" else 0.0 for s in structure.sources])
    rate = structure.B[structure.index(structure.pivot.flange)] @ speeds  # carrier, rad/s
    crossing = math.asin(structure.pivot.q_max / structure.pivot.amplitude) / rate
    plan = prepare(structure, {"motor_s": Constant(100.0)}, 3.0,
                   SimulationOptions(solver=solver), InitialState())
    times = np.arange(3001) * 1e-3
    run, states, _, _ = plan.sample(times)
    assert run.status == core.PIVOT_RANGE
    # located to 1e-9 s, plus the 1e-12 m the range check allows at 25 mm x 1 rad/s
    assert abs(run.t - crossing) <= 2e-9
    reached = ~np.isnan(states[:, 0])
    assert np.array_equal(reached, times <= run.t)

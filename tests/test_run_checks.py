"""A run whose energy ledger does not close says what would (issue 31, item 15)."""

from __future__ import annotations

import re

import numpy as np

from vsj.inputs import Table
from vsj.simulate import InitialState, SimulationOptions, simulate
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

"""End stops in the time-stepper, and the checks that keep a wrong run from passing.

The case of issue 18: motors held, q = -1 cm, 20 N m ramped onto the
end-effector over 4 s and held, 1 ms steps. Both springs are driven into their
end stops. The time-stepper treats each stop as a unilateral constraint solved
with the friction impulses (compliant: an extra row of the impulse problem;
rigid: none), so it is stable for every stop stiffness; the smooth law, run by
the adaptive solver with the stop as a stiff spring, is the reference.
"""

import math

import numpy as np
import pytest

from vsj.errors import InputError
from vsj.inputs import Constant, Table
from vsj.simulate import SimulationOptions, InitialState, simulate
from vsj.wrist import WristOptions, build_wrist

STOP = 1.40  # rad, the bundled end stop
LOAD = 20.0  # N m on theta_x
#: Static deflection of the time-stepper (true stiction) against the smooth arctan law:
#: both come to rest with the stop holding; friction holds the end-effector a little
#: differently (2e-4 rad measured).
DEFLECTION_TOL = 1e-3
#: Ledger closure with the eq 4.5 spring (linear in the deflection), for any stop.
LEDGER_TOL = 1e-6
#: With the geometric spring the trapezoidal linearisation of a non-linear spring leaves
#: a residual second order in the step (3e-5 measured at 1 ms): not the stop's.
LEDGER_TOL_GEOMETRIC = 1e-4


def run(params, stiffness, friction, elastic="exponential", load=LOAD, duration=8.0):
    p = params.with_overrides({"elastic_element.end_stop_stiffness": f"{stiffness} N m/rad"},
                              origin="test")
    structure = build_wrist(p, WristOptions(elastic=elastic)).assemble()
    ramp = Table((0.0, min(4.0, duration / 2), duration), (0.0, load, load))
    return simulate(structure, {"tau_x": ramp}, duration, initial=InitialState(q=-0.01),
                    options=SimulationOptions(friction=friction, output_step=0.01), ports=False)


@pytest.fixture(scope="module")
def smooth(params):
    """The smooth law's final deflection at 50 and 1000 N m/rad, per elastic model."""
    return {(elastic, k): run(params, k, "arctan", elastic)["phi_1"][-1]
            for elastic in ("exponential", "geometric") for k in (50.0, 1000.0)}


def reference(smooth, elastic, stiffness):
    """Deflection the stop allows: the smooth law's where it was run; for stiffer stops
    the same torque in the stop, which presses it in by torque / stiffness."""
    if (elastic, stiffness) in smooth:
        return smooth[(elastic, stiffness)]
    torque = 1000.0 * (smooth[(elastic, 1000.0)] - STOP)
    return STOP + torque / stiffness


@pytest.mark.parametrize("elastic, stiffness", [
    ("exponential", 50.0), ("exponential", 1000.0), ("exponential", 1e5), ("exponential", 1e7),
    ("geometric", 50.0), ("geometric", 1000.0), ("geometric", 1e7)])
def test_stiction_holds_the_end_stop_for_any_stiffness(params, smooth, elastic, stiffness):
    result = run(params, stiffness, "stiction", elastic)
    assert result.success, result.message
    phi = result["phi_1"]
    expected = reference(smooth, elastic, stiffness)
    assert abs(phi[-1] - expected) < DEFLECTION_TOL
    assert np.max(np.abs(phi)) < expected + DEFLECTION_TOL  # no overshoot into the stop
    tol = LEDGER_TOL if elastic == "exponential" else LEDGER_TOL_GEOMETRIC
    assert result.ledger["relative_residual"] < tol
    # the stops took energy (impacts, the implicit step) and the ledger says so
    assert result.ledger["dissipated"]["end stop vsm_1"] > 0.0


def test_a_soft_stop_stores_and_returns_its_energy(params):
    """Pressed into a 50 N m/rad stop and released, the spring comes back out: the
    stop's energy is stored while it is pressed, not lost."""
    p = params.with_overrides({"elastic_element.end_stop_stiffness": "50 N m/rad"}, origin="t")
    structure = build_wrist(p, WristOptions(elastic="exponential")).assemble()
    pulse = Table((0.0, 2.0, 4.0, 6.0, 10.0), (0.0, LOAD, LOAD, 0.0, 0.0))
    result = simulate(structure, {"tau_x": pulse}, 10.0, initial=InitialState(q=-0.01),
                      options=SimulationOptions(friction="stiction", output_step=0.01), ports=False)
    assert result.success
    phi = result["phi_1"]
    assert np.max(phi) > STOP + 0.2 and abs(phi[-1]) < 0.2
    assert result.ledger["relative_residual"] < LEDGER_TOL


def test_the_adaptive_solver_refuses_a_rigid_stop_the_time_stepper_takes_it(params):
    from vsj import components
    from vsj.network import Network
    from vsj.springs import EXPONENTIAL_FIELDS

    # a one-ring network with the eq 4.5 spring and a rigid stop
    fields = dict(zip(EXPONENTIAL_FIELDS,
                      (0.2, -145.0, 0.02, STOP, math.inf)))
    net = Network("ring")
    net.add(components.ElasticElement("vsm", model="exponential",
                                      exponential=list(fields.values())),
            components.Inertia("ring", 1e-4), components.TorqueSource("load", "tau"))
    net.connect("vsm.ring", "ring.flange").connect("ring.flange", "load.flange")
    structure = net.assemble()
    with pytest.raises(InputError, match="rigid end stop"):
        simulate(structure, {"tau": Constant(1.0)}, 1.0,
                 options=SimulationOptions(solver="dopri"))
    result = simulate(structure, {"tau": Table((0.0, 0.5, 2.0), (0.0, 5.0, 5.0))}, 2.0)
    assert result.solver["name"] == "timestep" and result.success, result.message
    assert np.max(np.abs(result["vsm.ring"])) <= STOP + 1e-9
    assert result.ledger["relative_residual"] < LEDGER_TOL


def test_a_run_past_the_stop_succeeds_with_a_warning(params):
    result = run(params, 50.0, "stiction", load=1000.0, duration=1.0)
    assert result.success
    assert any("past its 1.4 rad end stop" in w for w in result.warnings)
    assert "warning: spring vsm_1" in result.summary()
    quiet = run(params, 50.0, "stiction", load=0.5, duration=1.0)
    assert quiet.success and quiet.warnings == []


def test_the_cli_warns_on_standard_error_and_in_the_record(tmp_path, capsys):
    import json

    from vsj.cli import main

    scenario = tmp_path / "overload.toml"
    scenario.write_text('name = "overload"\ndescription = "1000 N m on the end-effector"\n'
                        'network = "wrist"\nduration = "0.2 s"\n[solver]\n'
                        'friction = "stiction"\nstep = "1 ms"\n[initial]\nq = "-1 cm"\n'
                        '[inputs.tau_x]\nkind = "constant"\nvalue = "1000 N m"\n')
    assert main(["simulate", str(scenario), "--out", str(tmp_path / "out"), "--no-plot"]) == 0
    err = capsys.readouterr().err
    assert "vsj: warning: [overload] spring vsm_1 was driven to" in err
    case, = json.loads((tmp_path / "out" / "meta.json").read_text())["cases"]
    assert case["success"] and any("past its 1.4 rad end stop" in w for w in case["warnings"])
    assert main(["linearize", "--tau-x", "1000 N m"]) == 0
    assert "past its 1.4 rad end stop" in capsys.readouterr().err
    assert main(["linearize", "--tau-x", "0.1 N m"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_a_diverging_run_fails(params):
    """A stop too soft to hold (1e-3 N m/rad) lets 200 N m wind the springs up by
    hundreds of radians: the run fails, naming the spring, the time and the state."""
    result = run(params, 1e-3, "stiction", load=200.0, duration=6.0)
    assert not result.success
    assert "ten turns past" in result.message and "at t = " in result.message
    assert "vsm_1.ring.angle=" in result.message


def test_an_energy_ledger_that_does_not_close_fails_the_run(params):
    structure = build_wrist(params).assemble()
    inputs = {"tau_x": Table((0.0, 0.5, 1.0), (0.0, 0.5, 0.5))}
    loose = SimulationOptions(rtol=1e-2, atol=1e-2, ledger_tolerance=1e-12)
    result = simulate(structure, inputs, 1.0, options=loose, ports=False)
    assert not result.success and "energy ledger does not close" in result.message
    assert result.ledger["relative_residual"] > 1e-12  # it was measured, and reported
    sound = simulate(structure, inputs, 1.0, ports=False)
    assert sound.success and sound.ledger["relative_residual"] < 1e-3


@pytest.mark.parametrize("options, duration, match", [
    ({"rtol": 0.5}, 1.0, "option rtol must be a number in"),
    ({"rtol": True}, 1.0, "option rtol must be a number in"),
    ({"atol": 1.0}, 1.0, "option atol"),
    ({"step": 2.0, "friction": "stiction"}, 0.5, "option step"),
    ({"step": 0.04, "output_step": 0.04, "friction": "stiction"}, 0.02, "longer than the duration"),
    ({"max_steps": 10, "friction": "stiction"}, 1.0, "more than max_steps"),
    ({"max_steps": 2.5}, 1.0, "max_steps must be a whole number"),
    ({"output_step": 1e-6}, 1e7, "GiB in memory, more than"),
    ({}, math.inf, "duration must be a finite time"),
])
def test_numerical_settings_outside_their_ranges_are_refused(params, options, duration, match):
    structure = build_wrist(params).assemble()
    with pytest.raises(InputError, match=match):
        simulate(structure, {}, duration, options=SimulationOptions(**options))


def test_a_dc_motor_beyond_its_voltage_limit_is_warned_about(params):
    structure = build_wrist(params, WristOptions(motors="dc")).assemble()
    assert structure.motors[0].voltage_limit == params.motor.voltage_limit
    high = simulate(structure, {"voltage_1": Constant(1000.0)}, 0.05,
                    options=SimulationOptions(rtol=1e-6), ports=False)
    assert any("1000 V" in w and "24 V limit" in w for w in high.warnings)
    rated = simulate(structure, {"voltage_1": Constant(12.0)}, 0.05,
                     options=SimulationOptions(rtol=1e-6), ports=False)
    assert not any("voltage" in w or " V " in w for w in rated.warnings)



def test_a_rigid_stop_is_a_parameter_value(params):
    # "inf N m/rad" in a parameter set makes the stop a constraint of the time-stepper
    result = run(params, "inf", "stiction", load=1000.0, duration=1.0)
    assert result.success, result.message
    assert np.max(np.abs(result["phi_1"])) <= STOP + 1e-9
    # a smooth law with a rigid stop: the automatic choice is the time-stepper
    assert run(params, "inf", "arctan", duration=0.5).solver["name"] == "timestep"
    for bad in ("-inf", "nan", "1e309"):
        with pytest.raises(InputError, match="end_stop_stiffness"):
            params.with_overrides({"elastic_element.end_stop_stiffness": f"{bad} N m/rad"},
                                  origin="test")

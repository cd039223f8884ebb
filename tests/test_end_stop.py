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

from vsj.engine.core import IMPULSE_REL
from vsj.errors import InputError
from vsj.inputs import Constant, Table
from vsj.simulate import SimulationOptions, InitialState, simulate
from vsj.springs import evaluate, spring_law
from vsj.stepper import Stepper
from vsj.wrist import WristOptions, build_wrist

STOP = 1.40  # rad, the bundled end stop
LOAD = 20.0  # N m on theta_x
Q = -0.01  # m, the pivot position of these runs (motors held)
EPS = np.finfo(float).eps
#: Round-off of the time-stepper's energy ledger per step: each booked term is a product
#: of a few doubles, rounded to about 1e-16 each; ten of them per step and term (as in
#: tests/test_regression.py). The eq 4.5 spring is integrated exactly by the trapezoidal
#: update (its torque is linear in the deflection over a step), so with it nothing else
#: is left, whatever the stop.
LEDGER_ROUNDOFF_PER_STEP = 1e-15
#: The impulse solver's absolute tolerance on a slip speed [rad/s] (engine/c/impulses.c).
IMPULSE_ABS = 1e-14


def ledger_roundoff(result) -> float:
    """The most a time-stepper run's ledger may leave when only round-off remains."""
    return result.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP


def stop_overshoot(result, load: float, inertia: float, speed: float) -> float:
    """How far [rad] the time-stepper may pass a rigid stop: it holds |d| <= stop at
    each step's end through the end speed, solved to IMPULSE_ABS + IMPULSE_REL times the
    largest free slip of the step (at most ``speed`` plus one step of the load's
    acceleration, ``load / inertia``); the trapezoidal update turns that speed into h/2 of
    it. Plus a few ulp of the angle."""
    h = result.solver["step"]
    slip = speed + h * load / inertia
    return h / 2 * (IMPULSE_ABS + IMPULSE_REL * slip) + 4 * EPS * STOP


def run(params, stiffness, friction, elastic="exponential", load=LOAD, duration=8.0,
        step=1e-3, output_step=0.01):
    p = params.with_overrides({"elastic_element.end_stop_stiffness": f"{stiffness} N m/rad"},
                              origin="test")
    structure = build_wrist(p, WristOptions(elastic=elastic)).assemble()
    ramp = Table((0.0, min(4.0, duration / 2), duration), (0.0, load, load))
    return simulate(structure, {"tau_x": ramp}, duration, initial=InitialState(q=Q),
                    options=SimulationOptions(friction=friction, output_step=output_step,
                                              step=step),
                    ports=False)


@pytest.fixture(scope="module")
def smooth(params):
    """The smooth law's final deflection at 50 and 1000 N m/rad, per elastic model."""
    return {(elastic, k): run(params, k, "arctan", elastic)["phi_1"][-1]
            for elastic in ("exponential", "geometric") for k in (50.0, 1000.0)}


def spring(params, elastic, stiffness):
    """The wrist's first spring (law and parameters) with an end stop of ``stiffness``."""
    p = params.with_overrides({"elastic_element.end_stop_stiffness": f"{stiffness} N m/rad"},
                              origin="test")
    return next(sp for sp in build_wrist(p, WristOptions(elastic=elastic)).assemble().springs
                if sp.name == "vsm_1")


def reference(params, smooth, elastic, stiffness):
    """Deflection [rad] the stop allows: the smooth law's where it was run (at rest the
    arctan law holds nothing, so that is the frictionless balance); for stiffer stops the
    deflection where spring and stop hold the same torque as at 1000 N m/rad (Newton's
    method on the law, which gives the torque and its slope)."""
    if (elastic, stiffness) in smooth:
        return smooth[(elastic, stiffness)]
    stiff, known = spring(params, elastic, stiffness), spring(params, elastic, 1000.0)
    target = spring_law(known.law, known.parameters, smooth[(elastic, 1000.0)], Q)[0]
    phi = smooth[(elastic, 1000.0)]  # past the stop, where the torque is smooth
    for _ in range(50):
        torque, slope = spring_law(stiff.law, stiff.parameters, phi, Q)[:2]
        phi += (torque - target) / slope
    return phi


def friction_band(params, elastic, stiffness, phi):
    """How far [rad] true stiction may hold the ring from the frictionless balance ``phi``:
    each friction element holds at most its Coulomb level, which reaches the first ring
    through its slip's coefficient on that ring (the springs' stiffness is diagonal in
    the ring angles, the motors are held); divided by the least stiffness of spring and
    stop near ``phi``."""
    structure = build_wrist(params, WristOptions(elastic=elastic)).assemble()
    torque = sum(f.coulomb * abs(sum(c * structure.rows(flange)[0][0]
                                     for flange, c in f.speed.items()))
                 for f in structure.frictions)
    sp = spring(params, elastic, stiffness)
    reach = torque / stiffness  # the stop alone: an upper bound on the distance
    slopes = evaluate(sp.law, sp.parameters, np.linspace(phi - reach, phi + reach, 41), Q)[1]
    return torque / slopes.min()


@pytest.mark.parametrize("elastic, stiffness", [
    ("exponential", 50.0), ("exponential", 1000.0), ("exponential", 1e5), ("exponential", 1e7),
    ("geometric", 50.0), ("geometric", 1000.0), ("geometric", 1e7)])
def test_stiction_holds_the_end_stop_for_any_stiffness(params, smooth, elastic, stiffness):
    # sampled at every step: the trapezoidal update leaves a stiff stop's fastest mode
    # undamped, so the ring may end in a period-two oscillation of the steps' states about
    # where friction holds it; the mean of the last two steps is that rest position
    result = run(params, stiffness, "stiction", elastic, output_step=1e-3)
    assert result.success, result.message
    phi = result["phi_1"]
    expected = reference(params, smooth, elastic, stiffness)
    band = friction_band(params, elastic, stiffness, expected)
    rest = 0.5 * (phi[-1] + phi[-2])
    # plus a few ulps of the angle: the mean's and the reference's Newton iteration's
    assert abs(rest - expected) <= band + 8 * EPS * abs(expected)
    # no overshoot into the stop: beyond the static band, only as far as the ring's kinetic
    # energy, at the fastest it met the stop, can press it (1/2 M v^2 = 1/2 k x^2)
    past = np.abs(phi) >= STOP
    speed = np.max(np.abs(result["phi_1.speed"][past]))
    mass = Stepper.wrist(params, WristOptions(elastic=elastic)).model.mass[0, 0]
    assert np.max(np.abs(phi)) <= expected + band + speed * np.sqrt(mass / stiffness)
    residual = result.ledger["relative_residual"]
    if elastic == "exponential":
        assert residual <= ledger_roundoff(result), residual
    else:
        # the trapezoidal update linearises the geometric spring within each step: what
        # the ledger leaves falls at second order when the step halves (ratio 4; first
        # order 2: their geometric mean)
        finer = run(params, stiffness, "stiction", elastic, step=result.solver["step"] / 2)
        assert residual / finer.ledger["relative_residual"] > 2 ** 1.5, residual
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
    assert result.ledger["relative_residual"] <= ledger_roundoff(result)


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
    speed = np.max(np.abs(result["vsm.ring.speed"]))
    assert np.max(np.abs(result["vsm.ring"])) <= STOP + stop_overshoot(result, 5.0, 1e-4, speed)
    assert result.ledger["relative_residual"] <= ledger_roundoff(result)


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
    # a sound run closes its ledger as its solver converges: every term is integrated by
    # the same error-controlled steps as the state, so the residual follows rtol (falls
    # about a hundredfold at rtol / 100; ten, the geometric mean of 1 and 100, separates
    # it from a residual that stays)
    sound = simulate(structure, inputs, 1.0, ports=False)
    finer = simulate(structure, inputs, 1.0, ports=False,
                     options=SimulationOptions(rtol=sound.solver["options"]["rtol"] / 100))
    assert sound.success and finer.success
    assert sound.ledger["relative_residual"] / finer.ledger["relative_residual"] > 10


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
    speed = np.max(np.abs(result["phi_1.speed"]))
    ring = params["planetary.ring_inertia"]  # the least inertia the ring's coordinate has
    assert np.max(np.abs(result["phi_1"])) <= STOP + stop_overshoot(result, 1000.0, ring, speed)
    # a smooth law with a rigid stop: the automatic choice is the time-stepper
    assert run(params, "inf", "arctan", duration=0.5).solver["name"] == "timestep"
    for bad in ("-inf", "nan", "1e309"):
        with pytest.raises(InputError, match="end_stop_stiffness"):
            params.with_overrides({"elastic_element.end_stop_stiffness": f"{bad} N m/rad"},
                                  origin="test")

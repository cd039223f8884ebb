"""DC motor: armature and rotor physics, and its place at the wrist's motor ports."""

import numpy as np
import pytest

from vsj.components import Bearing, DCMotor, Fixed, Inertia
from vsj.inputs import Constant, Table
from vsj.network import Network
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist


def test_steady_speed_and_current_follow_the_armature_equations():
    R, L, k, J, n, b = 2.0, 2e-4, 0.025, 1e-6, 10.0, 2e-3
    net = Network("motor")
    net.add(DCMotor("m", resistance=R, inductance=L, torque_constant=k, rotor_inertia=J,
                    gear_ratio=n, channel="v"), Inertia("load", 1e-4), Bearing("b", viscous=b))
    net.connect("m.flange", "load.flange").connect("m.flange", "b.flange")
    V = 12.0
    r = simulate(net.assemble(), {"v": Constant(V)}, 2.0,
                 options=SimulationOptions(friction="viscous"), ports=False)
    assert r.success
    # rotor: k i = (b / n^2) w_rotor; circuit: V = R i + k w_rotor
    w_rotor = V * k / (R * b / n ** 2 + k ** 2)
    # the transient is gone (2 s is over 300 time constants (J + J_load / n^2) / (b / n^2
    # + k^2 / R)): what remains is dopri's error, rtol per step; 10 rtol allows its growth
    rtol = 10 * SimulationOptions().rtol
    assert r["motor.m.speed"][-1] == pytest.approx(w_rotor, rel=rtol)
    # the load turns n times slower and its bearing resists with b w_load
    assert r["friction.b.torque"][-1] == pytest.approx(b * w_rotor / n, rel=rtol)
    # the current is a difference, (V - k w) / R: w's relative error times k w / (V - k w)
    assert r["motor.m.current"][-1] == pytest.approx(
        (V - k * w_rotor) / R, rel=rtol * k * w_rotor / (V - k * w_rotor))
    # the ledger's terms are integrated by the same error-controlled steps as the state
    assert r.ledger["relative_residual"] <= SimulationOptions().rtol
    assert r.ledger["dissipated"]["resistance m"] > 0


def test_dc_motor_wrist_agrees_across_solvers(params):
    structure = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc")).assemble()
    inputs = {"voltage_1": Table((0, 0.2, 1.0), (0, 6.0, 6.0)),
              "voltage_2": Table((0, 0.2, 1.0), (0, -4.0, -4.0))}
    runs = {}
    for solver, step in (("dopri", 1e-3), ("timestep", 1e-5)):
        runs[solver] = simulate(structure, inputs, 1.0, initial=InitialState(q=-0.01),
                                options=SimulationOptions(friction="arctan", solver=solver,
                                                          step=step), ports=False)
        assert runs[solver].success, runs[solver].message
    a, b = runs["dopri"], runs["timestep"]
    assert np.max(np.abs(a["theta_x"])) > 0.1  # the motors move the wrist
    # first-order time stepping with 10 us steps: agreement to ~1e-3 of the motion
    assert np.max(np.abs(a["theta_x"] - b["theta_x"])) < 2e-3 * np.max(np.abs(a["theta_x"]))
    assert b.ledger["relative_residual"] < 1e-3


# ---- the armature circuit in the time-stepper ----------------------------------------

def test_a_held_rotor_current_follows_the_armature_exponential_at_every_step():
    """With the rotor held, L di/dt = V - R i has the exact solution
    V/R (1 - exp(-t/tau)); the time-stepper integrates the circuit exactly over each
    step, so even a time constant ten times shorter than the step (the default motor
    at the default 1 ms) is followed to round-off. Implicit Euler was 9 % low after
    the first step."""
    R, L, V = 2.3, 2.4e-4, 6.0
    net = Network("held")
    net.add(DCMotor("m", resistance=R, inductance=L, torque_constant=0.0235,
                    rotor_inertia=1e-6, gear_ratio=14.0, channel="v"), Fixed("ground"))
    net.connect("m.flange", "ground.flange")
    r = simulate(net.assemble(), {"v": Constant(V)}, 0.01, ports=False,
                 options=SimulationOptions(friction="viscous", solver="timestep"))
    assert r.success, r.message
    exact = V / R * -np.expm1(-r.time * R / L)
    # a closed form of a few operations, each rounded to 1 ulp
    np.testing.assert_allclose(r["motor.m.current"], exact, rtol=1e-14, atol=0.0)


def _motor_on_a_damped_inertia(R=2.3, L=2.4e-4, k=0.0235, J=1.1e-6, n=14.0, J_load=2e-4,
                               b=3e-3):
    net = Network("motor")
    net.add(DCMotor("m", resistance=R, inductance=L, torque_constant=k, rotor_inertia=J,
                    gear_ratio=n, channel="v"), Inertia("load", J_load),
            Bearing("b", viscous=b))
    net.connect("m.flange", "load.flange").connect("m.flange", "b.flange")
    return net.assemble()


#: Round-off of the energy ledger per step: each booked term is a product of a few
#: doubles, rounded to about 1e-16 each; ten of them per step and term.
LEDGER_ROUNDOFF_PER_STEP = 1e-15


def test_a_linear_motor_drive_closes_its_ledger_to_round_off():
    """Motor, gearhead, load and viscous bearing are linear: with the circuit exact and
    the rotor moving with the mid-step speed, nothing is left for the ledger but
    round-off, even under a square-wave voltage."""
    structure = _motor_on_a_damped_inertia()
    square = Table((0, 0.1, 0.1001, 0.2, 0.2001, 0.3), (6, 6, -6, -6, 6, 6))
    r = simulate(structure, {"v": square}, 0.3, ports=False,
                 options=SimulationOptions(friction="viscous", solver="timestep"))
    assert r.success, r.message
    assert r.ledger["relative_residual"] <= r.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP


#: Voltage programs of DC-driven wrist runs with true stiction (an audit found the
#: implicit-Euler armature leaving ledger residuals from 3e-5 to 7 % at the default step).
DC_PROGRAMS = {
    "constant": ({"voltage_1": Constant(1.0)}, False),
    "slow sine": ({"voltage_1": Table(np.linspace(0, 4, 401),
                                      2.0 * np.sin(2 * np.pi * 0.2 * np.linspace(0, 4, 401)))},
                  False),
    "fast sine": ({"voltage_1": Table(np.linspace(0, 4, 4001),
                                      3.0 * np.sin(2 * np.pi * 5 * np.linspace(0, 4, 4001))),
                   "voltage_2": Table(np.linspace(0, 4, 4001),
                                      3.0 * np.sin(2 * np.pi * 3 * np.linspace(0, 4, 4001)))},
                  False),
    "square wave": ({"voltage_1": Table((0, 1, 1.0001, 2, 2.0001, 3, 3.0001, 4),
                                        (2, 2, -2, -2, 2, 2, -2, -2))}, False),
    "DC-driven pivot": ({"voltage_1": Constant(1.0),
                         "voltage_s": Table((0, 1, 1.0001, 4), (0, 0, 3, 3))}, True),
}
#: The default configuration's accuracy target for the energy ledger (issue 30).
DC_LEDGER = 1e-6


@pytest.mark.parametrize("program", list(DC_PROGRAMS))
def test_dc_wrist_with_stiction_closes_its_ledger_at_the_default_step(params, program):
    inputs, dc_pivot = DC_PROGRAMS[program]
    structure = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc" if dc_pivot
                                                 else "velocity")).assemble()
    r = simulate(structure, inputs, 4.0, initial=InitialState(q=-0.01), ports=False,
                 options=SimulationOptions(friction="stiction"))
    assert r.success, r.message
    assert r.solver["step"] == 1e-3  # the default step
    assert r.ledger["relative_residual"] <= DC_LEDGER, r.ledger["relative_residual"]
    assert r.ledger["dissipated"]["resistance motor_1"] > 0.0


def test_what_remains_of_the_dc_ledger_residual_is_second_order(params):
    """With the circuit exact, the residual left is the springs' linearisation within
    a step: it falls at second order as the step halves."""
    inputs, _ = DC_PROGRAMS["fast sine"]
    structure = build_wrist(params, WristOptions(motors="dc")).assemble()
    residual = []
    for h in (1e-3, 5e-4):
        r = simulate(structure, inputs, 4.0, initial=InitialState(q=-0.01), ports=False,
                     options=SimulationOptions(friction="stiction", step=h))
        assert r.success, r.message
        residual.append(r.ledger["relative_residual"])
    # error ratio 4 for second order, 2 for first: their geometric mean separates them
    assert residual[0] / residual[1] > 2 ** 1.5, residual

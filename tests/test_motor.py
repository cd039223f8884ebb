"""DC motor: armature and rotor physics, and its place at the wrist's motor ports."""

import numpy as np
import pytest

from vsj.components import Bearing, DCMotor, Inertia
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
    assert r["motor.m.speed"][-1] == pytest.approx(w_rotor, rel=1e-6)
    # the load turns n times slower and its bearing resists with b w_load
    assert r["friction.b.torque"][-1] == pytest.approx(b * w_rotor / n, rel=1e-6)
    assert r["motor.m.current"][-1] == pytest.approx((V - k * w_rotor) / R, rel=1e-6)
    assert r.ledger["relative_residual"] < 1e-6
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

"""Assembly: elimination, state choice, inconsistent networks, port flows."""

import numpy as np
import pytest

from vsj.components import Inertia, TorqueSource, Transmission, VelocitySource
from vsj.errors import InputError
from vsj.inputs import Sine
from vsj.network import Network
from vsj.simulate import InitialState, simulate
from vsj.wrist import WristOptions, build_wrist


#: A handful of roundings, half an ulp each.
ROUNDING = 8 * np.finfo(float).eps


def test_wrist_reduces_to_one_degree_of_freedom_per_chain(params):
    s = build_wrist(params).assemble()
    assert s.free == ("vsm_1.ring", "vsm_2.ring")
    s2 = build_wrist(params.with_overrides({"transmission.series_compliance_1": "0.5 rad/(N m)"},
                                           origin="t")).assemble()
    assert s2.n == 3 and "tr_1.output" in s2.free  # the compliance frees its far side


def test_dc_motors_add_their_rotors(params):
    s = build_wrist(params, WristOptions(motors="dc", pivot_drive="dc")).assemble()
    assert set(s.free) == {"vsm_1.ring", "vsm_2.ring", "motor_1.rotor", "motor_2.rotor",
                           "motor_s.rotor"}
    assert len(s.motors) == 3


def test_over_determined_sources_are_named():
    net = Network("bad")
    net.add(VelocitySource("a"), VelocitySource("b"), Inertia("m", 1.0))
    net.connect("a.flange", "m.flange").connect("b.flange", "m.flange")
    with pytest.raises(InputError, match="over-determined.*a, b"):
        net.assemble()


def test_massless_degree_of_freedom_is_named():
    net = Network("bad")
    net.add(Inertia("m", 1.0), Transmission("t", compliance=0.1), TorqueSource("push"))
    net.connect("m.flange", "t.input").connect("t.output", "push.flange")
    with pytest.raises(InputError, match="no inertia.*t.output"):
        net.assemble()


def test_connection_torques_balance_the_sources(params):
    """The motor's flange has no inertia, so the connection to the sun carries exactly
    the source's torque (Newton per flange, solved after the run)."""
    s = build_wrist(params).assemble()
    r = simulate(s, {"motor_1": Sine(2.0, 1.0), "tau_x": Sine(0.05, 2.0)}, 1.0,
                 initial=InitialState(q=-0.004))
    assert r.success
    port = r["port.motor_1.flange--pg_1.sun.torque"]
    source = r["source.motor_1.torque"]
    # both solved from Newton's law on the constraint rows: a few ulp of the largest
    # torque of the run, amplified by the rows' condition number
    largest = max(np.max(np.abs(r[name])) for name in r.columns() if name.endswith(".torque"))
    tol = ROUNDING * np.linalg.cond(s.constraint_rows) * largest
    assert np.max(np.abs(port + source)) <= tol
    assert np.max(np.abs(source)) > 1e-3
    # power flows through a rigid connection unchanged: into the sun = out of the motor
    # (each torque times the same speed)
    speed = np.abs(r["source.motor_1.speed"])
    assert np.all(np.abs(r["port.motor_1.flange--pg_1.sun.power"] + r["source.motor_1.power"])
                  <= (tol + ROUNDING * largest) * speed)


def test_initial_angles_must_respect_the_constraints(params):
    s = build_wrist(params).assemble()
    with pytest.raises(InputError, match="contradict"):
        s.initial_positions({"pg_1.carrier": 0.1, "vsm_1.ring": 0.0, "pg_1.sun": 0.0})


def test_initial_angles_are_the_least_norm_solution_each_time(params):
    """The rows' pseudo-inverse is kept per set of named flanges: each call solves its
    own angles, the smallest motion that meets them (orthogonal to the rows' null
    space), and a contradiction is still found after a consistent call."""
    s = build_wrist(params).assemble()
    names = ("pg_1.carrier", "vsm_1.ring")
    rows = np.array([np.concatenate(s.rows(f)) for f in names])
    null = np.linalg.svd(rows)[2][len(names):]  # the motions that leave both angles
    for target in ([0.1, 0.0], [-0.3, 0.25], [0.0, 0.0]):
        x0, sigma0 = s.initial_positions(dict(zip(names, target)))
        sol = np.concatenate([x0, sigma0])
        # round-off of a solve with rows of order one: a few ulp of the target
        assert np.allclose(rows @ sol, target, rtol=0, atol=1e-14)
        assert np.max(np.abs(null @ sol)) <= 1e-14
    with pytest.raises(InputError, match="contradict"):
        s.initial_positions({"pg_1.carrier": 0.1, "vsm_1.ring": 0.0, "pg_1.sun": 0.0})

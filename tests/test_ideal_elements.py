"""Ideal elements against relations derived independently of their code.

Each component is checked twice: its kinematics (an assembled network's speed
rows, `Structure.rows`) against the relation of the report, and its torques
(what the engine's velocity sources must supply, `source.<name>.torque`)
against a static balance worked out by hand here: the planet's force balance
for the planetary set, the lever of a gear pair, the two bevel meshes of the
differential. None of these use the component's own matrix, so a wrong
coefficient in a component, or a torque that is not the transpose of its
kinematics, fails (unlike a check of ``C^T nu`` against ``C``'s null space,
which holds for any matrix ``C``).
"""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from vsj.components import (
    Differential,
    Fixed,
    IdealGear,
    IdealPlanetary,
    TorqueSource,
    Transmission,
    VelocitySource,
)
from vsj.inputs import Constant
from vsj.network import Network, Signal
from vsj.simulate import SimulationOptions, simulate

EPS = np.finfo(float).eps
#: Rounding of a coefficient or a torque built by a handful of operations (a ratio of
#: tooth counts, a product along a chain of elements): half an ulp each.
ULPS = 8


def roundoff(scale):
    """A few roundings of terms up to ``scale``."""
    return ULPS * EPS * scale


def magnitudes(limit, smallest=1e-6):
    """Zero, or a value of either sign from ``smallest`` to ``limit`` in magnitude: products
    of such values stay in the normal range, where rounding errs relatively (below it, a
    rounding errs by half the smallest subnormal whatever the value)."""
    return st.one_of(st.just(0.0), st.floats(smallest, limit), st.floats(-limit, -smallest))


def torque_tol(structure, scale):
    """Round-off [N m] of a torque solved from the constraint rows (sources by the engine,
    connections by a pseudo-inverse, `vsj.simulate.signals.port_flows`): a few ulp of the
    largest torque, amplified by the rows' condition number."""
    return roundoff(np.linalg.cond(structure.constraint_rows) * scale)


speeds = magnitudes(100)
torques = magnitudes(10)
teeth = st.integers(8, 200)
ratios = st.floats(0.1, 10)
#: A short run: the sources are constant, so every sample is the same static balance.
SHORT = SimulationOptions(output_step=0.01)


def _speed_row(structure, flange):
    """Coefficients of a flange speed on the sources, by source name (no free states)."""
    rx, ru = structure.rows(flange)
    assert rx.size == 0 or not np.any(rx), f"{flange} should follow the sources alone"
    return {s.name: ru[j] for j, s in enumerate(structure.sources)}


def _static(net, levels):
    """Run ``net`` with constant inputs; the last sample of every signal."""
    result = simulate(net.assemble(), {k: Constant(v) for k, v in levels.items()}, 0.01,
                      options=SHORT)
    assert result.success, result.message
    return {name: result[name][-1] for name in result.columns()}


def _close(structure, a, b, scale):
    return abs(a - b) <= torque_tol(structure, scale)


# -- the components' own methods ----------------------------------------------


@given(n_s=teeth, n_r=teeth, w_r=speeds, w_s=speeds, tau_c=torques)
def test_planetary_methods_follow_willis_and_the_planets_balance(n_s, n_r, w_r, w_s, tau_c):
    """The component's own methods against relations that do not use its ratios: Willis'
    equation for `speeds` (seen from the carrier, sun and ring turn oppositely at the
    inverse ratio of their teeth) and the planet's balance for `torques` (the same tooth
    force on sun and ring: torques in the ratio of the teeth, and with the carrier's they
    sum to zero). A wrong ratio, a swapped pair or a sign fails; power balance follows."""
    gear = IdealPlanetary("pg", n_s, n_r)
    w_c = gear.speeds(w_r, w_s)
    tau_r, tau_s = gear.torques(tau_c)
    # each side a speed difference times a tooth count: a few ulp of the largest term
    speed_scale = (n_s + n_r) * max(abs(w_s), abs(w_r), abs(w_c))
    assert abs((w_s - w_c) * n_s + (w_r - w_c) * n_r) <= roundoff(speed_scale)
    torque_scale = (n_s + n_r) * abs(tau_c)
    assert abs(tau_r * n_s - tau_s * n_r) <= roundoff(torque_scale)
    assert abs(tau_r + tau_s + tau_c) <= roundoff(abs(tau_c))
    terms = np.array([tau_c * w_c, tau_r * w_r, tau_s * w_s])
    assert abs(terms.sum()) <= roundoff(np.abs(terms).max())


def test_planetary_ratios_follow_eq_3_11():
    gear = IdealPlanetary("pg", 16, 50)
    # one correctly rounded division each, as here: equal on any machine
    assert gear.r_RC == 50 / 66 and gear.r_SC == 16 / 66
    # ring held: the carrier turns r_SC times the sun; sun held: r_RC times the ring
    # (products with 0 and 1: exact)
    assert gear.speeds(0.0, 1.0) == 16 / 66
    assert gear.speeds(1.0, 0.0) == 50 / 66


def test_differential_follows_eq_3_31():
    # halves and sums of 0, 1 and 2: exact in binary on any machine
    assert np.array_equal(Differential.speeds([1.0, 1.0]), [1.0, 0.0])
    assert np.array_equal(Differential.speeds([1.0, -1.0]), [0.0, 1.0])
    # outputs loaded: each input holds half of tau_x, and +-half of tau_y
    assert np.array_equal(Differential.torques([2.0, 0.0]), [1.0, 1.0])
    assert np.array_equal(Differential.torques([0.0, 2.0]), [1.0, -1.0])


# -- planetary set: Willis' equation and the planet's force balance -----------


@settings(max_examples=40)
@given(n_s=teeth, n_r=teeth)
def test_planetary_kinematics_is_willis_equation(n_s, n_r):
    """With sun and ring driven, the carrier obeys Willis' equation
    ``(w_S - w_C) / (w_R - w_C) = -N_R / N_S`` (seen from the carrier, sun and
    ring turn in opposite senses at the inverse ratio of their teeth), that is
    ``w_C = (N_S w_S + N_R w_R) / (N_S + N_R)`` (eq 3.9)."""
    net = Network("willis")
    net.add(IdealPlanetary("pg", n_s, n_r), VelocitySource("sun"), VelocitySource("ring"))
    net.connect("sun.flange", "pg.sun").connect("ring.flange", "pg.ring")
    row = _speed_row(net.assemble(), "pg.carrier")
    # rows from one elimination: a few ulp of each coefficient
    assert abs(row["sun"] - n_s / (n_s + n_r)) <= ULPS * EPS * n_s / (n_s + n_r)
    assert abs(row["ring"] - n_r / (n_s + n_r)) <= ULPS * EPS * n_r / (n_s + n_r)
    # Willis at one operating point, in its own form: a few ulp of its largest term
    w_s, w_r = 3.0, -1.0
    w_c = row["sun"] * w_s + row["ring"] * w_r
    assert abs((w_s - w_c) * n_s + (w_r - w_c) * n_r) <= ULPS * EPS * (n_s + n_r) * abs(w_s)


@settings(max_examples=25)
@given(n_s=teeth, n_r=teeth, w_s=magnitudes(50), tau_c=torques)
def test_planetary_torques_follow_the_planets_force_balance(n_s, n_r, w_s, tau_c):
    """A planet meshes with the sun and the ring at the same tangential force F
    (its own moment balance) and is pushed by the carrier at its centre with 2F.
    With pitch radii in proportion to the tooth counts, the torques on the
    members are ``tau_S : tau_R : tau_C = N_S : N_R : -(N_S + N_R)``. Ring held,
    sun driven, a torque ``tau_c`` applied to the carrier: the sun's source
    supplies ``-N_S/(N_S+N_R) tau_c``, the ground ``-N_R/(N_S+N_R) tau_c``."""
    net = Network("planet")
    net.add(IdealPlanetary("pg", n_s, n_r), VelocitySource("drive"), Fixed("ground"),
            TorqueSource("load"))
    net.connect("drive.flange", "pg.sun").connect("pg.ring", "ground.flange")
    net.connect("load.flange", "pg.carrier")
    last = _static(net, {"drive": w_s, "load": tau_c})
    tau_s = last["source.drive.torque"]
    # the connection's torque is applied to its first flange, the ring
    tau_r = last["port.pg.ring--ground.flange.torque"]
    structure = net.assemble()
    assert _close(structure, tau_s, -n_s / (n_s + n_r) * tau_c, abs(tau_c))
    assert _close(structure, tau_r, -n_r / (n_s + n_r) * tau_c, abs(tau_c))


# -- gear pair and transmission: the lever of a gear mesh ---------------------


@settings(max_examples=25)
@given(ratio=ratios, w_b=magnitudes(50), tau_a=torques)
def test_gear_pair_speed_and_torque_ratio(ratio, w_b, tau_a):
    """``omega_a = ratio omega_b``; a torque on a is held at b by ``-ratio tau_a``
    (radius ratio of the mesh: the same tooth force on both wheels)."""
    net = Network("gear")
    net.add(IdealGear("g", ratio), VelocitySource("drive"), TorqueSource("load"))
    net.connect("drive.flange", "g.b").connect("load.flange", "g.a")
    structure = net.assemble()
    assert abs(_speed_row(structure, "g.a")["drive"] - ratio) <= ULPS * EPS * ratio
    last = _static(net, {"drive": w_b, "load": tau_a})
    assert _close(structure, last["source.drive.torque"], -ratio * tau_a, abs(ratio * tau_a))


@settings(max_examples=20)
@given(ratio=ratios, w_out=magnitudes(20), tau_out=torques,
       viscous=st.one_of(st.just(0.0), st.floats(1e-6, 0.1)))
def test_transmission_ratio_and_friction_on_its_input(ratio, w_out, tau_out, viscous):
    """A rigid transmission module turns its input ``ratio`` times its output
    (input over output, table 4.1's module), and its viscous ``b_T`` acts on the
    input (carrier side): driven at the input with a torque on the output, the
    source supplies ``b_T w_in - tau_out / ratio``."""
    net = Network("transmission")
    net.add(Transmission("tr", ratio=ratio, viscous=viscous), VelocitySource("drive"),
            TorqueSource("load"))
    net.connect("drive.flange", "tr.input").connect("load.flange", "tr.output")
    structure = net.assemble()
    assert abs(_speed_row(structure, "tr.output")["drive"] - 1.0 / ratio) <= ULPS * EPS / ratio
    w_in = ratio * w_out
    last = _static(net, {"drive": w_in, "load": tau_out})
    expected = viscous * w_in - tau_out / ratio
    assert _close(structure, last["source.drive.torque"], expected,
                  abs(viscous * w_in) + abs(tau_out) / ratio)


@settings(max_examples=15)
@given(ratio=ratios, compliance=st.floats(0.01, 10.0), twist=magnitudes(1.0))
def test_transmission_compliance_seen_through_its_ratio(ratio, compliance, twist):
    """Fig 4.14's parasitic compliance sits on the output side of the gear: with
    the output held, turning the input by ``phi`` twists the spring by
    ``phi / ratio``, so the input feels the stiffness ``1 / (c ratio^2)``."""
    net = Network("compliant")
    net.add(Transmission("tr", ratio=ratio, compliance=compliance), VelocitySource("drive"),
            Fixed("ground"))
    net.connect("drive.flange", "tr.input").connect("tr.output", "ground.flange")
    # drive at a constant speed for 0.01 s: the input angle is 0.01 * speed
    last = _static(net, {"drive": twist / 0.01})
    expected = twist / (compliance * ratio ** 2)
    structure = net.assemble()
    assert _close(structure, last["source.drive.torque"], expected, abs(expected))
    # the spring pulls the held output along with the input (the torque transmitted)
    assert _close(structure, last["spring.tr.compliance.torque"], twist / (ratio * compliance),
                  abs(expected) * ratio)


# -- differential: two bevel meshes -------------------------------------------


@settings(max_examples=25)
@given(w1=magnitudes(20), w2=magnitudes(20), tx=torques, ty=torques)
def test_differential_mixes_inputs_as_eq_3_30(w1, w2, tx, ty):
    """``theta_x = (psi_1 + psi_2)/2``, ``theta_y = (psi_1 - psi_2)/2`` (eq 3.30-3.31,
    d1/d2 = 1). Statics: a torque about x turns both inputs alike, so each
    input holds half of it; a torque about y turns them oppositely, so they
    hold +-half: ``tau_1 = -(tau_x + tau_y)/2``, ``tau_2 = -(tau_x - tau_y)/2``."""
    net = Network("diff")
    net.add(Differential("d"), VelocitySource("in_1"), VelocitySource("in_2"),
            TorqueSource("tau_x"), TorqueSource("tau_y"))
    net.connect("in_1.flange", "d.input_1").connect("in_2.flange", "d.input_2")
    net.connect("tau_x.flange", "d.theta_x").connect("tau_y.flange", "d.theta_y")
    structure = net.assemble()
    x, y = _speed_row(structure, "d.theta_x"), _speed_row(structure, "d.theta_y")
    assert np.allclose([x["in_1"], x["in_2"], y["in_1"], y["in_2"]], [0.5, 0.5, 0.5, -0.5],
                       rtol=0, atol=ULPS * EPS * 0.5)
    last = _static(net, {"in_1": w1, "in_2": w2, "tau_x": tx, "tau_y": ty})
    scale = abs(tx) + abs(ty)
    assert _close(structure, last["source.in_1.torque"], -(tx + ty) / 2, scale)
    assert _close(structure, last["source.in_2.torque"], -(tx - ty) / 2, scale)


# -- a chain of them: kinematics and torques compose through the connections --


@settings(max_examples=20)
@given(n_s=teeth, n_r=teeth, ratio=ratios, w_1=magnitudes(20), w_2=magnitudes(20),
       tx=torques, ty=torques)
def test_wrist_chain_of_ideal_elements(n_s, n_r, ratio, w_1, w_2, tx, ty):
    """Two sun drives -> planetary sets (ring held) -> transmissions -> differential,
    as in the wrist with its elastic elements locked. The end-effector speeds
    and the motors' torques are the products of the hand-derived ratios above:
    ``psi_i = (N_S / (N_S+N_R)) w_i / ratio`` and each motor holds
    ``N_S / (N_S+N_R) / ratio`` of its input's share of the output torques.
    The rigid connections pass power unchanged: what the motors put in, the
    loads take out, and each connection reports the torque of the flange it
    joins."""
    net = Network("chain")
    r_sc = n_s / (n_s + n_r)
    for i in (1, 2):
        net.add(IdealPlanetary(f"pg_{i}", n_s, n_r), Fixed(f"ground_{i}"),
                VelocitySource(f"motor_{i}"), Transmission(f"tr_{i}", ratio=ratio))
        net.connect(f"motor_{i}.flange", f"pg_{i}.sun").connect(f"pg_{i}.ring",
                                                                 f"ground_{i}.flange")
        net.connect(f"pg_{i}.carrier", f"tr_{i}.input")
        net.connect(f"tr_{i}.output", f"d.input_{i}")
    net.add(Differential("d"), TorqueSource("tau_x"), TorqueSource("tau_y"))
    net.connect("d.theta_x", "tau_x.flange").connect("d.theta_y", "tau_y.flange")
    net.signal(Signal("theta_x", "d.theta_x")).signal(Signal("theta_y", "d.theta_y"))
    structure = net.assemble()
    psi = np.array([w_1, w_2]) * r_sc / ratio
    x, y = _speed_row(structure, "d.theta_x"), _speed_row(structure, "d.theta_y")
    gain = r_sc / ratio
    # a product along the chain: a few ulp of each coefficient
    assert np.allclose([x["motor_1"], x["motor_2"], y["motor_1"], y["motor_2"]],
                       np.array([0.5, 0.5, 0.5, -0.5]) * gain, rtol=ULPS * EPS, atol=0.0)
    last = _static(net, {"motor_1": w_1, "motor_2": w_2, "tau_x": tx, "tau_y": ty})
    scale = (abs(tx) + abs(ty)) * max(gain, 1.0)
    assert _close(structure, last["source.motor_1.torque"], -gain * (tx + ty) / 2, scale)
    assert _close(structure, last["source.motor_2.torque"], -gain * (tx - ty) / 2, scale)
    # speeds: the rows times the sources' speeds, a few ulp of the largest
    speed_tol = roundoff(abs(psi).max())
    assert abs(last["theta_x.speed"] - (psi[0] + psi[1]) / 2) <= speed_tol
    assert abs(last["theta_y.speed"] - (psi[0] - psi[1]) / 2) <= speed_tol
    power_in = last["source.motor_1.power"] + last["source.motor_2.power"]
    power_out = last["load.tau_x.power"] + last["load.tau_y.power"]
    assert _close(structure, power_in + power_out, 0.0, scale * (abs(w_1) + abs(w_2)))
    # the planet's balance once more: the connection pushes the carrier with
    # -(N_S + N_R)/N_S times the sun's torque
    carrier = last["port.pg_1.carrier--tr_1.input.torque"]
    assert _close(structure, carrier, -last["source.motor_1.torque"] / r_sc, scale / r_sc)

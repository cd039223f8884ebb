"""Friction laws: all dissipate, all are odd, and each has its documented shape."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vsj import friction

EPS = np.finfo(float).eps
#: A law's torque is a handful of operations (a product, an arctan, a sum): half an ulp
#: each.
ULPS = 8

laws = st.sampled_from(sorted(friction.RUN_LAWS))  # (a contact's force needs its penetration)
speed = st.floats(-50, 50, allow_nan=False)
positive = st.floats(0, 1, allow_nan=False)


@given(law=laws, s=speed, b=positive, k=positive, kb=st.floats(0.1, 100), w=st.floats(1e-4, 1))
def test_every_law_dissipates_and_is_odd(law, s, b, k, kb, w):
    f = friction.torque(law, [s, -s], viscous=b, stiction=k, sharpness=kb, width=w)
    assert f[0] * s >= 0.0
    # the same operations on negated operands: round-to-nearest is symmetric, and atan,
    # sign and clip are odd, so the law is odd to the last bit on any machine
    assert f[1] == -f[0]


@given(law=st.sampled_from(["arctan", "sign", "slope", "stiction"]), k=st.floats(1e-4, 1))
def test_every_coulomb_law_saturates_at_k_pi_over_2(law, k):
    speed, sharpness = 1e6, 10.0
    f = friction.torque(law, [speed], stiction=k, sharpness=sharpness, width=1e-3)[0]
    # the arctan law is k atan(k_b s) there, the others at their level (to rounding)
    level = k * math.pi / 2
    expected = k * math.atan(sharpness * speed) if law == "arctan" else level
    assert f == pytest.approx(expected, rel=ULPS * EPS, abs=0.0)
    # and k atan(k_b s) is within k / (k_b s) of the level (pi/2 - atan(x) < 1/x, a bound
    # tight to 1/(3 x^3); the two products round by an ulp each)
    assert level - expected <= k / (sharpness * speed) + ULPS * EPS * level


def test_slope_law_is_linear_inside_its_band():
    k, w = 0.01, 0.02
    s = np.linspace(-w, w, 9)
    f = friction.torque("slope", s, stiction=k, width=w)
    assert np.allclose(f, k * math.pi / 2 * s / w, rtol=ULPS * EPS, atol=0.0)


def test_viscous_law_drops_the_coulomb_part():
    # b s with s = 2: a doubling, exact
    assert friction.torque("viscous", [2.0], viscous=0.1, stiction=5.0)[0] == 0.1 * 2.0


def test_unknown_law_is_named():
    with pytest.raises(ValueError, match="unknown friction law 'coulomb'"):
        friction.law_code("coulomb")


def _engine_atan(x):
    """The engine's arctangent, as the arctan law with k = 1, k_b = 1, b = 0 gives it
    (k atan(k_b s) with unit factors: the products are exact)."""
    return friction.torque("arctan", x, stiction=1.0, sharpness=1.0)


def test_the_engines_arctangent_is_within_two_ulps_of_the_c_librarys():
    # the engine's arctangent (engine/c/internal.h) is within 0.9 ulp of the exact value
    # on every interval of its reduction (tools/atan_coefficients.py measures it), and a
    # C library's atan within an ulp (glibc's within 0.52): the two are less than two
    # ulps apart
    rng = np.random.default_rng(7)
    wide = np.sign(rng.normal(size=200_000)) * 10.0 ** rng.uniform(-308, 308, 200_000)
    near = rng.uniform(-5.0, 5.0, 200_000)
    # a thousand neighbours on each side of each switch of the reduction
    edges = [b + np.arange(-1000, 1001) * np.spacing(b)
             for b in (0.4375, 0.6875, 1.1875, 2.4375)]
    x = np.concatenate([wide, near, *edges, -np.concatenate(edges)])
    got = _engine_atan(x)
    expected = np.array([math.atan(v) for v in x])
    ulps = np.abs(got - expected) / np.spacing(np.abs(expected))
    assert ulps.max() < 2.0, x[np.argmax(ulps)]
    # and it rises wherever x rises, across the switches too (a friction law's slope
    # is never negative)
    order = np.sort(x)
    assert np.all(np.diff(_engine_atan(order)) >= 0.0)


def test_the_engines_arctangent_keeps_signed_zeros_and_tiny_and_huge_values():
    # (through the law with b = 0: its 0 s term is a zero of the speed's sign, so that
    # atan(-0) must be -0 for the torque to be -0)
    x = np.array([0.0, -0.0, 5e-324, -5e-324, 1e-310, 1e-20, 1e300, -1e300])
    got = _engine_atan(x)
    assert np.array_equal(np.signbit(got[:2]), [False, True]) and np.all(got[:2] == 0.0)
    assert np.array_equal(got[2:6], x[2:6])  # atan(x) = x to the last bit below 1e-8
    assert got[6] == math.pi / 2 and got[7] == -math.pi / 2  # the double nearest pi/2


def test_elements_on_one_shaft_each_keep_their_own_law():
    """Bearings and a slip friction on two shafts, several on one shaft (the engine
    evaluates a shared slip once, and an arctangent once where the sharpness is the
    same): each element's torque is its own law at its own slip, as computed here by
    hand, in the accelerations and in each element's dissipation rate (the ledger
    evaluates every element, the dynamics only those the shafts feel)."""
    from vsj.components import Bearing, Inertia, TorqueSource
    from vsj.components.basic import SlipFriction
    from vsj.inputs import Constant
    from vsj.network import Network
    from vsj.simulate import InitialState, SimulationOptions, prepare

    # name: (shaft or the slip "J1-J2", viscous, stiction k, sharpness), in network order
    elements = {"b1": ("J1", 0.01, 0.2, 10.0), "slip": ("J1-J2", 0.0, 0.05, 10.0),
                "b2": ("J1", 0.0, 0.3, 30.0), "b3": ("J2", 0.02, 0.1, 10.0),
                "b4": ("J1", 0.03, 0.15, 10.0), "b5": ("J2", 0.0, 0.25, 3.0)}
    inertia = {"J1": 0.2, "J2": 0.5}
    net = Network("shafts")
    net.add(TorqueSource("torque", "torque"), *(Inertia(j, v) for j, v in inertia.items()))
    net.connect("torque.flange", "J1.flange")
    for name, (shaft, b, k, kb) in elements.items():
        if shaft == "J1-J2":
            net.add(SlipFriction(name, viscous=b, stiction=k, sharpness=kb))
            net.connect("J1.flange", f"{name}.a").connect(f"{name}.b", "J2.flange")
        else:
            net.add(Bearing(name, viscous=b, stiction=k, sharpness=kb))
            net.connect(f"{shaft}.flange", f"{name}.flange")
    structure = net.assemble()
    assert [f.name for f in structure.frictions] == list(elements)
    plan = prepare(structure, {"torque": Constant(0.4)}, 1.0,
                   SimulationOptions(friction="arctan"),
                   InitialState(speeds={"J1.flange": 0.3, "J2.flange": -0.07}))
    engine = plan.engine()
    n = structure.n
    speed = {"J1": 0.3, "J2": -0.07}
    y = np.zeros(engine.n_state)
    column = {}  # each shaft's generalised coordinate
    for shaft, w in speed.items():
        rx, _ = structure.rows(f"{shaft}.flange")
        column[shaft] = int(np.flatnonzero(rx)[0])
        assert rx[column[shaft]] == 1.0 and np.count_nonzero(rx) == 1
        y[n + column[shaft]] = w
    slips = {name: speed["J1"] - speed["J2"] if shaft == "J1-J2" else speed[shaft]
             for name, (shaft, *_) in elements.items()}
    torques = {name: b * slips[name] + k * math.atan(kb * slips[name])
               for name, (_, b, k, kb) in elements.items()}
    load = {"J1": 0.4 - torques["slip"], "J2": torques["slip"]}
    for name, (shaft, *_) in elements.items():
        if shaft != "J1-J2":
            load[shaft] -= torques[name]
    status, dy = engine.derivatives(0.1, y)
    assert status == 0
    layout = plan.layout
    acc = np.concatenate([y, np.zeros(layout.n_acc)])
    status, dy_ledger = engine.derivatives(0.1, acc)
    assert status == 0
    rates = dy_ledger[engine.n_state:][layout.acc_slices()["friction"]]
    for name, rate in zip(elements, rates):
        # a law is a product, an arctangent (within two ulps) and a sum
        assert rate == pytest.approx(torques[name] * slips[name], rel=ULPS * EPS, abs=0)
    for shaft, J in inertia.items():
        i = n + column[shaft]
        # each acceleration sums six torques of size up to 0.4 N m, each within a few ulps
        for derivative in (dy, dy_ledger):
            assert derivative[i] == pytest.approx(load[shaft] / J, rel=0,
                                                  abs=6 * ULPS * EPS * 0.4 / J)

"""Ideal elements conserve power: their torques are the transpose of their kinematic map."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from vsj.components import Differential, IdealGear, IdealPlanetary
from vsj.network import Network, kinematics

#: Power balance holds to round-off; 1e-12 relative to the largest power term.
POWER_TOL = 1e-12

speeds = st.floats(-100, 100, allow_nan=False)
torques = st.floats(-10, 10, allow_nan=False)
teeth = st.integers(8, 200)


@given(n_s=teeth, n_r=teeth, w_r=speeds, w_s=speeds, tau_c=torques)
def test_planetary_conserves_power(n_s, n_r, w_r, w_s, tau_c):
    gear = IdealPlanetary("pg", n_s, n_r)
    w_c = gear.speeds(w_r, w_s)
    tau_r, tau_s = gear.torques(tau_c)
    terms = np.array([tau_c * w_c, tau_r * w_r, tau_s * w_s])
    assert abs(terms.sum()) <= POWER_TOL * max(np.abs(terms).max(), 1.0)


def test_planetary_ratios_follow_eq_3_11():
    gear = IdealPlanetary("pg", 16, 50)
    assert np.isclose(gear.r_RC, 50 / 66) and np.isclose(gear.r_SC, 16 / 66)
    # ring held: the carrier turns r_SC times the sun; sun held: r_RC times the ring
    assert np.isclose(gear.speeds(0.0, 1.0), 16 / 66)
    assert np.isclose(gear.speeds(1.0, 0.0), 50 / 66)


@given(w1=speeds, w2=speeds, tx=torques, ty=torques)
def test_differential_conserves_power(w1, w2, tx, ty):
    out = Differential.speeds([w1, w2])
    t_in = Differential.torques([tx, ty])
    terms = np.array([tx * out[0], ty * out[1], -t_in[0] * w1, -t_in[1] * w2])
    assert abs(terms.sum()) <= POWER_TOL * max(np.abs(terms).max(), 1.0)


def test_differential_follows_eq_3_31():
    assert np.allclose(Differential.speeds([1.0, 1.0]), [1.0, 0.0])
    assert np.allclose(Differential.speeds([1.0, -1.0]), [0.0, 1.0])


@given(ratio=st.floats(0.05, 50), w_b=speeds, tau_a=torques)
def test_gear_conserves_power(ratio, w_b, tau_a):
    gear = IdealGear("g", ratio)
    terms = np.array([tau_a * gear.speeds(w_b), gear.torques(tau_a) * w_b])
    assert abs(terms.sum()) <= POWER_TOL * max(np.abs(terms).max(), 1.0)


@settings(max_examples=30)
@given(n_s=teeth, n_r=teeth, ratio=st.floats(0.1, 10), flows=st.lists(speeds, min_size=3,
                                                                       max_size=3),
       forces=st.lists(torques, min_size=6, max_size=6))
def test_network_of_ideal_elements_conserves_power(n_s, n_r, ratio, flows, forces):
    """Planetary -> gear -> differential, assembled: any constraint forces do no work.

    The network's constraint rows C define the kinematics; flange speeds in
    their null space and torques C^T nu (any nu) balance to round-off.
    """
    net = Network("ideal")
    net.add(IdealPlanetary("pg", n_s, n_r), IdealGear("g", ratio), Differential("d"))
    net.connect("pg.carrier", "g.a").connect("g.b", "d.input_1")
    _, _, C = kinematics(net.parts(), net.connections)
    null = np.linalg.svd(C)[2][np.linalg.matrix_rank(C):].T
    omega = null @ np.resize(np.array(flows), null.shape[1])
    nu = np.resize(np.array(forces), C.shape[0])
    tau = C.T @ nu
    terms = tau * omega
    assert abs(terms.sum()) <= 1e-10 * max(np.abs(terms).max(), 1.0)
    assert np.allclose(C @ omega, 0.0, atol=1e-9 * max(1.0, np.abs(omega).max()))

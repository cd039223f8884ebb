"""Twin test: the assembled wrist, reduced to linear springs and viscous friction,
against a state-space model derived by hand from the same parameters."""

import numpy as np
from scipy.integrate import solve_ivp

from conftest import override
from vsj.inputs import Sine
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist

#: Both sides integrate to rtol 1e-10; 1e-8 rad on deflections of ~0.01 rad.
TWIN_TOL = 1e-8
K = 0.8  # linear spring [N m/rad]
U = (Sine(2.0, 0.7), Sine(-1.5, 1.1, phase=0.0))
TAU = (Sine(0.05, 1.3), Sine(-0.03, 0.4))


def hand_matrices(p):
    """M phi'' + Mu u' = -K phi - D phi' - Du u + G tau, derived by hand.

    Ring speeds w, sun speeds u: carrier w_C = r_RC w + r_SC u; differential
    inputs psi' = w_C / ratio; theta' = J psi' with J = [[1, 1], [1, -1]] / 2.
    Returns the matrices M, Mu, D, Du, G (shared with tests/test_linear.py).
    """
    pg, tr, d, ee = p.planetary, p.transmission, p.differential, p.elastic_element
    r_rc = pg.ring_teeth / (pg.ring_teeth + pg.sun_teeth)
    r_sc = pg.sun_teeth / (pg.ring_teeth + pg.sun_teeth)
    g = 1.0 / tr.ratio
    J = np.array([[0.5, 0.5], [0.5, -0.5]])
    Iee = np.diag([d.inertia_x, d.inertia_y])
    JIJ = J.T @ Iee @ J
    I2 = np.eye(2)
    M = (pg.ring_inertia + pg.carrier_inertia * r_rc ** 2) * I2 + g ** 2 * r_rc ** 2 * JIJ
    Mu = pg.carrier_inertia * r_rc * r_sc * I2 + g ** 2 * r_rc * r_sc * JIJ
    e = np.array([0.5, -0.5])
    b_ring = pg.ring_bearing_viscous + ee.lever_viscous      # on w
    b_carrier = pg.carrier_bearing_viscous + tr.viscous      # on w_C
    D = (b_ring + b_carrier * r_rc ** 2) * I2 + d.viscous * g ** 2 * r_rc ** 2 * np.outer(e, e)
    Du = b_carrier * r_rc * r_sc * I2 + d.viscous * g ** 2 * r_rc * r_sc * np.outer(e, e)
    G = g * r_rc * J.T
    return {"M": M, "Mu": Mu, "D": D, "Du": Du, "G": G}


def hand_model(p):
    """Right-hand side of the hand-derived model (`hand_matrices`) driven by U and TAU."""
    m = hand_matrices(p)
    M, Mu, D, Du, G = m["M"], m["Mu"], m["D"], m["Du"], m["G"]
    Minv = np.linalg.inv(M)

    def rhs(t, y):
        phi, w = y[:2], y[2:]
        u = np.array([s.value(t) for s in U]).ravel()
        du = np.array([2 * np.pi * s.frequency * s.amplitude
                       * np.cos(2 * np.pi * s.frequency * t + s.phase) for s in U])
        tau = np.array([s.value(t) for s in TAU]).ravel()
        acc = Minv @ (-K * phi - D @ w - Du @ u - Mu @ du + G @ tau)
        return np.concatenate([w, acc])

    return rhs


def test_linear_viscous_wrist_matches_hand_derived_model(params):
    p = override(params, elastic_element__lever_viscous="2e-4 N m s/rad",
                 differential__viscous="3e-4 N m s/rad",
                 planetary__sun_bearing_viscous="1e-5 N m s/rad")
    structure = build_wrist(p, WristOptions(elastic="linear", linear_stiffness=K)).assemble()
    inputs = {"motor_1": U[0], "motor_2": U[1], "tau_x": TAU[0], "tau_y": TAU[1]}
    result = simulate(structure, inputs, 3.0, initial=InitialState(q=0.0),
                      options=SimulationOptions(friction="viscous", rtol=1e-11, atol=1e-13,
                                                output_step=0.01), ports=False)
    assert result.success, result.message
    ref = solve_ivp(hand_model(p), (0.0, 3.0), np.zeros(4), method="DOP853", rtol=1e-12,
                    atol=1e-14, t_eval=result.time)
    assert np.max(np.abs(ref.y[0] - result["phi_1"])) < TWIN_TOL
    assert np.max(np.abs(ref.y[1] - result["phi_2"])) < TWIN_TOL
    assert np.max(np.abs(ref.y[2] - result["phi_1.speed"])) < 100 * TWIN_TOL
    # the comparison is not trivial: the deflections are well above the tolerance
    assert np.max(np.abs(result["phi_1"])) > 1e-3

"""Twin test: the assembled wrist, reduced to linear springs and viscous friction,
against a state-space model derived by hand from the same parameters."""

import bisect
import math

import numpy as np
from scipy.integrate import solve_ivp

from conftest import override
from vsj.inputs import Sine, engine_pieces, evaluate_repeating
from vsj.simulate import InitialState, SimulationOptions, simulate
from vsj.wrist import WristOptions, build_wrist

#: vsj's tolerance (its error measured against a run at RTOL / 100) and the reference's
#: (SciPy's DOP853, its error bounded by the difference from a run at REF_RTOL * 100).
RTOL = 1e-11
REF_RTOL = 1e-12
DURATION = 3.0
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


def _spline(pieces):
    """``t -> (value, slope)`` of the engine's pieces of a signal (`engine_pieces`: the
    last period repeated where the signal repeats), in plain floats: the arithmetic of
    `evaluate_repeating`, operation for operation (the test checks that they agree to
    the bit), without NumPy's cost per call, which the reference integrator would pay
    at every stage of every step."""
    knots, coef, period = pieces
    knots, coef = knots.tolist(), coef.tolist()
    first, last = knots[0], knots[-1]

    def at(t):
        inside = first <= t <= last
        if period > 0.0 and t >= last:
            t -= (math.floor((t - last) / period) + 1.0) * period
            t = max(t, last - period)
            inside = first <= t <= last
        k = min(max(bisect.bisect_right(knots, t) - 1, 0), len(coef) - 1)
        tau = min(max(t, first), last) - knots[k]
        c0, c1, c2, c3 = coef[k]
        value = c0 + tau * (c1 + tau * (c2 + tau * c3))
        slope = c1 + tau * (2 * c2 + 3 * c3 * tau)
        return value, (slope if inside else 0.0)

    return at


def hand_model(p):
    """Right-hand side of the hand-derived model (`hand_matrices`) driven by U and TAU.

    vsj samples a sine at 400 points a period and splines it (`vsj.inputs.Sine`): the
    model is driven by the same splines (their values, and their slopes as the sources'
    accelerations), so that what is compared is the mechanics, not the sampling (which
    tests/test_inputs.py checks against SciPy)."""
    m = hand_matrices(p)
    M, Mu, D, Du, G = m["M"], m["Mu"], m["D"], m["Du"], m["G"]
    Minv = np.linalg.inv(M)
    speeds = [_spline(engine_pieces(s, DURATION)) for s in U]
    loads = [_spline(engine_pieces(s, DURATION)) for s in TAU]

    def rhs(t, y):
        phi, w = y[:2], y[2:]
        u, du = np.array([at(t) for at in speeds]).T
        tau = np.array([at(t)[0] for at in loads])
        acc = Minv @ (-K * phi - D @ w - Du @ u - Mu @ du + G @ tau)
        return np.concatenate([w, acc])

    return rhs


def test_the_reference_reads_the_inputs_as_the_engine_does():
    """The hand model's inputs (`_spline`) equal `evaluate_repeating`, the engine's reading
    of its pieces, to the bit: before, at and after the knots, in the repeated periods and
    past the end."""
    for signal in U + TAU:
        pieces = engine_pieces(signal, DURATION)
        knots = pieces[0]
        t = np.concatenate([np.linspace(-0.1, DURATION + 0.1, 2001), knots,
                            np.nextafter(knots, np.inf), np.nextafter(knots, -np.inf)])
        at = _spline(pieces)
        mine = np.array([at(float(x)) for x in t])
        value, slope = evaluate_repeating(*pieces, t)
        assert np.array_equal(mine[:, 0], value) and np.array_equal(mine[:, 1], slope)


def test_linear_viscous_wrist_matches_hand_derived_model(params):
    p = override(params, elastic_element__lever_viscous="2e-4 N m s/rad",
                 differential__viscous="3e-4 N m s/rad",
                 planetary__sun_bearing_viscous="1e-5 N m s/rad")
    structure = build_wrist(p, WristOptions(elastic="linear", linear_stiffness=K)).assemble()
    inputs = {"motor_1": U[0], "motor_2": U[1], "tau_x": TAU[0], "tau_y": TAU[1]}
    result, finer = (simulate(structure, inputs, DURATION, initial=InitialState(q=0.0),
                              options=SimulationOptions(friction="viscous", rtol=rtol,
                                                        atol=rtol / 100, output_step=0.01),
                              ports=False) for rtol in (RTOL, RTOL / 100))
    assert result.success and finer.success, result.message
    ref, coarser = (solve_ivp(hand_model(p), (0.0, DURATION), np.zeros(4), method="DOP853",
                              rtol=rtol, atol=rtol / 100, t_eval=result.time)
                    for rtol in (REF_RTOL, REF_RTOL * 100))
    for k, name in enumerate(("phi_1", "phi_2", "phi_1.speed", "phi_2.speed")):
        # each run within its own global error of the exact solution: vsj's measured
        # against its rerun at rtol / 100; the reference's is below its difference from
        # the run at 100 rtol, whose error is the larger
        errors = (np.max(np.abs(result[name] - finer[name]))
                  + np.max(np.abs(ref.y[k] - coarser.y[k])))
        assert np.max(np.abs(result[name] - ref.y[k])) <= errors, name
    # the comparison is not trivial: the deflections are well above the tolerance
    assert np.max(np.abs(result["phi_1"])) > 1e-3

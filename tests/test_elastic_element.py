"""VSM elastic element: symmetry, continuity, derivatives, slack springs, end stop."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vsj import characteristics as ch
from vsj.springs import EXPONENTIAL, GEOMETRIC, GEOMETRIC_REPORT, LINEAR, evaluate
from vsj.wrist import exponential, geometry

#: Central differences with step 1e-6 rad are accurate to about 1e-9 relative here.
FD_STEP = 1e-6
FD_TOL = 1e-6


@pytest.fixture(scope="module")
def laws(params):
    return {GEOMETRIC: geometry(params), GEOMETRIC_REPORT: geometry(params),
            EXPONENTIAL: exponential(params), LINEAR: (0.5,)}


pivot = st.floats(-0.022, 0.020)
deflection = st.floats(-1.6, 1.6)


@settings(max_examples=200, deadline=None)
@given(law=st.sampled_from([GEOMETRIC, GEOMETRIC_REPORT, EXPONENTIAL, LINEAR]), q=pivot,
       phi=deflection)
def test_torque_is_odd_in_deflection(laws, law, q, phi):
    tau = evaluate(law, laws[law], [phi, -phi], q)[0]
    assert tau[1] == pytest.approx(-tau[0], rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("law", [GEOMETRIC, GEOMETRIC_REPORT, EXPONENTIAL])
@pytest.mark.parametrize("q", [-0.022, -0.004, 0.0, 0.014, 0.020])
def test_finite_and_continuous_at_zero(laws, law, q):
    par = laws[law]
    tau, stiff, energy, _ = evaluate(law, par, [-1e-9, 0.0, 1e-9], q)
    assert np.all(np.isfinite(tau)) and np.all(np.isfinite(stiff))
    if law == EXPONENTIAL:  # -K(q) phi: zero exactly
        assert tau[1] == 0.0
    else:
        # the two springs' torques cancel at zero deflection: round-off (a compiler may
        # contract the two sides' arithmetic differently) leaves a few ulps of either,
        # a spring force k (l - s0) times a lever of at most R + L + W
        R, L, W, k = par[0], par[1], par[2], par[6]
        pull = k * max(max(ch.spring_extensions(par, q, 0.0)), 0.0) * (R + L + W)
        assert abs(tau[1]) <= 8 * np.finfo(float).eps * pull
    # continuity: the torque near zero is the small-deflection stiffness times phi
    assert tau[2] == pytest.approx(-stiff[1] * 1e-9, rel=1e-6)
    assert stiff[0] == pytest.approx(stiff[2], rel=1e-9) and stiff[1] > 0


@settings(max_examples=150, deadline=None)
@given(law=st.sampled_from([GEOMETRIC, GEOMETRIC_REPORT, EXPONENTIAL]), q=pivot,
       phi=st.floats(-1.3, 1.3))
def test_stiffness_matches_finite_difference(laws, law, q, phi):
    par = laws[law]
    tau, stiff, energy, dvq = evaluate(law, par, [phi - FD_STEP, phi, phi + FD_STEP], q)
    slack = [min(ch.spring_extensions(par, q, p)) for p in (phi - FD_STEP, phi + FD_STEP)] \
        if law != EXPONENTIAL else [1.0, 1.0]
    if np.sign(slack[0]) != np.sign(slack[1]):
        return  # a spring goes slack inside the stencil: the stiffness jumps there
    fd = -(tau[2] - tau[0]) / (2 * FD_STEP)
    assert stiff[1] == pytest.approx(fd, rel=FD_TOL, abs=1e-9 * max(1.0, abs(stiff[1])))


@settings(max_examples=150, deadline=None)
@given(law=st.sampled_from([GEOMETRIC, EXPONENTIAL]), q=st.floats(-0.021, 0.019),
       phi=st.floats(-1.3, 1.3))
def test_potential_models_are_gradients_of_their_energy(laws, law, q, phi):
    par = laws[law]
    energy = evaluate(law, par, [phi - FD_STEP, phi + FD_STEP], q)[2]
    tau, _, _, dvq = evaluate(law, par, [phi], q)
    assert tau[0] == pytest.approx(-(energy[1] - energy[0]) / (2 * FD_STEP), rel=FD_TOL,
                                   abs=1e-10)
    # q in m: a 0.1 um step; the pretension energy (~1e-2 J) sets a round-off floor of ~1e-8 N
    dq = 1e-7
    e_q = [evaluate(law, par, [phi], q + d)[2][0] for d in (-dq, dq)]
    assert dvq[0] == pytest.approx((e_q[1] - e_q[0]) / (2 * dq), rel=1e-5, abs=1e-6)


def test_report_form_agrees_with_potential_at_q_zero_only(laws):
    par = laws[GEOMETRIC]
    for phi in (0.05, 0.4, 1.0):
        assert abs(ch.eq38_mismatch(par, 0.0, phi)) < 1e-9
    assert max(abs(ch.eq38_mismatch(par, q, 1.0)) for q in (-0.015, 0.015)) > 1e-3


def test_slack_spring_carries_no_force(laws):
    """Beyond the pretension loss the slack spring stays out: the torque equals the
    other spring's alone, with no jump in torque but a drop in stiffness."""
    par = np.array(laws[GEOMETRIC])
    q = -0.004
    loss = ch.pretension_loss(par, q)
    assert 0.0 < loss < 1.4
    before, after = loss - 1e-4, loss + 1e-4
    ext_b, ext_a = ch.spring_extensions(par, q, before), ch.spring_extensions(par, q, after)
    assert min(ext_b) > 0 and min(ext_a) < 0
    tau, stiff, _, _ = evaluate(GEOMETRIC, par, [before, after], q)
    assert tau[1] == pytest.approx(tau[0], rel=1e-2)
    assert stiff[1] < stiff[0]


@pytest.mark.parametrize("law", [GEOMETRIC, GEOMETRIC_REPORT, EXPONENTIAL])
def test_end_stop_holds_at_1_40_rad(laws, law):
    par = laws[law]
    tau_in, k_in, _, _ = evaluate(law, par, [1.39], 0.0)
    tau_out, k_out, _, _ = evaluate(law, par, [1.45], 0.0)
    assert k_out[0] - k_in[0] > 40.0  # the stop's 50 N m/rad adds on
    # under a load far beyond the springs' torque the deflection stays near the stop
    phi = np.linspace(1.3, 1.6, 3001)
    tau = -evaluate(law, par, phi, 0.0)[0]
    held = phi[np.argmax(tau >= 2.0)]
    assert 1.40 < held < 1.45

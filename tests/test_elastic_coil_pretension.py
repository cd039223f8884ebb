"""Coil pretension of the elastic element's springs (issue 21, item 8).

An extension spring with initial tension F_i pulls with F_i + k (l - s0) while longer
than its free length s0 and not at all below: the ring torque jumps by F_i |dl/dphi|
where a spring goes slack. Checked against the potential it derives from, by symmetry,
and by the size of the jump; and the engine, which has no such term, refuses to
simulate it.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vsj import characteristics as ch
from vsj.components import ElasticElement
from vsj.springs import GEOMETRIC, GEOMETRY_FIELDS, coil_pretension, evaluate, extensions
from vsj.wrist import geometry

#: Central-difference step [rad] for dV/dphi, and the agreement it allows: the error is
#: about h^2/6 |V'''| (below 1e-9 N m here) plus round-off eps |V| / h (about 1e-10).
H = 1e-5
DERIVATIVE = 1e-7


def _element(params, tension):
    return ElasticElement("vsm", model="geometric", geometry=geometry(params),
                          initial_tension=tension)


def _slack_angle(par, q):
    return ch.pretension_loss(par, q, limit=1.4)


def test_no_tension_adds_nothing(params):
    par = geometry(params)
    phis = np.linspace(-1.0, 1.0, 21)
    torque, energy = coil_pretension(phis, -0.004, par, 0.0)
    assert not torque.any() and not energy.any()
    assert np.array_equal(_element(params, 0.0).torque(phis, -0.004),
                          evaluate(GEOMETRIC, par, phis, -0.004)[0])


@settings(max_examples=25, deadline=None)
@given(phi=st.floats(-1.2, 1.2), q=st.floats(-0.02, 0.018), tension=st.floats(0.05, 2.0))
def test_torque_is_minus_the_derivative_of_the_potential(params, phi, q, tension):
    par = geometry(params)
    slack = _slack_angle(par, q)
    if np.isfinite(slack) and min(abs(abs(phi) - slack), abs(phi)) < 10 * H:
        return  # the jump itself, or too close to it for a central difference
    for other in (-phi, phi):
        ext = np.array(extensions(other, q, par))
        if np.any(np.abs(ext) < 1e-6):
            return

    def potential(angle):
        return (evaluate(GEOMETRIC, par, angle, q)[2][0]
                + coil_pretension(angle, q, par, tension)[1][0])

    torque = _element(params, tension).torque(phi, q)[0]
    assert torque == pytest.approx(-(potential(phi + H) - potential(phi - H)) / (2 * H),
                                   abs=DERIVATIVE)


@settings(max_examples=25, deadline=None)
@given(phi=st.floats(0.0, 1.3), q=st.floats(-0.02, 0.018), tension=st.floats(0.0, 2.0))
def test_torque_is_odd_in_the_deflection(params, phi, q, tension):
    element = _element(params, tension)
    assert element.torque(-phi, q)[0] == pytest.approx(-element.torque(phi, q)[0], abs=1e-12)


@pytest.mark.parametrize("q", [0.002, -0.004, -0.010])
def test_the_torque_jumps_by_f_i_times_the_length_rate_where_a_spring_goes_slack(params, q):
    par = geometry(params)
    tension = 0.4
    slack = _slack_angle(par, q)
    assert np.isfinite(slack)
    eps = 1e-7
    element = _element(params, tension)
    before, after = element.torque([slack - eps, slack + eps], q)
    h = 1e-6
    rates = [(extensions(slack + h, q, par)[k] - extensions(slack - h, q, par)[k]) / (2 * h)
             for k in (0, 1)]
    going_slack = int(np.argmin(np.abs(extensions(slack, q, par))))
    assert abs(after - before) == pytest.approx(tension * abs(rates[going_slack]), rel=1e-3)
    # without coil pretension the same point is only a kink: across 2 eps the torque
    # moves by about K 2 eps (1e-7 N m), four orders of magnitude below the jump
    plain = _element(params, 0.0).torque([slack - eps, slack + eps], q)
    assert abs(plain[1] - plain[0]) < 1e-3 * abs(after - before)


def test_the_engine_refuses_what_it_cannot_simulate(params):
    with pytest.raises(ValueError, match="cannot be simulated"):
        _element(params, 0.3).parts()
    with pytest.raises(ValueError, match="geometric"):
        ElasticElement("vsm", model="exponential", exponential=(0.2, -145.0, 0.02, 1.4, 50.0),
                       initial_tension=0.3)
    with pytest.raises(ValueError, match="initial_tension"):
        _element(params, -0.1)


def test_part_of_the_preload_as_coil_pretension_keeps_the_curve_until_the_free_length(params):
    """The fig 3.7 variant: free length raised by F_i / k, so while both springs are taut
    the force F_i + k (l - s0') is the calibrated k (l - s0)."""
    from vsj.reproduce.model_figures import _coil_curve, _with_coil_pretension

    par = geometry(params)
    row, tension = _with_coil_pretension(par, 0.5)
    k = par[GEOMETRY_FIELDS.index("spring_stiffness")]
    s = GEOMETRY_FIELDS.index("rest_length")
    assert row[s] - par[s] == pytest.approx(tension / k, rel=1e-12)
    q = -0.004
    slack = _slack_angle(row, q)
    phis = np.linspace(0.0, 0.95 * slack, 20)
    # the central difference of the lengths (LENGTH_STEP 1e-6 rad) leaves round-off of
    # about eps l / h = 1e-11 m/rad in dl/dphi, times F_i below 1 N
    assert np.allclose(_coil_curve(row, tension, q, phis),
                       ch.torque_curve(GEOMETRIC, par, q, phis), rtol=0, atol=1e-10)

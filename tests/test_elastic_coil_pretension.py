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
from vsj.springs import (GEOMETRIC, GEOMETRY_FIELDS, LENGTH_STEP, coil_pretension, evaluate,
                         extensions)
from vsj.wrist import geometry

#: Central-difference step [rad] for dV/dphi (its error is estimated in the test).
H = 1e-5
EPS = np.finfo(float).eps
#: Rounding of one evaluation of a spring's length, energy or force-times-slope: a few
#: ulp of the largest term (a square root and a handful of products and sums).
ULPS = 8


def torque_roundoff(par, phi, q, tension):
    """Round-off [N m] of the element's torque at ``phi``: a few ulp of each spring's
    force times its length's slope, and, for the coil part, the slope as a central
    difference over LENGTH_STEP of lengths rounded to a few ulp (ULPS eps l / LENGTH_STEP
    per spring, times the tension; its truncation is below 1e-13 m/rad, vsj.springs)."""
    k = par[GEOMETRY_FIELDS.index("spring_stiffness")]
    free = par[GEOMETRY_FIELDS.index("rest_length")]
    ext = np.abs(np.array(extensions(phi, q, par)))
    slope = np.abs(np.array(extensions(phi + LENGTH_STEP, q, par))
                   - np.array(extensions(phi - LENGTH_STEP, q, par))) / (2 * LENGTH_STEP)
    forces = ULPS * EPS * np.sum((k * ext + tension) * slope)
    return forces + tension * np.sum(ULPS * EPS * (free + ext) / LENGTH_STEP)


def energy_roundoff(par, phi, q, tension):
    """Round-off [J] of the potential at ``phi``: each spring's extension l - s0 is rounded
    to a few ulp of its length l, which moves its energy by its force times that."""
    k = par[GEOMETRY_FIELDS.index("spring_stiffness")]
    free = par[GEOMETRY_FIELDS.index("rest_length")]
    ext = np.abs(np.array(extensions(phi, q, par)))
    return ULPS * EPS * np.sum((k * ext + tension) * (free + ext))


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
    central = -(potential(phi + H) - potential(phi - H)) / (2 * H)
    wider = -(potential(phi + 2 * H) - potential(phi - 2 * H)) / (4 * H)
    # Richardson: the central difference misses H^2/6 times V's third derivative, four
    # times that at 2H; the extrapolation removes it, and the term removed, (wider -
    # central) / 3, bounds what is left (of order H^4)
    derivative = (4 * central - wider) / 3
    truncation = abs(wider - central) / 3
    # V rounded at each end: over 2H at weight 4/3, over 4H at 1/3
    cancellation = 1.5 * energy_roundoff(par, phi, q, tension) / H
    tol = truncation + cancellation + torque_roundoff(par, phi, q, tension)
    assert abs(torque - derivative) <= tol


@settings(max_examples=25, deadline=None)
@given(phi=st.floats(0.0, 1.3), q=st.floats(-0.02, 0.018), tension=st.floats(0.0, 2.0))
def test_torque_is_odd_in_the_deflection(params, phi, q, tension):
    element = _element(params, tension)
    # mirrored, the springs swap: the same operations on negated values, which round alike
    # unless a compiler contracts the two springs' expressions differently
    tol = 2 * torque_roundoff(geometry(params), phi, q, tension)
    assert abs(element.torque(-phi, q)[0] + element.torque(phi, q)[0]) <= tol


@pytest.mark.parametrize("q", [0.002, -0.004, -0.010])
def test_the_torque_jumps_by_f_i_times_the_length_rate_where_a_spring_goes_slack(params, q):
    par = geometry(params)
    tension = 0.4
    slack = _slack_angle(par, q)
    assert np.isfinite(slack)
    eps = 1e-7  # a hundred times the slack angle's root tolerance (brentq's xtol, 1e-9)
    element = _element(params, tension)
    before, after = element.torque([slack - eps, slack + eps], q)
    h = LENGTH_STEP

    def rates(angle):
        return np.array([(extensions(angle + h, q, par)[k]
                          - extensions(angle - h, q, par)[k]) / (2 * h) for k in (0, 1)])

    going_slack = int(np.argmin(np.abs(extensions(slack, q, par))))
    plain = _element(params, 0.0).torque([slack - eps, slack + eps], q)
    # besides the jump, across 2 eps the torque moves as it does without coil pretension
    # (plain), and the pretension term by F_i times its slope's change; each torque and
    # the slope here carry their round-off
    moved = abs(plain[1] - plain[0]) + tension * np.sum(np.abs(rates(slack + eps)
                                                               - rates(slack - eps)))
    roundoff = sum(torque_roundoff(par, a, q, tension) + torque_roundoff(par, a, q, 0.0)
                   for a in (slack - eps, slack + eps))
    length = np.max(np.abs(extensions(slack, q, par))) + par[GEOMETRY_FIELDS.index("rest_length")]
    jump = tension * abs(rates(slack)[going_slack])
    assert abs(abs(after - before) - jump) <= moved + roundoff + tension * ULPS * EPS * length / h
    # without coil pretension the same point is only a kink: across 2 eps the torque
    # moves by at most eps times the stiffness on either side, far below the jump
    stiffness = evaluate(GEOMETRIC, par, [slack - eps, slack + eps], q)[1]
    kink = eps * np.sum(np.abs(stiffness)) + sum(torque_roundoff(par, a, q, 0.0)
                                                 for a in (slack - eps, slack + eps))
    assert abs(plain[1] - plain[0]) <= kink < abs(after - before)


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
    # the free length raised by F_i / k in one rounded sum: exact to an ulp of the length
    assert abs((row[s] - par[s]) - tension / k) <= np.spacing(row[s])
    q = -0.004
    slack = _slack_angle(row, q)
    phis = np.linspace(0.0, 0.95 * slack, 20)
    # the two curves round differently: each torque its own way (torque_roundoff), and the
    # raised free length by an ulp, which moves each spring's force by k times that
    tol = np.array([torque_roundoff(row, a, q, tension) + torque_roundoff(par, a, q, 0.0)
                    for a in phis]) + 2 * k * np.spacing(row[s])
    assert np.all(np.abs(_coil_curve(row, tension, q, phis)
                         - ch.torque_curve(GEOMETRIC, par, q, phis)) <= tol)

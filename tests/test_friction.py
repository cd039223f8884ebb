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

"""Friction laws: all dissipate, all are odd, and each has its documented shape."""

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from vsj import friction

laws = st.sampled_from(sorted(friction.LAWS))
speed = st.floats(-50, 50, allow_nan=False)
positive = st.floats(0, 1, allow_nan=False)


@given(law=laws, s=speed, b=positive, k=positive, kb=st.floats(0.1, 100), w=st.floats(1e-4, 1))
def test_every_law_dissipates_and_is_odd(law, s, b, k, kb, w):
    f = friction.torque(law, [s, -s], viscous=b, stiction=k, sharpness=kb, width=w)
    assert f[0] * s >= 0.0
    assert f[1] == pytest.approx(-f[0], abs=1e-15)


@given(law=st.sampled_from(["arctan", "sign", "slope", "stiction"]), k=st.floats(1e-4, 1))
def test_every_coulomb_law_saturates_at_k_pi_over_2(law, k):
    f = friction.torque(law, [1e6], stiction=k, sharpness=10.0, width=1e-3)[0]
    assert f == pytest.approx(k * math.pi / 2, rel=1e-5)


def test_slope_law_is_linear_inside_its_band():
    k, w = 0.01, 0.02
    s = np.linspace(-w, w, 9)
    f = friction.torque("slope", s, stiction=k, width=w)
    assert np.allclose(f, k * math.pi / 2 * s / w)


def test_viscous_law_drops_the_coulomb_part():
    assert friction.torque("viscous", [2.0], viscous=0.1, stiction=5.0)[0] == pytest.approx(0.2)


def test_unknown_law_is_named():
    with pytest.raises(ValueError, match="unknown friction law 'coulomb'"):
        friction.law_code("coulomb")

"""The input splines: vsj's not-a-knot spline is SciPy's CubicSpline (to rounding),
reproduces cubics exactly, is twice continuously differentiable, and a run with sampled
inputs does not import scipy.interpolate (whose import costs more than the run)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from vsj.inputs import Table, evaluate, spline_pieces


def _grid(n: int, seed: int):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.uniform(0.05, 2.0, n)), rng.normal(size=n)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6, 20, 500])
def test_the_spline_is_scipys_cubic_spline(n):
    t, y = _grid(n, n)
    knots, coef = spline_pieces(t, y)
    reference = CubicSpline(t, y)  # not-a-knot ends, SciPy's default
    assert np.array_equal(knots, t)
    scale = np.max(np.abs(reference.c))
    assert np.max(np.abs(coef - reference.c[::-1].T)) <= 1e-13 * scale
    inside = np.linspace(t[0], t[-1], 1001)
    assert np.max(np.abs(evaluate((knots, coef), inside) - reference(inside))) <= 1e-12 * scale


def test_a_cubic_is_reproduced_exactly():
    t, _ = _grid(9, 1)
    cubic = np.polynomial.Polynomial([0.3, -1.2, 0.7, 0.25])
    knots, coef = spline_pieces(t, cubic(t))
    inside = np.linspace(t[0], t[-1], 333)
    assert np.max(np.abs(evaluate((knots, coef), inside) - cubic(inside))) <= 1e-11
    assert np.allclose(coef[:, 3], 0.25, rtol=1e-9)


def test_value_slope_and_curvature_are_continuous_at_inner_knots():
    t, y = _grid(40, 7)
    knots, c = spline_pieces(t, y)
    h = np.diff(knots)[:-1]
    left = [c[:-1, 0] + h * (c[:-1, 1] + h * (c[:-1, 2] + h * c[:-1, 3])),
            c[:-1, 1] + h * (2 * c[:-1, 2] + 3 * h * c[:-1, 3]),
            2 * c[:-1, 2] + 6 * h * c[:-1, 3]]
    right = [c[1:, 0], c[1:, 1], 2 * c[1:, 2]]
    for a, b in zip(left, right):
        assert np.max(np.abs(a - b)) <= 1e-9 * np.max(np.abs(b))


def test_a_cubic_table_holds_its_end_values_outside():
    t, y = _grid(6, 3)
    table = Table(tuple(t), tuple(y), "cubic")
    inside = np.linspace(t[0], t[-1], 50)
    assert np.allclose(table.value(inside), CubicSpline(t, y)(inside), rtol=0, atol=1e-12)
    assert table.value(np.array([t[0] - 5.0, t[-1] + 5.0])) == pytest.approx([y[0], y[-1]],
                                                                              abs=1e-12)


def test_a_run_with_sampled_inputs_does_not_import_scipy_interpolate():
    script = ("import sys\n"
              "from vsj import params, scenario\n"
              "s = scenario.load('fig-4.15')\n"
              "result = scenario.prepare_case(s, s.cases[0], params.default()).run(duration=0.5)\n"
              "assert result.success\n"
              "print('scipy.interpolate' in sys.modules)\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "False"

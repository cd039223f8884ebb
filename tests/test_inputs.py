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


EPS = np.finfo(float).eps
#: Rounding of a handful of operations (a slope, a Horner sum of four terms): half an
#: ulp each.
ULPS = 8


def _grid(n: int, seed: int):
    rng = np.random.default_rng(seed)
    return np.cumsum(rng.uniform(0.05, 2.0, n)), rng.normal(size=n)


def slope_condition(t) -> float:
    """Condition number of the linear system whose solution is a not-a-knot spline's
    slopes at the knots ``t`` (continuous second derivative inside, continuous third
    derivative across the first and last inner knots; de Boor, A Practical Guide to
    Splines, ch. IV): the slopes, and so the coefficients, carry rounding of that many
    ulp of their size. 1 for two or three knots (a closed form)."""
    n = len(t)
    if n < 4:
        return 1.0
    h = np.diff(t)
    a = np.zeros((n, n))
    for i in range(1, n - 1):
        a[i, i - 1:i + 2] = h[i], 2 * (h[i - 1] + h[i]), h[i - 1]
    a[0, :2] = h[1], h[0] + h[1]
    a[-1, -2:] = h[-1] + h[-2], h[-2]
    return float(np.linalg.cond(a))


def piece_sizes(knots, coef):
    """Largest term of each piece's Horner sum over its interval, sum_k |c_k| h^k."""
    h = np.diff(knots)[:, None] ** np.arange(4)
    return np.sum(np.abs(coef) * h, axis=1)


@pytest.mark.parametrize("n", [2, 3, 4, 5, 6, 20, 500])
def test_the_spline_is_scipys_cubic_spline(n):
    t, y = _grid(n, n)
    knots, coef = spline_pieces(t, y)
    reference = CubicSpline(t, y)  # not-a-knot ends, SciPy's default
    assert np.array_equal(knots, t)
    # two solutions of the same system, each to its condition number times a few ulp
    # (each coefficient weighed by what it adds over its piece, c_k h^k)
    rounding = ULPS * EPS * slope_condition(t)
    sizes = piece_sizes(knots, coef)
    reach = np.diff(knots)[:, None] ** np.arange(4)
    assert np.all(np.abs(coef - reference.c[::-1].T) * reach <= rounding * sizes[:, None])
    # and each evaluation a Horner sum of such coefficients
    inside = np.linspace(t[0], t[-1], 1001)
    assert np.max(np.abs(evaluate((knots, coef), inside) - reference(inside))) \
        <= 2 * rounding * sizes.max()


def test_a_cubic_is_reproduced_exactly():
    t, _ = _grid(9, 1)
    cubic = np.polynomial.Polynomial([0.3, -1.2, 0.7, 0.25])
    knots, coef = spline_pieces(t, cubic(t))
    inside = np.linspace(t[0], t[-1], 333)
    rounding = ULPS * EPS * slope_condition(t)
    assert np.max(np.abs(evaluate((knots, coef), inside) - cubic(inside))) \
        <= rounding * piece_sizes(knots, coef).max()
    # the leading coefficient is (m_i + m_i+1 - 2 secant) / h^2: the slopes' rounding
    # over h^2, after a cancellation of terms as large as the slopes
    h = np.diff(knots)
    slopes = np.abs(coef[:, 1]) + np.abs(coef[:, 1] + h * (2 * coef[:, 2] + 3 * h * coef[:, 3]))
    secants = np.abs(np.diff(cubic(t))) / h
    assert np.all(np.abs(coef[:, 3] - 0.25) <= rounding * (slopes + 2 * secants) / h ** 2)


def test_value_slope_and_curvature_are_continuous_at_inner_knots():
    t, y = _grid(40, 7)
    knots, c = spline_pieces(t, y)
    h = np.diff(knots)[:-1]
    left = [c[:-1, 0] + h * (c[:-1, 1] + h * (c[:-1, 2] + h * c[:-1, 3])),
            c[:-1, 1] + h * (2 * c[:-1, 2] + 3 * h * c[:-1, 3]),
            2 * c[:-1, 2] + 6 * h * c[:-1, 3]]
    right = [c[1:, 0], c[1:, 1], 2 * c[1:, 2]]
    # in exact arithmetic equal (the slopes solve the continuity conditions); here each
    # side's terms rounded as the slopes are, and as the Horner sums are
    rounding = ULPS * EPS * slope_condition(t)
    terms = [np.abs(c[:-1, 0]) + h * (np.abs(c[:-1, 1]) + h * (np.abs(c[:-1, 2])
                                                            + h * np.abs(c[:-1, 3]))),
             np.abs(c[:-1, 1]) + h * (2 * np.abs(c[:-1, 2]) + 3 * h * np.abs(c[:-1, 3])),
             2 * np.abs(c[:-1, 2]) + 6 * h * np.abs(c[:-1, 3])]
    for a, b, size in zip(left, right, terms):
        assert np.all(np.abs(a - b) <= rounding * (size + np.abs(b)))


def test_a_cubic_table_holds_its_end_values_outside():
    t, y = _grid(6, 3)
    table = Table(tuple(t), tuple(y), "cubic")
    inside = np.linspace(t[0], t[-1], 50)
    knots, coef = spline_pieces(t, y)
    sizes = piece_sizes(knots, coef)
    rounding = ULPS * EPS * slope_condition(t)
    assert np.allclose(table.value(inside), CubicSpline(t, y)(inside), rtol=0,
                       atol=2 * rounding * sizes.max())
    # outside: the first value as it is, the last as the last piece's Horner sum ends
    assert table.value(np.array([t[0] - 5.0])) == y[0]
    assert abs(table.value(np.array([t[-1] + 5.0]))[0] - y[-1]) <= rounding * sizes[-1]


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


@pytest.mark.parametrize("seed", range(5))
def test_the_tridiagonal_solver_pivots(seed):
    """The engine's tridiagonal solve (behind the splines' slopes) against a dense solve,
    on systems whose sub-diagonal entries are larger than the diagonal ones, where
    elimination without row exchanges loses every digit: the error stays within the
    condition number times a few ulp."""
    from vsj import _core

    rng = np.random.default_rng(seed)
    n = 40
    lower, diagonal, upper = rng.normal(size=n - 1), 1e-9 * rng.normal(size=n), \
        rng.normal(size=n - 1)
    a = np.diag(diagonal) + np.diag(lower, -1) + np.diag(upper, 1)
    x = rng.normal(size=n)
    b = a @ x
    solved = b.copy()
    assert _core.solve_tridiagonal(lower.copy(), diagonal.copy(), upper.copy(), solved) == 0
    # backward stable: |x - x*| <= cond(A) * (a few ulp) * |x|, the few ulp for the
    # n-step elimination and the product a @ x
    bound = np.linalg.cond(a) * 16 * n * EPS * np.max(np.abs(x))
    assert np.max(np.abs(solved - x)) <= bound


def test_a_singular_tridiagonal_system_is_reported():
    from vsj import _core

    zeros = np.zeros(2)
    assert _core.solve_tridiagonal(zeros.copy(), np.zeros(3), zeros.copy(), np.ones(3)) == -1
    with pytest.raises(ValueError, match="lower and upper"):
        _core.solve_tridiagonal(np.zeros(3), np.ones(3), np.zeros(2), np.ones(3))


@pytest.mark.parametrize("table", [
    Table((-1.0, 1.0), (1.0, 1.0)),                      # starts before the run
    Table((0.3, 1.0), (1.0, 2.0)),                       # starts after it: 1 held until 0.3
    Table((-2.0, -1.0), (3.0, 1.0)),                     # over before it: 1 held
    Table((-1.0, 0.2, 0.4, 0.7), (0.0, 1.0, 3.0, -1.0), "cubic"),  # a piece across 0
], ids=["before", "after", "over", "cubic-across-0"])
def test_a_velocity_source_angle_is_its_tables_integral_from_the_start(table):
    """A source driven by a table starts at angle 0, wherever the table's first time lies,
    and its angle is the table's integral from t = 0 (outside the table its end values
    held): the engine integrates from its pieces' first knot, which is put at 0."""
    from scipy.integrate import quad

    from vsj import build_wrist, params, simulate

    wrist = build_wrist(params.default()).assemble()
    result = simulate(wrist, {"motor_1": table}, 0.5)
    assert result.success
    t = result.time[::50]
    integral = np.array([quad(lambda s: float(table.value(np.array([s]))[0]), 0.0, end,
                              points=[k for k in table.times if 0.0 < k < end] or None,
                              epsabs=1e-13, epsrel=1e-13)[0] for end in t])
    assert result["motor_1"][0] == 0.0
    # the engine's integral is the pieces' closed form: its rounding, a few ulp of the
    # angle (quad's own error is below 1e-13 at these tolerances)
    assert np.max(np.abs(result["motor_1"][::50] - integral)) <= 1e-12


@pytest.mark.parametrize("kind", ["table", "hold"])
def test_a_signal_keeps_the_samples_it_validated(kind):
    """Arrays given to a Table or Hold are copied: changing them afterwards (a NaN put in)
    does not reach the signal, which compares and hashes as a value."""
    from vsj.inputs import Hold

    make = Table if kind == "table" else Hold
    times, values = np.array([0.0, 1.0, 2.0]), np.array([1.0, 2.0, 3.0])
    signal = make(times, values)
    times[1], values[0] = 5.0, np.nan
    assert signal.times == (0.0, 1.0, 2.0) and signal.values == (1.0, 2.0, 3.0)
    assert signal == make([0.0, 1.0, 2.0], [1.0, 2.0, 3.0])
    assert hash(signal) == hash(make((0.0, 1.0, 2.0), (1.0, 2.0, 3.0)))

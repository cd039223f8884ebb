"""The energy ledger closes: work done = stored change + dissipation."""

import pytest

from vsj import scenario as scenarios

#: Round-off of the ledger per solver step: each booked term is a product of a few
#: doubles, rounded to about 1e-16 each; ten of them per step and term (as in
#: tests/test_regression.py).
LEDGER_ROUNDOFF_PER_STEP = 1e-15


def test_ledger_closes_on_fig_4_15_with_smooth_friction(params):
    scen = scenarios.load("fig-4.15")
    for run in scenarios.run(scen, params, ports=False):
        assert run.case.options.friction == "arctan"
        result = run.result
        assert result.success, result.message
        led = result.ledger
        # every term is integrated by the same error-controlled steps as the state (as
        # tests/test_regression.py checks): to the run's rtol, plus round-off per step
        rtol = result.solver["options"]["rtol"]
        tol = rtol + result.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP
        assert led["relative_residual"] <= tol, run.case.label
        assert led["total_in"] > 0.1  # the motors do real work against friction
        # every friction element dissipates: f(s) s >= 0 at every instant, so its
        # integral can fall below zero only by the integration's error
        assert all(v >= -rtol * led["total_in"] for v in led["dissipated"].values())
        # the balance is made of independently accumulated terms, not a residual
        assert led["total_dissipated"] == pytest.approx(
            led["total_in"] - led["total_stored"], rel=tol, abs=0.0)

"""The report figures' numbers (`vsj.reproduce`, `Figure.data`), as the session's
reproduction wrote them (``fig-X.Y.npz``, read back by `Figure.load`), checked against
the model computed independently here: things a figure that draws the wrong arrays, or
computes them in the drawing, gets wrong. And that computing a figure needs no
Matplotlib.
"""

from __future__ import annotations

import ast
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vsj.reproduce.data_figures import MEASURED_K

#: The modules that compute the figures, and what they must never import: Matplotlib,
#: and the modules that draw (reached only through `vsj.reproduce.base.Drawing`).
COMPUTING = ("base", "model_figures", "data_figures")
DRAWING = ("matplotlib", "vsj.plots", "vsj.reproduce.draw_model", "vsj.reproduce.draw_data")


@pytest.fixture(scope="module")
def computed(reproduced_figures):
    return {"data": {name: fig.data for name, fig in reproduced_figures.items()},
            "rows": {name: len(fig.rows) for name, fig in reproduced_figures.items()}}


def test_every_figures_numbers_are_written(computed):
    from vsj.reproduce import figures

    assert set(computed["data"]) == set(figures())
    for name, data in computed["data"].items():
        assert data, name
        assert computed["rows"][name] > 0, name


def _imported(path: Path) -> set[str]:
    """Every module an ``import`` anywhere in ``path`` names (relative ones resolved
    within vsj.reproduce), with the packages above it."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = (["vsj", "reproduce"][:3 - node.level] if node.level else []) \
                + (node.module.split(".") if node.module else [])
            names |= {".".join(base + [alias.name]) for alias in node.names}
            names.add(".".join(base))
    return {".".join(n.split(".")[:k + 1]) for n in names for k in range(n.count(".") + 1)}


def test_computing_a_figure_imports_no_matplotlib(tmp_path):
    """The modules that compute the figures import nothing that draws, at their top or
    in a function, and importing them with `vsj.reproduce` (which imports `vsj.plots`
    to save what is drawn, and `vsj.plots` Matplotlib only when it draws) loads neither
    Matplotlib nor a drawing module; a module that did is found."""
    import vsj.reproduce

    folder = Path(vsj.reproduce.__file__).parent
    for name in COMPUTING:
        assert not _imported(folder / f"{name}.py") & set(DRAWING), name
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from .draw_model import fig_3_5\n")
    assert _imported(bad) & set(DRAWING) == {"vsj.reproduce.draw_model"}
    code = ("import sys; import vsj.reproduce; "
            + "; ".join(f"import vsj.reproduce.{name}" for name in COMPUTING)
            + "; print(sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib'"
            " or m in ('vsj.reproduce.draw_model', 'vsj.reproduce.draw_data')))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def _array(value) -> np.ndarray:
    return np.asarray(value, dtype=float)


def test_fig_3_5_deflection_reaches_the_end_stop_where_the_load_is_not_held(computed, params):
    """Under 1 N m the deflection is the end stop exactly where the element's largest torque
    before the stop is below 1 N m, and the linear spring of eq 4.5 deflects 1 N m / K(q)."""
    data = computed["data"]["fig-3.5"]
    stop, load, q = data["end_stop"], data["load"], _array(data["q"])
    assert stop == pytest.approx(params.elastic_element.end_stop)
    assert q[-1] == 0.0 and q[0] == pytest.approx(params.pivot.q_min)
    models = {m["law"]: m for m in data["models"]}
    assert set(models) == {"geometric", "geometric-report", "exponential"}
    for law, model in models.items():
        phi, largest = _array(model["deflection"]), _array(model["largest_torque"])
        assert phi.shape == largest.shape == q.shape
        held = largest >= load
        assert np.all(phi[~held] == stop), law
        assert np.all(phi[held] < stop), law
    # the calibrated potential model is too compliant to hold 1 N m at q = 0 (fig 3.5 row)
    geometric = _array(models["geometric"]["deflection"])
    assert geometric[0] < stop and geometric[-1] == stop
    e = params.elastic_element
    phi = _array(models["exponential"]["deflection"])
    held = phi < stop
    assert held.any() and not held.all()
    K = e.a1 * np.exp(e.a2 * q[held]) + e.a3
    # deflection_under's root finding puts each within XTOL (plus 4 ulp) of load / K
    from vsj.characteristics import XTOL

    assert np.all(np.abs(phi[held] - load / K) <= XTOL + 4 * np.spacing(load / K))


def test_fig_4_15_softer_settings_lag_more(computed):
    data = computed["data"]["fig-4.15"]
    laws = data["laws"]
    assert [law["law"] for law in laws] == ["stiction", "arctan"]
    for law in laws:
        q, lag = _array(law["q"]), _array(law["lag"])
        assert len(q) == 5 and np.all(np.diff(q) > 0)
        assert np.all(lag > 0) and np.all(np.diff(lag) > 0), law["law"]
        assert np.allclose(lag, 0.5 * (_array(law["lag_x"]) + _array(law["lag_y"])))
        # the traces drawn are the runs at the same settings, under this law
        assert [t["q"] for t in law["traces"]] == list(law["q"])
        for trace in law["traces"]:
            deflection = max(np.max(np.abs(_array(trace[k]))) for k in ("phi_1", "phi_2"))
            assert 0 < deflection < 1.4  # within the end stop
    # the rigid-spring path is what the motors command: the same circle as the end-effector
    rigid = data["rigid"]
    assert np.max(np.abs(_array(rigid["theta_x"]))) == pytest.approx(
        np.max(np.abs(_array(laws[0]["traces"][0]["theta_x"]))), rel=0.2)


def test_fig_4_15_shows_the_run_the_command_line_makes(computed, params):
    """Issue 30: `vsj simulate fig-4.15` runs the built-in scenario's arctan law; the page
    shows that run, named as such, beside true stiction."""
    from vsj import scenario as scenarios

    data = computed["data"]["fig-4.15"]
    scen = scenarios.load("fig-4.15")
    law = scen.table["solver"]["friction"]
    assert data["scenario_law"] == law
    shown = {entry["law"]: entry for entry in data["laws"]}
    assert set(shown) == {"stiction", law}
    for name, entry in shown.items():
        assert entry["label"].startswith(name)
        assert ("`vsj simulate fig-4.15`" in entry["label"]) == (name == law)
    # the stiffest setting, run as the command line runs it, over the page's duration
    trace = shown[law]["traces"][0]
    t = _array(trace["time"])
    result = scenarios.prepare_case(scen, scen.cases[0], params).run(duration=t[-1],
                                                                      ports=False)
    assert result.success and np.array_equal(result.time, t)
    # the same run in another process: identical up to the adaptive solver's tolerance
    # (the default rtol, 1e-6) on a 0.5 rad signal
    for key in ("theta_x", "theta_y", "phi_1", "phi_2"):
        assert np.max(np.abs(result[key] - _array(trace[key]))) < 1e-6, key


def test_fig_4_14_torque_loop_is_round_without_compliance(computed):
    cases = computed["data"]["fig-4.14"]["cases"]
    assert cases[0]["compliance"] == 0.0 and all(c["compliance"] > 0 for c in cases[1:])
    ratios = []
    for case in cases:
        tx, ty = _array(case["torque_x"]), _array(case["torque_y"])
        assert np.allclose(_array(case["torque_magnitude"]), np.hypot(tx, ty))
        direction = _array(case["direction"])
        assert np.all((direction >= 0) & (direction <= 2 * math.pi))
        assert np.ptp(direction) > 1.9 * math.pi  # one full circle
        lam = np.linalg.eigvalsh(np.cov(np.vstack([tx, ty])))
        ratios.append(math.sqrt(lam[0] / lam[1]))
    assert ratios[0] > 0.98
    assert all(b < a for a, b in zip(ratios, ratios[1:]))


def test_fig_4_7_curves_are_the_reports_and_table_4_1s(computed, params):
    from vsj import synth
    from vsj.wrist import planetary

    data = computed["data"]["fig-4.7"]
    w = _array(data["speed"])
    module = planetary("pg", params)
    for config in data["configurations"]:
        c = synth.REPORT_CONSTANTS[("second", config["fixed"])]
        assert np.allclose(config["report"], c[0] * w + c[1] * np.arctan(c[2] * w))
        model = {m["law"]: _array(m["torque"]) for m in config["model"]}
        for law in ("arctan", "sign"):
            assert np.allclose(model[law], module.closed_form_torque(config["fixed"], w, law))
        assert not np.allclose(config["equal_force"], model["arctan"])


def test_fig_4_13_stiffness_curves(computed, params):
    data = computed["data"]["fig-4.13"]
    grid = _array(data["grid"])
    a1, a2, a3 = (params[f"elastic_element.{k}"] for k in ("a1", "a2", "a3"))
    assert np.allclose(data["report"]["K"], a1 * np.exp(a2 * grid) + a3)
    e = data["exponential"]
    assert np.allclose(e["K"], e["a1"] * np.exp(e["a2"] * grid) + e["a3"])
    # the loops come from the geometric model, so the refitted exponential follows it
    q, K = _array(data["q"]), _array(data["K"])
    assert np.all(np.diff(K[np.argsort(q)]) < 0)  # stiffer towards negative q
    assert dict(zip(data["measured"]["q"], data["measured"]["K"])) == MEASURED_K
    geometric = np.interp(q, grid, data["geometric_K"])
    assert np.allclose(K, geometric, rtol=0.25)


def test_friction_figures_fit_their_points(computed):
    for name in ("fig-4.2", "fig-4.3", "fig-4.4", "fig-4.5"):
        data = computed["data"][name]
        points, curve = data["points"], data["curve"]
        c1, c2, c3 = data["constants"]
        w = _array(curve["speed"])
        assert np.allclose(curve["torque"], c1 * w + c2 * np.arctan(c3 * w)), name
        torque = _array(points["torque"])
        residual = _array(data["residual"])
        assert np.allclose(residual, torque - (c1 * _array(points["speed"])
                                               + c2 * np.arctan(c3 * _array(points["speed"]))))
        assert np.sqrt(np.mean(residual ** 2)) < 0.05 * np.max(np.abs(torque)), name

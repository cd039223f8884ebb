"""The model-side figures of the report (fig 3.5-3.7, 4.14, 4.15), in reduced mode, as the
session's reproduction wrote them (`conftest.reproduced_figures`) and drawn again from
those files.

Checks that each figure is complete (rows, labelled axes, a caption naming the
parameter set), that its rows are plain deterministic values, and that the
report's qualitative statements for these figures hold in vsj.
"""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from vsj.reproduce.base import Row
from vsj.reproduce.model_figures import FIGURES

NAMES = ("fig-3.5", "fig-3.6", "fig-3.7", "fig-4.14", "fig-4.15")


@pytest.fixture(scope="module")
def figures(reproduced_figures):
    """The model figures of the session's reproduction, read back from its files."""
    return {name: reproduced_figures[name] for name in FIGURES}


def _filled(value) -> bool:
    if isinstance(value, str):
        return bool(value.strip())
    return type(value) in (int, float) and math.isfinite(value)


def test_registry_names_every_model_figure(figures):
    assert tuple(FIGURES) == NAMES
    for name, fig in figures.items():
        assert fig.name == name
        assert not fig.synthetic  # model output only, no synthetic measurements


@pytest.mark.parametrize("name", NAMES)
def test_every_row_has_values_and_a_source(figures, name):
    rows = figures[name].rows
    assert rows
    for row in rows:
        assert isinstance(row, Row)
        assert row.quantity.strip() and row.source.strip()
        assert _filled(row.report), row
        assert _filled(row.vsj), row
        assert isinstance(row.unit, str) and isinstance(row.note, str)
    assert len({row.quantity for row in rows}) == len(rows)


@pytest.mark.parametrize("name", NAMES)
def test_axes_are_labelled_and_the_figure_renders(figures, name, params):
    fig = figures[name]
    assert fig.figure.axes
    for ax in fig.figure.axes:
        assert ax.get_xlabel() and ax.get_ylabel()
        assert ax.lines or ax.collections or ax.patches
    assert fig.figure.legends or any(ax.get_legend() for ax in fig.figure.axes)
    assert params.hash()[:12] in fig.caption
    FigureCanvasAgg(fig.figure)
    buffer = io.BytesIO()
    fig.figure.savefig(buffer, format="png", dpi=40)
    assert buffer.getvalue().startswith(b"\x89PNG")


def test_the_figures_file_holds_the_rows_of_results_json(figures, reproduction):
    """Each figure's ``.npz`` (`Figure.save`) and ``results.json``, written by one run,
    give the same rows, every field of every row (JSON keeps a float's every digit)."""
    from vsj.reproduce import _row_json

    code, out = reproduction
    assert code == 0
    recorded = json.loads((out / "results.json").read_text())["rows"]
    for name in NAMES:
        mine = [_row_json(name, r) for r in figures[name].rows]
        assert mine and mine == [r for r in recorded if r["figure"] == name], name


def _row(figures, name, start):
    return next(r for r in figures[name].rows if r.quantity.startswith(start))


def test_end_stop_is_the_reports(figures):
    # the parameter as read from the bundled file ("1.40 rad"): the same float
    assert _row(figures, "fig-3.5", "physical end stop").vsj == 1.40


def test_pretension_loss_where_the_report_saw_it(figures):
    """Section 4.2.2: a spring goes slack in the tested range at q = 0.2 ... -1.0 cm only."""
    rows = [r for r in figures["fig-3.7"].rows if r.quantity.startswith("spring loses")]
    assert len(rows) == 8
    for row in rows:
        assert row.vsj.split()[0] == row.report, row


def test_circle_without_and_ellipse_with_parasitic_compliance(figures, params):
    """Section 4.3: circular without, elliptical with a compliance in one DOF.

    Without it the loop is a circle but for the differential's stiction, the only
    friction that reaches one axis (theta_y) and not the other: a torque of at most its
    Coulomb level F added to one coordinate moves that semi-axis (sqrt(2) times the
    coordinate's standard deviation, `_ellipse`) by at most sqrt(2) F, so the ratio
    stays within 2 sqrt(2) F / major of 1. A compliance c in DOF 1 (the theta_x + theta_y
    direction, half of whose torque reaches differential input 1) is in series with the
    wrist's stiffness K there: that axis shrinks to 1 / (1 + K c / 2) of the other. Each
    ratio is rounded to 3 decimals."""
    from vsj.reproduce.model_figures import _ellipse

    cases = figures["fig-4.14"].data["cases"]
    radius = figures["fig-4.14"].data["radius"]
    major = _ellipse(cases[0]["torque_x"], cases[0]["torque_y"])[0]
    asymmetry = 2 * np.sqrt(2) * params.differential.stiction * np.pi / 2 / major
    rounding = 5e-4
    assert _row(figures, "fig-4.14", "axis ratio of").vsj >= 1 - asymmetry - rounding
    ratios = [r.vsj for r in figures["fig-4.14"].rows if r.quantity.startswith("axis ratio with")]
    assert len(ratios) == 3
    assert all(b < a for a, b in zip(ratios, ratios[1:]))
    stiffness = major / radius  # the rigid wrist's, the same in every direction
    for ratio, case in zip(ratios, cases[1:]):
        series = 1 / (1 + stiffness * case["compliance"] / 2)
        assert abs(ratio - series) <= asymmetry + 2 * rounding, (case["compliance"], ratio)


def test_stiffer_settings_follow_faster(figures):
    following = [r for r in figures["fig-4.15"].rows if r.quantity.startswith("stiffer")]
    assert [r.quantity.rsplit(", ", 1)[1] for r in following] == ["stiction", "arctan"]
    assert all(r.vsj == "yes" for r in following)
    for law in ("stiction", "arctan"):  # true stiction drawn, the arctan law beside it
        lags = [r.vsj for r in figures["fig-4.15"].rows
                if r.quantity.startswith("lag of") and r.quantity.endswith(law)]
        assert len(lags) == 5 and all(lag > 0 for lag in lags), law
        assert all(b > a for a, b in zip(lags, lags[1:])), law


def test_fig_4_15_names_the_law_of_every_curve_and_row(figures):
    """Issue 30: both friction laws are shown, and each panel of traces and each row
    says which law it is (the built-in scenario's, what `vsj simulate` runs, included)."""
    fig = figures["fig-4.15"]
    laws = [entry["law"] for entry in fig.data["laws"]]
    assert laws == ["stiction", "arctan"]
    traces = [ax for ax in fig.figure.axes if ax.get_xlabel() == "time [s]"]
    assert len(traces) == 3 * len(laws)
    for ax in traces:
        named = [law for law in laws if f"friction: {law} (" in ax.get_title()]
        assert len(named) == 1, ax.get_title()
    for ax in fig.figure.axes:
        if ax.get_xlabel().startswith("pivot position"):
            labels = [line.get_label() for line in ax.lines]
            assert [label.split(" ")[0] for label in labels] == laws
    assert "`vsj simulate fig-4.15`" in fig.caption
    for row in fig.rows:
        if row.quantity.startswith(("stiffer", "lag of", "largest elastic")):
            assert row.quantity.rsplit(", ", 1)[1] in laws, row.quantity

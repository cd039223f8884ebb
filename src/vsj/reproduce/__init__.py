"""``vsj reproduce``: every result of the report regenerated, beside the report's numbers.

`run` calls each figure function (`model_figures`, `data_figures`: numbers,
rows and caption, no Matplotlib), writes them to ``fig-X.Y.npz`` (`Figure.save`;
`Figure.load` reads them back, to draw again or plot otherwise), draws the figure
(`draw_model`, `draw_data`), writes ``fig-X.Y.png`` and ``.svg``, then ``results.json`` (every row with its
category, statement and verdict, and the statements the predictions test,
machine readable) and ``report.html`` (one self-contained page: a summary whose
headline counts predictions only, one per report statement, then each figure,
embedded as base64 PNG, with its rows by category, and the inputs used as given
last). A figure that fails is reported
with its error and the others are still made; `run` then says so and the
command exits 1. The files are replaced as one set (`vsj.output.ResultSet`), so a
failed or interrupted run leaves the previous reproduction as it was.
"""

from __future__ import annotations

import html
import json
import math
import multiprocessing
import os
import re
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path

from .. import __version__, pages
from ..engine.core import available_cores, die_with_parent
from ..errors import InputError, SimulationError
from ..output import ResultSet, _jsonable, atomic_write
from ..params import Parameters
from ..plots import save
from ..progress import progress
from . import data_figures, model_figures
from .base import (AGREEMENT, BY_CONSTRUCTION, CALIBRATION, CATEGORIES, CONSISTENCY, INPUT,
                   LIMIT, PREDICTION, ROUND_TRIP, VARIANT, Context, Figure, Row,
                   statement_verdict)

#: The report's table 4.1 (section 4.3): parameter key -> (symbol, value, unit).
TABLE_4_1 = {
    "planetary.ring_inertia": ("I_R", 6.47e-5, "kg m^2"),
    "planetary.carrier_inertia": ("I_C", 1.90e-4, "kg m^2"),
    "planetary.carrier_bearing_viscous": ("b_C", 0.00010, "N m s/rad"),
    "planetary.carrier_bearing_stiction": ("k_C", 0.00026, "N m"),
    "planetary.ring_bearing_viscous": ("b_R", 0.00080, "N m s/rad"),
    "planetary.ring_bearing_stiction": ("k_R", 0.00205, "N m"),
    "planetary.mesh_stiction": ("k_1", 0.00125, "N m"),
    "transmission.viscous": ("b_T", 0.003, "N m s/rad"),
    "transmission.stiction": ("k_T", 0.010, "N m"),
    "differential.stiction": ("k_D", 0.002, "N m"),
    "elastic_element.a1": ("a1", 0.2, "N m/rad"),
    "elastic_element.a3": ("a3", 0.02, "N m/rad"),
}


def _order(name: str) -> tuple:
    """Sort key of a figure name: ``fig-4.7`` before ``fig-4.7-refit`` before ``fig-4.10``."""
    chapter, number, suffix = re.fullmatch(r"fig-(\d+)\.(\d+)(.*)", name).groups()
    return int(chapter), int(number), suffix


def figures() -> dict:
    """Figure name -> function, in the report's order."""
    table = {**model_figures.FIGURES, **data_figures.FIGURES}
    return dict(sorted(table.items(), key=lambda kv: _order(kv[0])))


def carrier_side_inertia(params: Parameters) -> float:
    """Inertia [kg m^2] at each carrier: the carrier's own plus the end-effector's,
    reflected through transmission and differential (eq 3.30-3.31 give each input
    ``(I_x + I_y) / 4``, the transmission divides by its ratio squared). This is what
    table 4.1's I_C ("the carrier and what is attached to it") lumps."""
    d = params.differential
    return (params.planetary.carrier_inertia
            + (d.inertia_x + d.inertia_y) / (4.0 * params.transmission.ratio ** 2))


def table_4_1(params: Parameters) -> list[Row]:
    """Table 4.1 beside the parameter set: inputs used as given."""
    rows = []
    for key, (symbol, value, unit) in TABLE_4_1.items():
        if key == "planetary.carrier_inertia":
            vsj = carrier_side_inertia(params)
            how = ("at each carrier: planetary.carrier_inertia plus the end-effector's share "
                   "through transmission and differential (" + params.sources[key] + ")")
        else:
            vsj, how = params[key], "used as given"
        if not math.isclose(vsj, value, rel_tol=1e-9):
            how = "differs: " + params.sources[key]
        rows.append(Row(f"{symbol} (table 4.1)", value, vsj, unit, "table 4.1", how,
                        category=INPUT))
    rows.append(Row("a2 (table 4.1)", -1.45, params["elastic_element.a2"] / 100, "1/cm",
                    "table 4.1", "used as given", category=INPUT))
    return rows


@dataclass
class Outcome:
    """What became of one figure: its `Figure` (None if it failed), the error and traceback
    if it failed, the files written and the PNG drawn."""
    name: str
    figure: Figure | None = None
    error: str | None = None
    files: list[str] = field(default_factory=list)
    png: bytes = b""
    traceback: str = ""


@dataclass
class Reproduction:
    """Result of `run`: the output directory, one `Outcome` per figure, the rows of table
    4.1 and whether the reduced setting was used."""
    out: Path
    outcomes: list[Outcome]
    table: list[Row]
    reduced: bool

    @property
    def failed(self) -> list[Outcome]:
        """The outcomes of the figures that failed."""
        return [o for o in self.outcomes if o.error is not None]

    def rows(self) -> list[tuple[str, Row]]:
        """Every row compared with the report, labelled with its figure (or table 4.1)."""
        out = [("table 4.1", r) for r in self.table]
        for o in self.outcomes:
            if o.figure is not None:
                out += [(o.name, r) for r in o.figure.rows]
        return out

    def statements(self) -> list[dict]:
        """The report statements the predictions test, in page order: each with its
        ``statement`` (name), the ``figures`` showing it, the number of prediction rows
        (``cases``) and one ``verdict`` (`vsj.reproduce.base.statement_verdict`)."""
        groups: dict = {}
        for where, r in self.rows():
            if r.category != PREDICTION:
                continue
            key = r.statement if r.statement is not None else (where, r.quantity)
            group = groups.setdefault(key, {"statement": r.statement or r.quantity,
                                            "figures": [], "verdicts": []})
            if where not in group["figures"]:
                group["figures"].append(where)
            group["verdicts"].append(r.verdict())
        return [{"statement": g["statement"], "figures": g["figures"],
                 "cases": len(g["verdicts"]), "verdict": statement_verdict(g["verdicts"])}
                for g in groups.values()]

    def headline(self) -> dict:
        """Counts of the report statements the predictions test (compared: agree, differ;
        and shown where the report gives no value), and of the rows of every other
        category with their verdicts, counted apart."""
        verdicts = [s["verdict"] for s in self.statements()]
        rows = self.rows()
        return {"statements": len(verdicts),
                "agree": verdicts.count("agrees"), "differ": verdicts.count("differs"),
                "not_stated": verdicts.count("not compared"),
                "prediction_rows": sum(r.category == PREDICTION for _, r in rows),
                "not_predictions": {c: _counts([r for _, r in rows if r.category == c])
                                    for c in CATEGORIES if c != PREDICTION}}

    def headline_text(self) -> str:
        """The `headline` counts in one sentence."""
        h = self.headline()
        others = h["not_predictions"]
        apart = ", ".join(f"{others[c]['rows']} {COUNTED_AS[c]}" for c in CATEGORIES
                          if c != PREDICTION and others[c]["rows"])
        return (f"{h['agree'] + h['differ']} report statements compared with vsj's "
                f"predictions: {h['agree']} agree, {h['differ']} differ; {h['not_stated']} "
                f"more shown where the report gives no value ({h['prediction_rows']} "
                f"prediction rows in all, each statement counted once). Not counted: "
                f"{apart}.")


def _counts(rows: list[Row]) -> dict:
    verdicts = [r.verdict() for r in rows]
    return {"rows": len(rows), "agree": verdicts.count("agrees"),
            "differ": verdicts.count("differs"), "not_stated": verdicts.count("not compared")}


#: How the headline counts the rows of each category it leaves out.
COUNTED_AS = {CONSISTENCY: "report-consistency checks", VARIANT: "variants of the default model",
              LIMIT: "values decided by a limit", BY_CONSTRUCTION: "rows that hold by construction",
              CALIBRATION: "calibration targets", ROUND_TRIP: "round trips of synthetic data",
              INPUT: "inputs used as given"}


def _value(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _row_json(where: str, row: Row) -> dict:
    return {"figure": where, "quantity": row.quantity, "category": row.category,
            "statement": row.statement or row.quantity, "report": _value(row.report), "vsj": _value(row.vsj), "unit": row.unit,
            "source": row.source, "relative_difference": row.difference(),
            "verdict": row.verdict(), "note": row.note}


#: A conservative bound on the bytes `run` writes: a few times what a full run writes.
OUTPUT_BYTES = 64 * 2 ** 20


def run(out: Path, params: Parameters, *, reduced: bool = False, only=None,
        seed: int = 2026) -> Reproduction:
    """Regenerate the figures (all, or the names in ``only``) into ``out``, replacing the
    previous reproduction there as a unit (`vsj.output.ResultSet`); the directory is
    checked before any figure is made. The figures are made side by side, one per core
    (`_made`, in processes forked from this one)."""
    global _JOB
    table = figures()
    names = list(table) if not only else list(only)
    unknown = [n for n in names if n not in table]
    if unknown:
        raise InputError(f"unknown figure(s) {', '.join(unknown)}; known: {', '.join(table)}")
    out = Path(out)
    with ResultSet(out, "reproduce", size=OUTPUT_BYTES) as results:
        ctx = Context(params=params, reduced=reduced, seed=seed)
        # written last; entered now, which makes the staging directory the workers share
        results.path("results.json")
        _JOB = (table, ctx, results)
        try:
            made = _make_all(names, results)
        finally:
            _JOB = None
        outcomes = [made[name] for name in names]
        result = Reproduction(out, outcomes, table_4_1(params), reduced)
        record = {
            "reduced": reduced, "seed": seed, "parameters_hash": params.hash(),
            "figures": {o.name: {"files": o.files, "error": o.error,
                                 "synthetic": o.figure.synthetic if o.figure else None,
                                 "caption": o.figure.caption if o.figure else None}
                        for o in outcomes},
            "headline": result.headline(),
            "statements": result.statements(),
            "rows": [_row_json(w, r) for w, r in result.rows()],
            "success": not result.failed,
        }
        with atomic_write(results.path("results.json")) as handle:
            handle.write(json.dumps(_jsonable(record), indent=2))
        with atomic_write(results.path("report.html")) as handle:
            handle.write(render_html(result, params))
    return result


#: The figure table, context and result set of the `run` in progress, which the worker
#: processes it forks inherit (`_made`).
_JOB: tuple | None = None


def _made(name: str) -> Outcome:
    """Figure ``name`` of the run in progress (`_JOB`) computed, its numbers written
    (`Figure.save`), then drawn and written as PNG and SVG: its `Outcome`, with the
    error where it failed (a failing figure does not stop the others). An `OSError`
    from writing the set is raised: a failing disk ends the run, and the set is
    discarded."""
    table, ctx, results = _JOB
    outcome = Outcome(name)
    try:
        fig = table[name](ctx)
        fig.save(results.path(f"{name}.npz"))
        png = results.path(f"{name}.png")
        # uncropped: every figure is laid out by Matplotlib's layout engines, inside its
        # canvas (tests/test_reproduce.py), so cropping would cost a drawing pass per file
        # to take off the layout's padding
        save(fig.figure, png, svg=True, tight=False)
        results.path(f"{name}.svg")  # written beside the PNG: into the manifest
        outcome.png = png.read_bytes()  # embedded in the page
        outcome.figure = fig
        outcome.files = [f"{name}.png", f"{name}.svg", f"{name}.npz"]
    except Exception as exc:
        if isinstance(exc, OSError) and results.from_writing(exc):
            raise
        outcome.error = f"{type(exc).__name__}: {exc}"
        # a refused input or a failed run says all in its message; anything else is a
        # defect, whose traceback is for the report of it
        if not isinstance(exc, (InputError, SimulationError)):
            outcome.traceback = traceback.format_exc()
    return outcome


def _made_apart(name: str) -> Outcome:
    """`_made` in a worker process: the outcome without its Matplotlib figure, which
    stays behind (its numbers, rows, PNG bytes and files go back)."""
    outcome = _made(name)
    if outcome.figure is not None:
        outcome.figure._drawn = None
    return outcome


def _follow(parent: int) -> None:
    """A worker's start: the worker is killed when ``parent``, the run that forked it,
    ends (`die_with_parent`), so that a run killed outright leaves no worker behind
    holding the output directory's lock and the watchdog's pipe (which would keep the
    staging directory from being cleared)."""
    die_with_parent()
    if os.getppid() != parent:  # the run ended before the signal was asked for
        os._exit(1)


def _make_all(names: list[str], results: ResultSet) -> dict[str, Outcome]:
    """`_made` of every figure of ``names``: one after the other on one core, else in as
    many worker processes as there are cores (at most one per figure), forked from
    this one (the figure table as this process has it); the files the workers wrote
    are entered in ``results`` here."""
    workers = min(available_cores(), len(names))
    if workers <= 1:
        return {name: _made(name) for name in progress(names, desc="reproduce", unit="fig")}
    made = {}
    # forked before any thread of the pool (or of the progress bar) starts
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                               initializer=_follow, initargs=(os.getpid(),))
    try:
        futures = [pool.submit(_made_apart, name) for name in names]
        for future in progress(as_completed(futures), desc="reproduce", unit="fig",
                               total=len(names)):
            outcome = future.result()
            for name in outcome.files:
                results.path(name)
            made[outcome.name] = outcome
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return made


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


#: Section titles of the row tables, by category.
TITLES = {PREDICTION: "Predictions",
          CONSISTENCY: "Report consistency (the report's numbers against each other, "
                       "not vsj's)",
          VARIANT: "Variants (options that are not vsj's default model; not counted)",
          LIMIT: "Decided by a limit (the value is the limit, not a prediction)",
          BY_CONSTRUCTION: "By construction (agreement built into the set-up)",
          CALIBRATION: "Calibration targets (vsj's estimates were tuned to these)",
          ROUND_TRIP: "Round trips of synthetic data (check vsj's toolchain, not the report)",
          INPUT: "Inputs used as given"}


def _cell(value) -> str:
    """A table cell: numbers right-aligned (the page style's default), text left."""
    text = html.escape(_fmt(value))
    return f"<td>{text}</td>" if isinstance(value, (int, float)) else f"<td class=l>{text}</td>"


def _table_html(rows: list[tuple[str, Row]], with_figure: bool) -> str:
    head = ("<tr>" + ("<th class=l>figure</th>" if with_figure else "") +
            "<th class=l>quantity</th><th class=l>category</th><th>report</th><th>vsj</th>"
            "<th class=l>unit</th><th>difference</th><th class=l>verdict</th>"
            "<th class=l>source</th><th class=l>explanation</th></tr>")
    body = []
    for where, r in rows:
        d = r.difference()
        diff = "" if d is None else f"{d * 100:+.1f} %"
        verdict = r.verdict()
        body.append(f"<tr class='{verdict.replace(' ', '-')}'>"
                    + (f"<td class=l><a href='#{html.escape(where)}'>{html.escape(where)}</a>"
                       "</td>" if with_figure else "")
                    + f"<td class=l>{html.escape(r.quantity)}</td>"
                    f"<td class=l>{html.escape(r.category)}</td>{_cell(r.report)}"
                    f"{_cell(r.vsj)}<td class=l>{html.escape(r.unit)}</td><td>{diff}</td>"
                    f"<td class=l>{verdict}</td><td class=l>{html.escape(r.source)}</td>"
                    f"<td class=l>{html.escape(r.note)}</td></tr>")
    return f"<table>{head}{''.join(body)}</table>"


def rows_by_category(rows: list[tuple[str, Row]], categories=CATEGORIES) -> str:
    """HTML tables of ``rows`` (pairs of figure name and `Row`), one per category in
    ``categories`` that has rows, each under its title (`TITLES`)."""
    parts = []
    for category in categories:
        chosen = [(w, r) for w, r in rows if r.category == category]
        if chosen:
            parts.append(f"<h3>{TITLES[category]}</h3>" + _table_html(chosen, with_figure=False))
    return "".join(parts)


#: Why the reproduction differs where it does: the structural reasons behind the rows
#: marked "differs", each detailed in the rows' explanations.
WHY = (
    "The report publishes no raw measurements and not the dimensions of the elastic "
    "element, so vsj regenerates data synthetically and calibrates its geometry to the "
    "three stiffness values the report states; figures resting on that calibration agree "
    "by construction and are not counted. Run forward, table 4.1 does not reproduce the "
    "report's own torque-velocity curves with any one tooth ratio (fig 4.7), and the "
    "report's eq 4.5 misses its own measured stiffness at the stiff and soft ends "
    "(fig 4.13). Statements about curves of the old prototype's unpublished geometry "
    "(fig 3.5-3.7) are not met by a geometry calibrated to the second prototype's "
    "stiffness. Eq 3.27 is kept as printed (planetary module) and offered corrected as an "
    "option; its effect is a variant row of fig 4.7.")


def _link(where: str) -> str:
    return f"<a href='#{html.escape(where)}'>{html.escape(where)}</a>"


def _apart_text(result: Reproduction) -> str:
    """What the rows outside the headline show, category by category, counted from
    the rows: how many agree, differ or have no report value, and which differ."""
    parts = []
    rows = result.rows()
    counts = result.headline()["not_predictions"]
    for category in CATEGORIES:
        if category in (PREDICTION, INPUT) or not counts[category]["rows"]:
            continue
        n = counts[category]
        said = [f"{n[key]} {word}" for key, word in
                (("agree", "agree"), ("differ", "differ"),
                 ("not_stated", "have no report value to compare")) if n[key]]
        differing = [f"{html.escape(r.quantity)} ({_link(w)})" for w, r in rows
                     if r.category == category and r.verdict() == "differs"]
        parts.append(f"{COUNTED_AS[category]} ({n['rows']}): " + ", ".join(said)
                     + (" &mdash; differing: " + "; ".join(differing) if differing else ""))
    inputs = counts[INPUT]
    parts.append(f"{COUNTED_AS[INPUT]} ({inputs['rows']}): listed last, "
                 + ("all agree" if inputs["agree"] == inputs["rows"] else
                    f"{inputs['agree']} agree, {inputs['differ']} differ (the rows say why)"))
    return "<ul>" + "".join(f"<li>{p[0].upper()}{p[1:]}.</li>" for p in parts) + "</ul>"


def _statements_html(result: Reproduction) -> str:
    body = "".join(
        f"<tr class='{s['verdict'].replace(' ', '-')}'><td class=l>{html.escape(s['statement'])}"
        f"</td><td class=l>{', '.join(_link(w) for w in s['figures'])}</td><td>{s['cases']}"
        f"</td><td class=l>{s['verdict']}</td></tr>" for s in result.statements())
    return ("<table><tr><th class=l>report statement</th><th class=l>figures</th>"
            "<th>prediction rows</th><th class=l>verdict</th></tr>" + body + "</table>")


def _summary(result: Reproduction) -> str:
    rows = result.rows()
    differ: set[str] = set()
    agree: list[str] = []
    for where, r in rows:
        if r.category != PREDICTION:
            continue
        if r.verdict() == "differs":
            differ.add(where)
        elif r.verdict() == "agrees" and where not in agree:
            agree.append(where)
    reproduced = [w for w in agree if w not in differ]
    return ("<h2>Summary</h2>"
            f"<p class='headline'>{html.escape(result.headline_text())}</p>"
            "<p>Only predictions are counted: values vsj computes from its inputs with its "
            "default model that the report states independently, one entry per report "
            "statement however many cases (models, pivot positions, speeds, friction laws) "
            "show it; a statement differs when any of its cases differs. A number agrees "
            f"within {AGREEMENT:.0%} unless its row says otherwise (the report states no "
            "uncertainties).</p>" + _statements_html(result)
            + "<p>Listed apart under each figure, and not counted:</p>" + _apart_text(result)
            + ("<p>Reproduced without a differing prediction: "
               + ", ".join(_link(w) for w in reproduced) + ".</p>" if reproduced else "")
            + f"<p>Why vsj differs: {html.escape(WHY)}</p>")


def render_html(result: Reproduction, params: Parameters) -> str:
    """The body of report.html: provenance, failures, the comparison table and every figure
    with its notes."""
    parts = [f"<p>vsj {html.escape(__version__)}, parameter set "
             f"'{html.escape(str(params.meta.get('name', params.origin)))}' (hash "
             f"{params.hash()[:12]}){' — reduced setting' if result.reduced else ''}. "
             "The report publishes no raw measurements: every figure marked "
             "<span class='synthetic'>synthetic data</span> shows data generated by vsj from "
             "the model with known parameters, then analysed as a measurement would be.</p>"]
    if result.failed:
        parts.append("<p class='error'>Failed figures: " + ", ".join(
            f"{html.escape(o.name)} ({html.escape(o.error)})" for o in result.failed) + "</p>")
    parts.append(_summary(result))
    for o in result.outcomes:
        parts.append(f"<h2 id='{o.name}'>{html.escape(o.name)}</h2>")
        if o.error is not None:
            parts.append(f"<p class='error'>This figure failed: {html.escape(o.error)}</p>")
            continue
        parts.append(pages.figure(o.png, o.figure.caption, synthetic=o.figure.synthetic))
        parts.append(rows_by_category([(o.name, r) for r in o.figure.rows],
                                  [c for c in CATEGORIES if c != INPUT]))
    inputs = [(w, r) for w, r in result.rows() if r.category == INPUT]
    parts.append("<h2 id='inputs'>Inputs used as given</h2><p>The report's numbers vsj "
                 "takes as they are (table 4.1 and the settings of the figures): they agree "
                 "by construction and are not counted.</p>"
                 + _table_html(inputs, with_figure=True))
    return pages.document("The 2-DOF variable stiffness joint report, reproduced by vsj", parts)

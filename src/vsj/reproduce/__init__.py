"""``vsj reproduce``: every result of the report regenerated, beside the report's numbers.

`run` calls each figure function (`model_figures`, `data_figures`), writes
``fig-X.Y.png`` and ``.svg``, then ``results.json`` (every row, machine
readable) and ``report.html`` (one self-contained page: figures embedded as
base64 PNG, captions, the comparison table). A figure that fails is reported
with its error and the others are still made; `run` then says so and the
command exits 1. The files are replaced as one set (`vsj.output.ResultSet`), so a
failed or interrupted run leaves the previous reproduction as it was.
"""

from __future__ import annotations

import base64
import html
import json
import math
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from ..params import Parameters
from .base import Context, Figure, Row

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


def figures() -> dict:
    """Figure name -> function, in the report's order."""
    from . import data_figures, model_figures

    table = {**model_figures.FIGURES, **data_figures.FIGURES}
    return dict(sorted(table.items(), key=lambda kv: tuple(int(p) for p in
                                                           kv[0][4:].split("."))))


def table_4_1(params: Parameters) -> list[Row]:
    rows = [Row(f"{symbol} (table 4.1)", value, params[key], unit, "table 4.1",
                "used as given" if math.isclose(params[key], value, rel_tol=1e-9) else
                "differs: " + params.sources[key])
            for key, (symbol, value, unit) in TABLE_4_1.items()]
    rows.append(Row("a2 (table 4.1)", -1.45, params["elastic_element.a2"] / 100, "1/cm",
                    "table 4.1", "used as given"))
    return rows


@dataclass
class Outcome:
    name: str
    figure: Figure | None = None
    error: str | None = None
    files: list[str] = field(default_factory=list)
    png: bytes = b""
    traceback: str = ""


@dataclass
class Reproduction:
    out: Path
    outcomes: list[Outcome]
    table: list[Row]
    reduced: bool

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.error is not None]

    def rows(self) -> list[tuple[str, Row]]:
        out = [("table 4.1", r) for r in self.table]
        for o in self.outcomes:
            if o.figure is not None:
                out += [(o.name, r) for r in o.figure.rows]
        return out


def _value(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def _row_json(where: str, row: Row) -> dict:
    return {"figure": where, "quantity": row.quantity, "report": _value(row.report),
            "vsj": _value(row.vsj), "unit": row.unit, "source": row.source,
            "relative_difference": row.difference(), "note": row.note}


#: A conservative bound on the bytes `run` writes (a full run writes about 8 MB).
OUTPUT_BYTES = 64 * 2 ** 20


def run(out: Path, params: Parameters, *, reduced: bool = False, only=None,
        seed: int = 2026) -> Reproduction:
    """Regenerate the figures (all, or the names in ``only``) into ``out``, replacing the
    previous reproduction there as a unit (`vsj.output.ResultSet`); the directory is
    checked before any figure is made."""
    from ..errors import InputError
    from ..output import ResultSet, _jsonable, atomic_write
    from ..plots import save
    from ..progress import progress

    table = figures()
    names = list(table) if not only else list(only)
    unknown = [n for n in names if n not in table]
    if unknown:
        raise InputError(f"unknown figure(s) {', '.join(unknown)}; known: {', '.join(table)}")
    out = Path(out)
    with ResultSet(out, "reproduce", size=OUTPUT_BYTES) as results:
        ctx = Context(params=params, reduced=reduced, seed=seed)
        outcomes = []
        for name in progress(names, desc="reproduce", unit="fig"):
            outcome = Outcome(name)
            try:
                fig = table[name](ctx)
                png = results.path(f"{name}.png")
                save(fig.figure, png, svg=True)
                outcome.png = png.read_bytes()  # embedded in the page
                outcome.figure = fig
                outcome.files = [f"{name}.png", f"{name}.svg"]
            except Exception as exc:
                if isinstance(exc, OSError) and results.from_writing(exc):
                    raise  # a failing disk ends the run (and the set is discarded);
                # a failing figure does not stop the others
                outcome.error = f"{type(exc).__name__}: {exc}"
                outcome.traceback = traceback.format_exc()
            outcomes.append(outcome)
        result = Reproduction(out, outcomes, table_4_1(params), reduced)
        record = {
            "reduced": reduced, "seed": seed, "parameters_hash": params.hash(),
            "figures": {o.name: {"files": o.files, "error": o.error,
                                 "synthetic": o.figure.synthetic if o.figure else None,
                                 "caption": o.figure.caption if o.figure else None}
                        for o in outcomes},
            "rows": [_row_json(w, r) for w, r in result.rows()],
            "success": not result.failed,
        }
        with atomic_write(results.path("results.json")) as handle:
            handle.write(json.dumps(_jsonable(record), indent=2))
        with atomic_write(results.path("report.html")) as handle:
            handle.write(render_html(result, params))
    return result


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _table_html(rows: list[tuple[str, Row]], with_figure: bool) -> str:
    head = ("<tr>" + ("<th>figure</th>" if with_figure else "") +
            "<th>quantity</th><th>report</th><th>vsj</th><th>unit</th><th>difference</th>"
            "<th>source</th><th>explanation</th></tr>")
    body = []
    for where, r in rows:
        d = r.difference()
        diff = "" if d is None else f"{d * 100:+.1f} %"
        body.append("<tr>" + (f"<td>{html.escape(where)}</td>" if with_figure else "") +
                    f"<td>{html.escape(r.quantity)}</td><td>{html.escape(_fmt(r.report))}</td>"
                    f"<td>{html.escape(_fmt(r.vsj))}</td><td>{html.escape(r.unit)}</td>"
                    f"<td>{diff}</td><td>{html.escape(r.source)}</td>"
                    f"<td>{html.escape(r.note)}</td></tr>")
    return f"<table>{head}{''.join(body)}</table>"


STYLE = """
body { font-family: sans-serif; max-width: 1150px; margin: 2em auto; color: #222; }
table { border-collapse: collapse; font-size: 0.85em; margin: 0.5em 0 1.5em; }
td, th { border: 1px solid #ccc; padding: 3px 6px; vertical-align: top; }
th { background: #eee; }
img { max-width: 100%; border: 1px solid #ddd; }
.synthetic { background: #fff3cd; border: 1px solid #e0c060; padding: 2px 6px; }
.error { background: #f8d7da; padding: 0.5em; }
figure { margin: 0 0 0.5em; }
"""


def render_html(result: Reproduction, params: Parameters) -> str:
    from .. import __version__

    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>vsj: the report "
             f"reproduced</title><style>{STYLE}</style></head><body>",
             "<h1>The 2-DOF variable stiffness joint report, reproduced by vsj</h1>",
             f"<p>vsj {html.escape(__version__)}, parameter set "
             f"'{html.escape(str(params.meta.get('name', params.origin)))}' (hash "
             f"{params.hash()[:12]}){' — reduced setting' if result.reduced else ''}. "
             "The report publishes no raw measurements: every figure marked "
             "<span class='synthetic'>synthetic data</span> shows data generated by vsj from "
             "the model with known parameters, then analysed as a measurement would be.</p>"]
    if result.failed:
        parts.append("<p class='error'>Failed figures: " + ", ".join(
            f"{html.escape(o.name)} ({html.escape(o.error)})" for o in result.failed) + "</p>")
    parts.append("<h2>All numbers</h2>")
    parts.append(_table_html(result.rows(), with_figure=True))
    parts.append("<h2>Table 4.1</h2>" + _table_html([("table 4.1", r) for r in result.table],
                                                     with_figure=False))
    for o in result.outcomes:
        parts.append(f"<h2 id='{o.name}'>{html.escape(o.name)}</h2>")
        if o.error is not None:
            parts.append(f"<p class='error'>This figure failed: {html.escape(o.error)}</p>")
            continue
        tag = " <span class='synthetic'>synthetic data</span>" if o.figure.synthetic else ""
        data = base64.b64encode(o.png).decode("ascii")
        parts.append(f"<figure><img alt='{o.name}' src='data:image/png;base64,{data}'>"
                     f"<figcaption>{html.escape(o.figure.caption)}{tag}</figcaption></figure>")
        if o.figure.rows:
            parts.append(_table_html([(o.name, r) for r in o.figure.rows], with_figure=False))
    parts.append("</body></html>")
    return "\n".join(parts)

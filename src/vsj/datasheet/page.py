"""The datasheet as a page and a JSON file (`html_page`, `write`), in vsj's one
look (`vsj.pages`)."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

from .. import pages
from ..output import ResultSet, _jsonable, atomic_write
from .drawing import figures

# -- the page ---------------------------------------------------------------------------


def html_page(sheet: dict, figs: dict[str, tuple[str, bytes]]) -> str:
    """The datasheet as one self-contained HTML page (`vsj.pages`)."""
    esc = html.escape
    rows = []
    for key, r in sheet["ratings"].items():
        rows.append(f"<tr><td class=l>{esc(key.replace('_', ' '))}</td><td>{r['value']:.4g}</td>"
                    f"<td class=l>{esc(r['unit'])}</td><td class=l>{esc(r['note'])}</td></tr>")
    per_q = []
    for r in sheet["per_q"]:
        slow = r["modes"][0] if r["modes"] else {"frequency": math.nan, "damping": math.nan}
        per_q.append(
            f"<tr><td>{r['q'] * 100:.3g}</td><td>{r['ring_stiffness']:.4g}</td>"
            f"<td>{r['output_stiffness']:.4g}</td><td>{r['max_deflection']:.4g}</td>"
            f"<td class=l>{esc(r['max_deflection_limit'])}</td><td>{r['peak_torque']:.4g}</td>"
            f"<td>{r['max_energy']:.4g}</td><td>{_finite(r['pretension_loss_deflection'])}</td>"
            f"<td>{r['natural_frequencies'][0] / (2 * math.pi):.4g}</td>"
            f"<td>{slow['frequency'] / (2 * math.pi):.4g}</td><td>{slow['damping']:.3g}</td>"
            f"<td>{r['position_bandwidth'] / (2 * math.pi):.4g}</td></tr>")
    body = [
        f"<p>vsj {esc(sheet['vsj_version'])}, parameters {esc(sheet['parameters']['origin'])} "
        f"(hash {esc(sheet['parameters']['hash'][:12])}), elastic model "
        f"{esc(sheet['elastic_model'])}. In the spirit of Grioli et al. 2015, \"Variable "
        "stiffness actuators: the user's point of view\".</p>",
        "<h2>Ratings</h2><table><tr><th class=l>quantity</th><th>value</th>"
        "<th class=l>unit</th><th class=l>condition</th></tr>", *rows, "</table>",
        "<h2>Against the pivot position</h2><table><tr><th>q [cm]</th>"
        "<th>element stiffness [N m/rad]</th><th>output stiffness [N m/rad]</th>"
        "<th>max deflection [rad]</th><th class=l>decided by</th><th>peak torque [N m]</th><th>max energy [J]</th><th>pretension lost at [rad]</th>"
        "<th>natural freq. [Hz]</th><th>slowest pole, |p| [Hz]</th><th>its damping</th>"
        "<th>position bandwidth [Hz]</th></tr>", *per_q, "</table>",
        "<h2>Figures</h2>",
    ]
    body += [pages.figure(png, caption, anchor=name) for name, (caption, png) in figs.items()]
    body.append("<h2>Notes</h2><ul>")
    body += [f"<li>{esc(note)}</li>" for note in sheet["notes"]]
    body.append("</ul>")
    return pages.document(sheet["title"], body)


def _finite(value: float) -> str:
    return f"{value:.3g}" if math.isfinite(value) else "none"


#: A conservative bound on the bytes `write` puts in its directory (about 1 MB).
OUTPUT_BYTES = 16 * 2 ** 20


def write(sheet: dict, out) -> tuple[Path, Path]:
    """Write ``datasheet.html`` (with figures) and ``datasheet.json``: into the directory
    ``out``, replacing a previous datasheet there as a unit, or into ``out``, an open
    `vsj.output.ResultSet` of kind ``datasheet`` (checked before the sheet was computed).
    Returns where the two files are (or will be, once the set is committed)."""
    if not isinstance(out, ResultSet):
        with ResultSet(Path(out), "datasheet", size=OUTPUT_BYTES) as results:
            return write(sheet, results)
    page = html_page(sheet, figures(sheet))
    with atomic_write(out.path("datasheet.html")) as handle:
        handle.write(page)
    with atomic_write(out.path("datasheet.json")) as handle:
        handle.write(json.dumps(_jsonable(sheet), indent=1) + "\n")
    return out.out / "datasheet.html", out.out / "datasheet.json"

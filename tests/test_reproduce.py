"""`vsj reproduce` on the reduced setting: every figure, every row, one self-contained page."""

import base64
import html
import json
import re
import struct

import pytest

from vsj.cli import main
from vsj.reproduce import TABLE_4_1, figures

FIGURES = ["fig-3.5", "fig-3.6", "fig-3.7", "fig-4.2", "fig-4.3", "fig-4.4", "fig-4.5",
           "fig-4.6", "fig-4.7", "fig-4.7-refit", "fig-4.10", "fig-4.11", "fig-4.12",
           "fig-4.13", "fig-4.14", "fig-4.15"]


@pytest.fixture(scope="module")
def reproduced(reproduction):
    """The session's reduced reproduction (`conftest.reproduction`)."""
    return reproduction


def test_every_figure_is_written(reproduced):
    code, out = reproduced
    assert code == 0
    assert list(figures()) == FIGURES
    for name in FIGURES:
        png = (out / f"{name}.png").read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = struct.unpack(">II", png[16:24])
        assert width > 300 and height > 200
        assert (out / f"{name}.svg").read_text().lstrip().startswith(("<?xml", "<svg"))


def test_every_table_row_is_in_results_json(reproduced):
    _, out = reproduced
    record = json.loads((out / "results.json").read_text())
    assert record["success"] and record["reduced"]
    rows = record["rows"]
    by_figure = {}
    for row in rows:
        by_figure.setdefault(row["figure"], []).append(row)
        assert row["report"] is not None and row["vsj"] is not None, row
    # every figure states numbers, and table 4.1 is complete
    for name in FIGURES:
        assert by_figure.get(name), f"{name} has no rows"
    symbols = {r["quantity"].split()[0] for r in by_figure["table 4.1"]}
    assert symbols >= {s for s, _, _ in TABLE_4_1.values()} | {"a2"}
    quantities = " ".join(r["quantity"] for r in rows)
    for needed in ("c1", "c6", "a1", "a3", "linear stiffness at q = 1.4 cm", "end stop",
                   "deflection under 1 N m", "pretension", "non-linearity", "axis ratio",
                   "lag"):
        assert needed in quantities, needed
    # synthetic figures are labelled
    assert record["figures"]["fig-4.4"]["synthetic"] is True
    assert record["figures"]["fig-3.5"]["synthetic"] is False


def test_report_page_is_self_contained(reproduced):
    _, out = reproduced
    page = (out / "report.html").read_text()
    images = re.findall(r"<img[^>]*src='([^']*)'", page)
    assert len(images) == len(FIGURES)
    for src in images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    # nothing fetched from outside: no external URL in any src, href or CSS import
    assert not re.search(r"(src|href)\s*=\s*['\"]?(https?:)?//", page)
    assert "@import" not in page and "<script" not in page
    for name in FIGURES:
        assert f"id='{name}'" in page
    record = json.loads((out / "results.json").read_text())
    for row in record["rows"]:
        assert html.escape(row["quantity"]) in page
    assert page.count("synthetic data") >= 10


def test_a_failing_figure_is_reported_and_the_rest_written(tmp_path, capsys, monkeypatch):
    from vsj.reproduce import data_figures

    def broken(ctx):
        raise RuntimeError("deliberately broken")

    monkeypatch.setitem(data_figures.FIGURES, "fig-4.6", broken)
    out = tmp_path / "r"
    assert main(["reproduce", "--reduced", "--only", "fig-4.6", "fig-4.4", "--out",
                 str(out)]) == 1
    captured = capsys.readouterr()
    assert "deliberately broken" in captured.out + captured.err
    assert (out / "fig-4.4.png").exists() and not (out / "fig-4.6.png").exists()
    record = json.loads((out / "results.json").read_text())
    assert record["success"] is False
    assert "deliberately broken" in record["figures"]["fig-4.6"]["error"]
    assert "This figure failed" in (out / "report.html").read_text()


def test_unknown_figure_is_bad_input(tmp_path, capsys):
    assert main(["reproduce", "--only", "fig-9.9", "--out", str(tmp_path)]) == 2
    assert "fig-9.9" in capsys.readouterr().err

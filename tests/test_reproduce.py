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


def test_every_figure_is_drawn_inside_its_canvas(reproduced_figures):
    """The reproduction writes the figures uncropped (`vsj.reproduce._made`): each must
    lie inside its canvas as its layout engine placed it. Matplotlib's layouts pad by
    3 pt, more than a pixel of text extent at any resolution, so the bound is exact."""
    for name in FIGURES:
        fig = reproduced_figures[name].figure
        fig.draw_without_rendering()  # laid out by its engine
        inside = fig.get_tightbbox()
        width, height = fig.get_size_inches()
        assert inside.x0 >= 0 and inside.y0 >= 0, name
        assert inside.x1 <= width and inside.y1 <= height, name


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


def test_a_figures_numbers_come_back_from_its_file_as_they_were(tmp_path):
    """`Figure.save` and `Figure.load`: nested dicts and lists, arrays of any dtype and
    shape (bit for bit, NaN included), plain values, rows and the drawing come back;
    sequences as lists. A key that would read as an array, a file that is no figure
    and a figure of another format are refused, naming the file."""
    import numpy as np

    from vsj.errors import InputError
    from vsj.reproduce.base import Drawing, Figure, Row

    data = {"t": np.linspace(0.0, 1.0, 7), "grid": np.arange(6).reshape(2, 3),
            "flags": np.array([True, False]), "cases": [{"q": -0.01, "y": np.array([np.nan, 2.5])},
                                                         {"q": np.float64(0.5), "y": np.zeros(0)}],
            "pair": (1.0, "two"), "none": None, "title": "a figure"}
    rows = [Row("a quantity", 1.5, 1.4, "N m", "table 4.1", note="n", tolerance=0.2,
                statement="s"), Row("another", "yes", "no", "", "fig 4.7", agrees=False)]
    fig = Figure("fig-9.9", data, "caption", rows, synthetic=True,
                 draw=Drawing("draw_model", "fig_3_5"))
    fig.save(tmp_path / "f.npz")
    back = Figure.load(tmp_path / "f.npz")
    assert (back.name, back.caption, back.rows, back.synthetic, back.draw) == \
        ("fig-9.9", "caption", rows, True, Drawing("draw_model", "fig_3_5"))
    for key in ("t", "grid", "flags"):
        assert back.data[key].dtype == data[key].dtype
        np.testing.assert_array_equal(back.data[key], data[key])
    assert back.data["cases"][0]["q"] == -0.01 and back.data["cases"][1]["q"] == 0.5
    np.testing.assert_array_equal(back.data["cases"][0]["y"], [np.nan, 2.5])
    assert back.data["cases"][1]["y"].shape == (0,)
    assert back.data["pair"] == [1.0, "two"] and back.data["none"] is None
    assert back.data["title"] == "a figure"

    with pytest.raises(ValueError, match="__array__"):
        Figure("fig-9.9", {"__array__": 1.0}, "c").save(tmp_path / "g.npz")
    (tmp_path / "h.npz").write_text("not a figure")
    with pytest.raises(InputError, match="h.npz"):
        Figure.load(tmp_path / "h.npz")
    np.savez(tmp_path / "i.npz", figure=np.array(json.dumps({"format": "vsj-figure-0"})))
    with pytest.raises(InputError, match="i.npz: figure format .vsj-figure-0."):
        Figure.load(tmp_path / "i.npz")

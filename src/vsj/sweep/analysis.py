"""What a finished sweep shows: sensitivity indices, histograms, scatter plots, a page.

`sensitivity` computes SALib's indices from the design's unit-cube points and a
metric's values: Sobol first-order and total indices (Saltelli's estimators,
bootstrap 95 % confidence intervals) or Morris's mu* and sigma (mu* with its
bootstrap interval). The figures follow 20-sim's variation analysis: a
histogram of each metric, each metric against each varied quantity, and, for a
one-dimensional sweep over the pivot position q, the metric against q.
``summary.html`` is one self-contained page in the style of ``report.html``.
"""

from __future__ import annotations

import html
import io
import math

import numpy as np

from ..pages import document, figure
from .sampling import MORRIS_LEVELS

#: Confidence level of the intervals SALib's bootstrap gives.
CONFIDENCE = 0.95
#: Bootstrap resamples for the intervals.
RESAMPLES = 1000


def sensitivity(method: str, problem: dict, unit: np.ndarray, y: np.ndarray,
                seed: int) -> dict:
    """Indices of one output ``y`` (one value per run, in design order); NaN outputs
    (failed runs) make the indices NaN rather than wrong, and so does a Sobol output
    that does not vary (its indices are shares of a variance of zero)."""
    nan = [math.nan] * problem["num_vars"]
    keys = (("S1", "S1_conf", "ST", "ST_conf") if method == "sobol"
            else ("mu_star", "mu_star_conf", "sigma"))
    if not np.all(np.isfinite(y)):
        return {"names": list(problem["names"]), **{k: list(nan) for k in keys},
                "note": "some runs failed: indices need every run"}
    if method == "sobol" and np.ptp(y) == 0.0:
        return {"names": list(problem["names"]), **{k: list(nan) for k in keys},
                "note": "the metric is the same in every run: no variance to share"}
    if method == "sobol":
        from SALib.analyze import sobol  # lazy: SALib is heavy; only sensitivity studies

        r = sobol.analyze(problem, y, calc_second_order=False, num_resamples=RESAMPLES,
                          conf_level=CONFIDENCE, seed=seed)
        return {"names": list(problem["names"]), "S1": r["S1"].tolist(),
                "S1_conf": r["S1_conf"].tolist(), "ST": r["ST"].tolist(),
                "ST_conf": r["ST_conf"].tolist()}
    from SALib.analyze import morris  # lazy: SALib is heavy; only sensitivity studies

    levels = (unit * MORRIS_LEVELS - 0.5) / (MORRIS_LEVELS - 1)  # back to SALib's grid
    r = morris.analyze(problem, levels, y, num_resamples=RESAMPLES, conf_level=CONFIDENCE,
                       num_levels=MORRIS_LEVELS, seed=seed)
    return {"names": list(problem["names"]), "mu_star": np.asarray(r["mu_star"]).tolist(),
            "mu_star_conf": np.asarray(r["mu_star_conf"]).tolist(),
            "sigma": np.asarray(r["sigma"]).tolist()}


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90)
    return buffer.getvalue()


def _figure(rows: int, cols: int, width: float = 3.2, height: float = 2.6):
    from matplotlib.figure import Figure  # lazy: matplotlib is heavy; only the plots

    fig = Figure(figsize=(max(4.0, width * cols), max(3.0, height * rows)),
                 layout="constrained")
    axes = np.atleast_2d(fig.subplots(rows, cols, squeeze=False))
    return fig, axes


def _label(name: str, unit: str) -> str:
    return f"{name} [{unit}]" if unit else name


def histograms(metrics: np.ndarray, names: list[str], units: list[str]) -> bytes:
    """PNG of one histogram per metric (finite values only)."""
    cols = min(3, len(names))
    rows = math.ceil(len(names) / cols)
    fig, axes = _figure(rows, cols)
    for ax, j in zip(axes.flat, range(len(names))):
        values = metrics[:, j][np.isfinite(metrics[:, j])]
        ax.hist(values, bins=min(50, max(5, int(math.sqrt(max(1, len(values)))))),
                color="C0", alpha=0.8)
        ax.set(xlabel=_label(names[j], units[j]), ylabel="runs")
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    return _png(fig)


def scatter(metrics, names, units, inputs, input_names, input_units) -> bytes:
    """PNG of each metric against each varied input (the first six of each)."""
    shown_m, shown_i = names[:6], input_names[:6]
    fig, axes = _figure(len(shown_m), len(shown_i), 2.8, 2.3)
    step = max(1, len(metrics) // 5000)  # more points than pixels draw slowly
    for i in range(len(shown_m)):
        for j in range(len(shown_i)):
            ax = axes[i, j]
            ax.plot(inputs[::step, j], metrics[::step, i], ".", ms=2, alpha=0.5)
            ax.set(xlabel=_label(input_names[j], input_units[j]) if i == len(shown_m) - 1
                   else "", ylabel=_label(names[i], units[i]) if j == 0 else "")
    return _png(fig)


def versus_q(q: np.ndarray, metrics, names, units) -> bytes:
    """PNG of each metric against the pivot position q [cm]."""
    cols = min(3, len(names))
    rows = math.ceil(len(names) / cols)
    fig, axes = _figure(rows, cols)
    order = np.argsort(q)
    for ax, j in zip(axes.flat, range(len(names))):
        ax.plot(q[order] * 100, metrics[order, j], "o-", ms=3)
        ax.set(xlabel="pivot position q [cm]", ylabel=_label(names[j], units[j]))
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(names):]:
        ax.set_visible(False)
    return _png(fig)


def sensitivity_chart(method: str, indices: dict[str, dict]) -> bytes:
    """PNG of the sensitivity indices per metric (Sobol S1 and ST, or Morris mu* and sigma),
    with their confidence intervals."""
    names = list(indices)
    fig, axes = _figure(len(names), 1, 6.0, 2.6)
    for ax, metric in zip(axes.flat, names):
        r = indices[metric]
        x = np.arange(len(r["names"]))
        if method == "sobol":
            ax.bar(x - 0.2, r["S1"], 0.4, yerr=r["S1_conf"], label="first order S1", capsize=3)
            ax.bar(x + 0.2, r["ST"], 0.4, yerr=r["ST_conf"], label="total ST", capsize=3)
            ax.set_ylim(bottom=min(0.0, *(np.nan_to_num(r["S1"]) - 0.05)))
        else:
            ax.bar(x, r["mu_star"], 0.5, yerr=r["mu_star_conf"], label="mu*", capsize=3)
            ax.plot(x, r["sigma"], "ks", label="sigma")
        ax.set_xticks(x, r["names"], rotation=20, fontsize=8)
        ax.set_title(metric, fontsize=10)
        ax.legend(fontsize=8)
    return _png(fig)


def sensitivity_rows(method: str, indices: dict[str, dict]) -> list[list]:
    """Rows of ``sensitivity.csv`` and the page's table."""
    rows = []
    for metric, r in indices.items():
        for k, name in enumerate(r["names"]):
            if method == "sobol":
                rows.append([metric, name, r["S1"][k], r["S1_conf"][k], r["ST"][k],
                             r["ST_conf"][k]])
            else:
                rows.append([metric, name, r["mu_star"][k], r["mu_star_conf"][k],
                             r["sigma"][k]])
    return rows


def header(method: str) -> list[str]:
    """Column names of the sensitivity table for ``method`` (sobol or morris)."""
    if method == "sobol":
        return ["metric", "parameter", "S1", "S1 95% half-width", "ST", "ST 95% half-width"]
    return ["metric", "parameter", "mu*", "mu* 95% half-width", "sigma"]


def page(title: str, facts: list[tuple[str, str]], stats: list[list], figures: dict,
         method: str | None, rows: list[list], failures: list[tuple[int, str]]) -> str:
    """``summary.html``: facts, a table of each metric's statistics, the sensitivity
    table, the figures (embedded), the failed runs."""
    esc = html.escape
    parts = ["<table>"]
    parts += [f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in facts]
    parts.append("</table><h2>Metrics</h2><table><tr><th>metric</th><th>unit</th>"
                 "<th>runs</th><th>mean</th><th>std</th><th>min</th><th>5 %</th>"
                 "<th>median</th><th>95 %</th><th>max</th></tr>")
    for row in stats:
        parts.append("<tr>" + "".join(f"<td>{esc(_fmt(v))}</td>" for v in row) + "</tr>")
    parts.append("</table>")
    if method is not None:
        parts.append(f"<h2>Sensitivity ({esc(method)})</h2><table><tr>" +
                     "".join(f"<th>{esc(h)}</th>" for h in header(method)) + "</tr>")
        for row in rows:
            parts.append("<tr>" + "".join(f"<td>{esc(_fmt(v))}</td>" for v in row) + "</tr>")
        parts.append("</table>")
    for name, (caption, png) in figures.items():
        parts.append(f"<h2>{esc(caption)}</h2>" + figure(png, caption, anchor=name))
    if failures:
        parts.append(f"<h2>Failed runs ({len(failures)})</h2><table><tr><th>run</th>"
                     "<th>message</th></tr>")
        parts += [f"<tr><td>{r}</td><td>{esc(m)}</td></tr>" for r, m in failures[:200]]
        parts.append("</table>")
    return document(title, parts)


def statistics(metrics: np.ndarray, names: list[str], units: list[str]) -> list[list]:
    """Per metric: name, unit, count of finite values, mean, standard deviation, minimum,
    5th, 50th and 95th percentile and maximum."""
    out = []
    for j, name in enumerate(names):
        v = metrics[:, j][np.isfinite(metrics[:, j])]
        if not len(v):
            out.append([name, units[j], 0] + [math.nan] * 7)
            continue
        p5, p50, p95 = np.percentile(v, [5, 50, 95])
        out.append([name, units[j], len(v), float(np.mean(v)), float(np.std(v)),
                    float(np.min(v)), p5, p50, p95, float(np.max(v))])
    return out


def _fmt(v) -> str:
    if isinstance(v, (float, np.floating)):
        return "" if math.isnan(v) else f"{v:.4g}"
    return str(v)

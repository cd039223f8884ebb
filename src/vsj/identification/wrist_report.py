"""What `vsj fit wrist` writes: figures, an HTML page and the JSON record.

The page uses the datasheet's style sheet and its way of embedding figures
(base64 PNG), so every page vsj writes looks alike.
"""

from __future__ import annotations

import html
import io
import math

from .. import __version__
from ..output import atomic_write, write_meta
from ..pages import document, figure
from ..plots import MAX_POINTS, pyplot


def signals_figure(fit, kind: str):
    """Measured against simulated signals, and the residuals, of the fitting (``fit``) or
    validation (``validation``) logs: one column per log, each on its own time axis."""
    plt = pyplot()
    traces = fit.traces[kind]
    files = list(next(iter(traces.values())))
    fig, axes = plt.subplots(2 * len(traces), len(files),
                             figsize=(9 if len(files) == 1 else 5 * len(files),
                                      2.6 * len(traces) + 0.8),
                             squeeze=False, sharex="col")
    for col, path in enumerate(files):
        for r, (name, per_log) in enumerate(traces.items()):
            t, y, ys = per_log[path]
            every = max(1, -(-len(t) // MAX_POINTS))
            ax, ax_r = axes[2 * r, col], axes[2 * r + 1, col]
            ax.plot(t[::every], y[::every], ".", ms=1.5, color="0.5", label="measured")
            ax.plot(t[::every], ys[::every], "-", lw=1.0, color="C3", label="simulated")
            q = fit.quality[kind][name]
            title = f"{name}: fit {q.fit_percent:.4g} %, NRMSE {q.nrmse:.3g}"
            ax.set_title(title if len(files) == 1 else f"{path}\n{title}", fontsize=8)
            ax.legend(fontsize=7, loc="upper right")
            ax.grid(alpha=0.3)
            ax_r.plot(t[::every], (ys - y)[::every], "-", lw=0.6, color="C0")
            ax_r.axhline(0, color="0.5", lw=0.8)
            ax_r.set_ylabel("residual")
            ax_r.grid(alpha=0.3)
        axes[-1, col].set_xlabel("time of the log [s]")
    title = "identified wrist: " + ("fitting logs" if kind == "fit" else "validation logs")
    fig.suptitle(title + ("  [synthetic data]" if fit.synthetic else ""), fontsize=10)
    fig.tight_layout()
    return fig


def _png(fig) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=96)
    pyplot().close(fig)
    return buffer.getvalue()


def html_page(fit, figures: dict[str, bytes]) -> str:
    """One self-contained page: estimates, identifiability, correlations, starts, fit
    quality and the figures."""
    esc = html.escape
    rows = []
    for e in fit.estimates:
        ok = e.status == "determined"
        rows.append(f"<tr><td class=l>{esc(e.name)}</td><td>{e.value:.6g}</td>"
                    f"<td>{e.stderr:.3g}</td>" if ok else
                    f"<tr><td class=l>{esc(e.name)}</td><td>{e.value:.6g}</td><td>-</td>")
        rows.append((f"<td>{e.ci95[0]:.6g} .. {e.ci95[1]:.6g}</td>" if ok else "<td>-</td>")
                    + f"<td class=l>{esc(e.unit)}</td><td class=l>{esc(e.status)}</td>"
                    f"<td>{e.start:.4g}</td><td>{e.bounds[0]:.3g} .. {e.bounds[1]:.3g}</td></tr>")
    delays = [f"<tr><td class=l>{esc(e.name)}</td><td>{e.value * 1e3:.4g}</td><td>"
              + (f"{e.stderr * 1e3:.2g}" if e.status == "determined" else "-")
              + f"</td><td class=l>{esc(e.status)}</td></tr>" for e in fit.delays]
    corr = ["<tr><th></th>" + "".join(f"<th>{i + 1}</th>" for i in range(len(fit.names)))
            + "</tr>"]
    for i, name in enumerate(fit.names):
        cells = "".join("<td>-</td>" if not math.isfinite(v) else f"<td>{v:.2f}</td>"
                        for v in fit.correlation[i])
        corr.append(f"<tr><td class=l>{i + 1} {esc(name)}</td>{cells}</tr>")
    quality = []
    for kind, per in fit.quality.items():
        for name, q in per.items():
            quality.append(f"<tr><td class=l>{kind}</td><td class=l>{esc(name)}</td>"
                           f"<td>{q.fit_percent:.4g}</td><td>{q.nrmse:.3g}</td>"
                           f"<td>{q.noise:.3g}</td><td>{q.samples}</td></tr>")
    starts = [f"<tr><td>{k + 1}</td><td>{s['cost']:.6g}</td><td class=l>"
              f"{'yes' if s['reached_best'] else 'no'}</td></tr>"
              for k, s in enumerate(fit.starts)]
    ident = ([f"<li>not determined: {esc(', '.join(fit.undetermined))}</li>"]
             if fit.undetermined else ["<li>every free parameter is determined</li>"])
    ident += [f"<li>poorly determined direction: {esc(c)}</li>" for c in fit.combinations]
    title = "The wrist identified from its signals" + (" [synthetic data]" if fit.synthetic
                                                         else "")
    parts = [f"<p>vsj {esc(__version__)}; fitted to {esc(', '.join(fit.files))}"
             + (f"; validated on {esc(', '.join(fit.validation_files))}"
                if fit.validation_files else "")
             + f". {fit.simulations} window simulations ({fit.simulated_seconds:.4g} s "
               f"simulated) in {fit.wall_time:.3g} s.</p>",
             "<h2>Estimates</h2><table><tr><th class=l>parameter</th><th>value</th>"
             "<th>standard error</th><th>95 % interval</th><th class=l>unit (SI)</th>"
             "<th class=l>status</th><th>start</th><th>bounds</th></tr>", *rows, "</table>",
             *_uncertainty(fit),
             *(["<h2>Channel delays</h2><p>Each compared signal's delay behind the inputs "
                "(a nuisance parameter: the recorder's channels need not be "
                "simultaneous).</p><table><tr><th class=l>signal</th><th>delay [ms]</th>"
                "<th>standard error [ms]</th><th class=l>status</th></tr>", *delays,
                "</table>"] if delays else []),
             "<h2>Identifiability</h2><ul>", *ident, "</ul>",
             "<h2>Correlation</h2><table>", *corr, "</table>",
             f"<h2>Starts</h2><p>{fit.reached} of {len(fit.starts)} starts reached the best "
             "optimum: the same cost and the same end point, to within the noise (smooth "
             "friction law, part of the windows).</p><table><tr><th>start</th>"
             "<th>cost</th><th class=l>reached best</th></tr>", *starts, "</table>",
             "<h2>Fit quality</h2><table><tr><th class=l>data</th><th class=l>signal</th>"
             "<th>fit %</th><th>NRMSE</th><th>noise (SI)</th><th>samples</th></tr>",
             *quality, "</table>", "<h2>Figures</h2>"]
    parts += [figure(png, name, anchor=name, synthetic=fit.synthetic)
              for name, png in figures.items()]
    parts.append("<h2>Notes</h2><ul>" + "".join(f"<li>{esc(n)}</li>" for n in fit.notes)
                 + "</ul>")
    return document(title, parts)


def _uncertainty(fit) -> list[str]:
    """How the standard errors were computed, and how much of each variance the
    measured inputs' noise makes."""
    u = fit.uncertainty
    if not u:
        return []
    esc = html.escape
    out = [f"<p>Standard errors: {esc(u['description'])}.</p>"]
    if u.get("input_share"):
        out.append("<table><tr><th class=l>parameter</th><th>share of variance from the "
                   "inputs' noise</th><th>degrees of freedom</th></tr>")
        out += [f"<tr><td class=l>{esc(name)}</td><td>{100 * share:.0f} %</td>"
                f"<td>{u['dof'][name]:.3g}</td></tr>"
                for name, share in u["input_share"].items() if math.isfinite(share)]
        out.append("</table>")
    return out


def write(fit, results) -> list[str]:
    """Write ``wrist-fit.json``, ``wrist-fit.html`` and the figures into an open
    `vsj.output.ResultSet`; returns the file names."""
    figures = {}
    names = []
    for kind in fit.traces:
        fig = signals_figure(fit, kind)
        png = _png(fig)
        name = f"wrist-{'fit' if kind == 'fit' else 'validation'}.png"
        with atomic_write(results.path(name), "wb") as handle:
            handle.write(png)
        figures[name] = png
        names.append(name)
    write_meta(results.path("wrist-fit.json"), fit.to_json())
    with atomic_write(results.path("wrist-fit.html")) as handle:
        handle.write(html_page(fit, figures))
    return names + ["wrist-fit.json", "wrist-fit.html"]

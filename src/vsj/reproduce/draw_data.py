"""Drawing of the characterisation figures (fig 4.2-4.7, 4.7-refit, 4.10-4.13).

One function per figure (fig 4.2-4.5 share `friction_figure`, fig 4.10-4.12
`loop_figure`) that reads only the figure's ``data`` (SI units, as
`vsj.reproduce.data_figures` documents it) and returns a
`matplotlib.figure.Figure` (no pyplot state). The axes are
`vsj.identification.plots`' own, drawn from plain arrays; torques of friction
residuals and ripple are shown in mN m, pivot positions in cm and angles in
degrees.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..identification.plots import (
    exponential_label,
    loop_axes,
    stiffness_points_axes,
    torque_velocity_axes,
)


def _friction_axes(ax, data) -> None:
    """Samples, fitted points and curve of one torque-velocity fit."""
    samples, points, curve = data["samples"], data["points"], data["curve"]
    torque_velocity_axes(
        ax, points=(points["speed"], points["torque"]), curve=(curve["speed"], curve["torque"]),
        constants=data["constants"], ripple_removed=points["ripple_removed"],
        samples=None if samples is None else (samples["speed"], samples["torque"]))


def friction_figure(data) -> Figure:
    """Fig 4.2-4.5: the fit and its residuals."""
    fig = Figure(figsize=(10, 4))
    ax, res = fig.subplots(1, 2)
    _friction_axes(ax, data)
    res.axhline(0, color="0.5", lw=0.8)
    res.plot(data["points"]["speed"], data["residual"] * 1e3, "o", ms=4)
    res.set_xlabel("carrier speed w [rad/s]")
    res.set_ylabel("residual [mN m]")
    res.grid(alpha=0.3)
    fig.suptitle(data["title"], fontsize=10)
    fig.tight_layout()
    return fig


def fig_4_6(data) -> Figure:
    """Draw report fig 4.6 from its data: the raw torque and speed, and the ripple against
    the carrier angle."""
    fig = Figure(figsize=(10, 4))
    raw, shape = fig.subplots(1, 2)
    t = data["time"]
    raw.plot(t, data["torque"] * 1e3, lw=0.5, color="C0", label="torque")
    twin = raw.twinx()
    twin.plot(t, data["speed"], lw=0.8, color="C1", label="speed")
    raw.set_xlabel("time [s]")
    raw.set_ylabel("torque [mN m]")
    twin.set_ylabel("carrier speed [rad/s]")
    raw.set_title("raw torque while the speed steps", fontsize=9)
    ripple = data["ripple"]
    shape.plot(np.degrees(ripple["angle"]), ripple["torque"] * 1e3, color="C2",
               label="fitted ripple, w > 0")
    shape.set_xlabel("carrier angle [deg]")
    shape.set_ylabel("ripple [mN m]")
    shape.set_title(f"angle-dependent ripple: rms {ripple['rms'] * 1e3:.3g} mN m", fontsize=9)
    shape.grid(alpha=0.3)
    shape.legend(fontsize=7)
    fig.suptitle("fig-4.6: angle-dependent torque ripple, second prototype, sun fixed  "
                 "[synthetic data]", fontsize=10)
    fig.tight_layout()
    return fig


#: Line style of each law of fig 4.7's forward curves.
FORWARD_STYLES = {"arctan": "-", "sign": "--"}


def fig_4_7(data) -> Figure:
    """Draw report fig 4.7 from its data: for fixed sun and fixed ring, the report's curve
    against the table 4.1 model's, and their relative difference [%] over carrier speed."""
    w = data["speed"]
    low, high = data["measured_speeds"]
    fig = Figure(figsize=(11, 7), layout="constrained")
    axes = fig.subplots(2, 2)
    for col, config in enumerate(data["configurations"]):
        fixed = config["fixed"]
        top, bottom = axes[0, col], axes[1, col]
        reference = config["report"]
        top.plot(w, reference, "k-", lw=2.2, alpha=0.45,
                 label=f"report: {config['equation']} with {config['constant_names']} = "
                       + ", ".join(f"{c:g}" for c in config["constants"]))
        for model in config["model"]:
            style, torque = FORWARD_STYLES[model["law"]], model["torque"]
            top.plot(w, torque, style, color="C0", lw=1.4,
                     label=f"table 4.1 model, {model['label']}")
            bottom.plot(w, (torque / reference - 1) * 100, style, color="C0", lw=1.4)
        torque = config["equal_force"]
        top.plot(w, torque, ":", color="C2", lw=1.6,
                 label="table 4.1 model, eq 3.27 equal-force option, arctan")
        bottom.plot(w, (torque / reference - 1) * 100, ":", color="C2", lw=1.6)
        for ax in (top, bottom):
            ax.axvspan(low, high, color="0.85", alpha=0.4,
                       label="measured speed range" if ax is top else None)
            ax.set_xscale("log")
            ax.grid(alpha=0.3, which="both")
        bottom.axhline(0, color="k", lw=0.8)
        top.set(xlabel="carrier speed w [rad/s]", ylabel="torque to drive the carrier [N m]",
                title=f"{fixed} fixed (report fig {'4.4' if fixed == 'sun' else '4.5'} curve)")
        bottom.set(xlabel="carrier speed w [rad/s]", ylabel="model / report - 1 [%]",
                   title="difference from the report's curve")
        top.legend(fontsize=7, loc="upper left")
    return fig


def fig_4_7_refit(data) -> Figure:
    """Draw the refit beside fig 4.7: the fixed-sun and fixed-ring plateau means with each
    candidate structure's curves, and the residuals."""
    curves, candidates = data["curves"], data["candidates"]
    fig = Figure(figsize=(13, 4.6), layout="constrained")
    ax_sun, ax_ring, ax_res = fig.subplots(1, 3)
    colours = ("C1", "C3", "C4", "C2")
    for ax, key in ((ax_sun, "fixed_sun"), (ax_ring, "fixed_ring")):
        ax.plot(curves[key]["speed"], curves[key]["torque"], "o", ms=4, color="0.3",
                label="synthetic plateau means")
        for candidate, colour in zip(candidates, colours):
            v, t = candidate["predicted"][key]["speed"], candidate["predicted"][key]["torque"]
            order = np.argsort(v)
            accepted = candidate["accepted"]
            ax.plot(v[order], t[order], "-" if accepted else "--", color=colour, lw=1.3,
                    label=f"{candidate['label']} ({'accepted' if accepted else 'rejected'})")
        ax.set(xlabel="carrier speed w [rad/s]", ylabel="torque [N m]",
               title=key.replace("_", " "))
        ax.grid(alpha=0.3)
    ax_sun.legend(fontsize=7, loc="upper left")
    n_sun = len(curves["fixed_sun"]["speed"])
    index = np.arange(n_sun + len(curves["fixed_ring"]["speed"]))
    for candidate, colour in zip(candidates, colours):
        accepted = candidate["accepted"]
        ax_res.plot(index, candidate["normalised_residual"], "o" if accepted else "x",
                    color=colour, ms=5 if accepted else 6,
                    mfc=colour if accepted else "none", lw=0,
                    label=f"{candidate['label']}: {'accepted' if accepted else 'rejected'}, "
                          f"p = {candidate['p_value']:.2g}")
    ax_res.axhspan(-3, 3, color="tab:green", alpha=0.08, label="within 3 noise widths")
    ax_res.axvline(n_sun - 0.5, color="k", lw=0.8)
    ax_res.set_yscale("symlog", linthresh=3)
    ax_res.set(xlabel=f"point (0-{n_sun - 1}: sun fixed, then ring fixed)",
               ylabel="residual / point noise [-]", title="normalised residuals")
    ax_res.grid(alpha=0.3)
    ax_res.legend(fontsize=7, loc="lower left")
    fig.suptitle("fig-4.7-refit: the planetary module re-identified from synthetic curves  "
                 "[synthetic data]", fontsize=10)
    return fig


def _loop_axes(ax, loop, fit) -> None:
    """One loop with its linear fit."""
    loop_axes(ax, loop["deflection"], loop["torque"], q=fit["q"], K=fit["K"],
              hysteresis=fit["hysteresis"], offset=fit["offset"],
              linear_limit=fit["linear_limit"], play=fit["play"],
              play_detected=fit["play_detected"], pretension_loss=fit["pretension_loss"])


def loop_figure(data) -> Figure:
    """Fig 4.10-4.12: the middle loop with its fit, the slow and fast loops beside it."""
    fig = Figure(figsize=(6.2, 4.6))
    ax = fig.subplots()
    loops = data["loops"]
    _loop_axes(ax, loops["middle"], data["fit"])
    for label, colour in (("low velocity", "C0"), ("high velocity", "C1")):
        trace = loops[label]
        step = max(1, len(trace["deflection"]) // 3000)
        ax.plot(trace["deflection"][::step], trace["torque"][::step], ".", ms=1.2,
                color=colour, alpha=0.6)
        ax.plot([], [], ".", ms=6, color=colour,
                label=f"{label} (hand period {trace['period']:g} s), "
                      f"h = {trace['hysteresis'] * 1e3:.2g} mN m")
    ax.legend(fontsize=6, loc="upper left")
    fig.suptitle(data["title"], fontsize=10)
    fig.tight_layout()
    return fig


def fig_4_13(data) -> Figure:
    """K(q) on linear and log axes (as `vsj.identification.plots.stiffness_axes`), with the
    report's eq 4.5 and its three measured values."""
    fig = Figure(figsize=(11, 4.4))
    lin, log = fig.subplots(1, 2)
    grid, e, report = data["grid"], data["exponential"], data["report"]
    stiffness_points_axes(lin, log, q=data["q"], K=data["K"], K_stderr=data["K_stderr"],
                          grid=grid, model=data["geometric_K"],
                          exponential=(e["K"], exponential_label(e["a1"], e["a2"], e["a3"])))
    for ax in (lin, log):
        ax.plot(grid * 100, report["K"], "-.", color="k", lw=1.4,
                label=f"report's eq 4.5: {report['a1']:g} exp({report['a2'] / 100:g} q) + "
                      f"{report['a3']:g} (table 4.1)")
        ax.plot(data["measured"]["q"] * 100, data["measured"]["K"], "s", mfc="none",
                color="k", ms=8, label="report's measured values (fig 4.10-4.12)")
    lin.legend(fontsize=7)
    fig.suptitle("fig-4.13: stiffness against pivot position  [synthetic data]", fontsize=10)
    fig.tight_layout()
    return fig

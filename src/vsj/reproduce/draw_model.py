"""Drawing of the model-side figures (fig 3.5-3.7, 4.14, 4.15).

One function per figure, named as its figure function in
`vsj.reproduce.model_figures`, that reads only the figure's ``data`` (SI units)
and returns a `matplotlib.figure.Figure` (no pyplot state) with the report's
axes: pivot positions in cm, lags in ms, as the report plots them.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

#: Line style of each elastic model (fig 3.5, 3.6), by the model's name.
STYLES = {"geometric": "-", "geometric-report": "--", "exponential": ":"}


def fig_3_5(data) -> Figure:
    """Draw report fig 3.5 from its data: deflection and largest torque against pivot
    position [cm], per spring model."""
    stop, load, qs = data["end_stop"], data["load"], data["q"]
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    ax_phi, ax_tau = fig.subplots(1, 2)
    for model in data["models"]:
        style = STYLES[model["law"]]
        ax_phi.plot(qs * 100, model["deflection"], style, lw=1.6, label=model["label"])
        ax_tau.plot(qs * 100, model["largest_torque"], style, lw=1.6, label=model["label"])
    ax_phi.axhline(stop, color="k", lw=0.8, ls="-.", label=f"end stop {stop:.2f} rad")
    ax_phi.set(xlabel="pivot position q [cm]", ylabel="deflection φ under 1 N m [rad]",
               title="equilibrium deflection under a 1 N m load", ylim=(0, stop * 1.12))
    ax_tau.axhline(load, color="k", lw=0.8, ls="-.", label="load 1 N m")
    ax_tau.set(xlabel="pivot position q [cm]",
               ylabel="largest restoring torque before the stop [N m]",
               title="why: the element's torque capacity", yscale="log")
    for ax in (ax_phi, ax_tau):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return fig


def fig_3_6(data) -> Figure:
    """Draw report fig 3.6 from its data: the stiffness range against pivot position [cm],
    relative and absolute, per spring model."""
    qs = data["q"]
    report_lo, report_hi = data["report_range"]
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    ax_rel, ax_abs = fig.subplots(1, 2)
    for model in data["models"]:
        style, label = STYLES[model["law"]], model["label"]
        line, = ax_rel.plot(qs * 100, model["relative"], style, lw=1.6,
                            label=f"{label}, to 1 N m or the end stop")
        ax_rel.plot(qs * 100, model["tested_range"], style, lw=1.0, color=line.get_color(),
                    alpha=0.55, label=f"{label}, over the tested range")
        ax_abs.plot(qs * 100, model["absolute"], style, lw=1.6, label=label)
        ax_rel.axvline(model["jump"] * 100, color=line.get_color(), lw=0.8, ls=":")
    ax_rel.plot([], [], "k:", lw=0.8, label="φ_max jumps to the end stop")
    for ax in (ax_rel, ax_abs):
        ax.axvspan(report_lo * 100, report_hi * 100, color="tab:orange", alpha=0.15,
                   label="report: highest non-linearity")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    ax_rel.set(xlabel="pivot position q [cm]",
               ylabel="RMS(curve - tangent) / tangent torque at φ_max [-]",
               title="relative non-linearity")
    ax_abs.set(xlabel="pivot position q [cm]", ylabel="RMS(curve - tangent) [N m]",
               title="absolute non-linearity (to 1 N m or the end stop)")
    return fig


def fig_3_7(data) -> Figure:
    """Draw report fig 3.7 from its data: restoring torque [N m] against deflection [rad] at
    three pivot positions per panel, with the end stops and where a spring goes slack or
    taut."""
    phis, stop = data["phi"], data["end_stop"]
    fig = Figure(figsize=(14, 4.8), layout="constrained")
    axes = fig.subplots(1, 3, sharey=True)
    colours = ("tab:blue", "tab:green", "tab:red")
    for ax, panel in zip(axes, data["panels"]):
        for curve, colour in zip(panel["curves"], colours):
            ax.plot(phis, curve["torque"], color=colour, lw=1.6,
                    label=f"q = {curve['q'] * 100:+.1f} cm")
            if len(curve["switches"]):
                ax.plot(curve["switches"], curve["switch_torque"], "o", color=colour,
                        mfc="none", ms=7)
        ax.axvline(-stop, color="k", lw=0.8, ls="-.")
        ax.axvline(stop, color="k", lw=0.8, ls="-.")
        ax.set(xlabel="deflection φ [rad]", ylabel="restoring torque [N m]",
               title=panel["title"])
        ax.grid(alpha=0.3)
    axes[0].plot([], [], "ko", mfc="none", label="a spring goes slack or taut again")
    axes[0].plot([], [], "k-.", lw=0.8, label=f"end stop ±{stop:.2f} rad")
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=5,
               fontsize=8)
    return fig


def fig_4_14(data) -> Figure:
    """Draw report fig 4.14 from its data: the end-effector torque [N m] that holds it off
    centre around a circle, and its magnitude against the direction, per case."""
    cases = data["cases"]
    fig = Figure(figsize=(11, 5), layout="constrained")
    ax_tau, ax_mag = fig.subplots(1, 2)
    for case, alpha in zip(cases, np.linspace(0.35, 1.0, len(cases))):
        line, = ax_tau.plot(case["torque_x"], case["torque_y"], lw=1.8, alpha=alpha,
                            label=case["label"])
        direction = np.degrees(case["direction"])
        order = np.argsort(direction)
        ax_mag.plot(direction[order], case["torque_magnitude"][order], lw=1.8, alpha=alpha,
                    color=line.get_color())
    ax_tau.set_aspect("equal", adjustable="datalim")
    ax_tau.set(xlabel="end-effector torque τx [N m]", ylabel="end-effector torque τy [N m]",
               title=f"torque to hold the end-effector {data['radius']:g} rad off centre")
    ax_mag.set(xlabel="direction of the displacement atan2(θy, θx) [deg]",
               ylabel="|τ| [N m]", title="torque magnitude around the circle", xlim=(0, 360))
    ax_mag.set_xticks(range(0, 361, 45))
    for ax in (ax_tau, ax_mag):
        ax.grid(alpha=0.3)
    fig.legend(*ax_tau.get_legend_handles_labels(), loc="outside lower center", ncol=4,
               fontsize=8)
    return fig


def fig_4_15(data) -> Figure:
    """One row per friction law (its name in every panel title): the end-effector angles
    with the rigid-spring path and the elastic deflections over time; right, the lag and
    the deflection against q under both laws."""
    laws, rigid = data["laws"], data["rigid"]
    fig = Figure(figsize=(18, 8), layout="constrained")
    rows = [[f"{key}/{i}" for key in ("theta_x", "theta_y", "phi")] + [side]
            for i, side in enumerate(("lag", "deflection"))]
    axes = fig.subplot_mosaic(rows)
    t = rigid["time"]
    for i, law in enumerate(laws):
        traces = law["traces"]
        alphas = np.linspace(0.3, 1.0, len(traces))  # as the report: stiff light, soft solid
        for k, (trace, alpha) in enumerate(zip(traces, alphas)):
            style = dict(color=f"C{k}", alpha=alpha, lw=1.4)
            for key in ("theta_x", "theta_y"):
                axes[f"{key}/{i}"].plot(trace["time"], trace[key], **style,
                                        label=f"q = {trace['q'] * 100:+.1f} cm")
            axes[f"phi/{i}"].plot(trace["time"], trace["phi_1"], **style)
            axes[f"phi/{i}"].plot(trace["time"], trace["phi_2"], "--", **style)
        for key, name in (("theta_x", "end-effector θx [rad]"),
                          ("theta_y", "end-effector θy [rad]"),
                          ("phi", "elastic deflection φ1 (solid), φ2 (dashed) [rad]")):
            ax = axes[f"{key}/{i}"]
            if key != "phi":
                ax.plot(t, rigid[key], "k--", lw=0.9, label="rigid springs (motor command)")
            ax.set(xlabel="time [s]", ylabel=name, xlim=(t[0], t[-1]))
            ax.set_title(f"friction: {law['label']}", fontsize=8)
            ax.grid(alpha=0.3)
    for law, style in zip(laws, ("o-", "s--")):
        short = law["label"].split(";")[0]  # the law and its source; the titles say more
        axes["lag"].plot(law["q"] * 100, law["lag"] * 1e3, style, color="k", mfc="none",
                         label=short)
        axes["deflection"].plot(law["q"] * 100, law["deflection"], style, color="k",
                                mfc="none", label=short)
    axes["lag"].set(xlabel="pivot position q [cm]", ylabel="lag behind the motors [ms]",
                    title="phase lag at the drive frequency")
    axes["deflection"].set(xlabel="pivot position q [cm]", ylabel="largest |φ1|, |φ2| [rad]",
                           title="elastic deflection after the transient")
    for key in ("lag", "deflection"):
        axes[key].grid(alpha=0.3)
        axes[key].legend(fontsize=7)
    fig.legend(*axes["theta_x/0"].get_legend_handles_labels(), loc="outside lower center",
               ncol=len(laws[0]["traces"]) + 1, fontsize=8)
    return fig

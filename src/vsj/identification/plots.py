"""Figures of the characterisation results (Matplotlib, no global pyplot state).

Every function returns a `matplotlib.figure.Figure`; `vsj.plots.save` writes it. A
figure made from synthetic data says so in its title.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure


def _title(fig: Figure, text: str, synthetic: bool) -> None:
    fig.suptitle(text + ("  [synthetic data]" if synthetic else ""), fontsize=10)


def friction_axes(ax, fit, label="fit", colour="C3", show_raw=True):
    """Data and fitted curve of one torque-velocity fit on ``ax``."""
    if show_raw and fit.raw is not None and fit.form != "points":
        w, T = fit.raw
        step = max(1, len(w) // 4000)
        ax.plot(w[::step], T[::step], ".", ms=1, color="0.75", label="samples")
    ax.plot(fit.velocity, fit.torque, "o", ms=4, color="C0",
            label="plateau means (ripple removed)" if fit.ripple is not None
            and fit.form == "segments" else "data")
    grid = np.linspace(min(fit.velocity.min(), 0), max(fit.velocity.max(), 0), 400)
    ax.plot(grid, fit.predict(grid), "-", color=colour,
            label=f"{label}: {fit.c1.value:.3g} w + {fit.c2.value:.3g} atan({fit.c3.value:.3g} w)")
    ax.set_xlabel("carrier speed w [rad/s]")
    ax.set_ylabel("torque T [N m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")


def friction_figure(fit) -> Figure:
    """Fit, residuals and (when separated) the angle-dependent ripple (fig 4.2-4.6)."""
    panels = 3 if fit.ripple is not None else 2
    fig = Figure(figsize=(4.6 * panels, 4.0))
    axes = fig.subplots(1, panels)
    friction_axes(axes[0], fit)
    residual = fit.torque - fit.predict(fit.velocity)
    axes[1].axhline(0, color="0.5", lw=0.8)
    axes[1].plot(fit.velocity, residual * 1e3, "o", ms=4)
    axes[1].set_xlabel("carrier speed w [rad/s]")
    axes[1].set_ylabel("residual [mN m]")
    axes[1].set_title(f"residuals (rms {fit.residual_rms * 1e3:.3g} mN m)", fontsize=9)
    axes[1].grid(alpha=0.3)
    if fit.ripple is not None:
        r = fit.ripple
        axes[2].plot(np.degrees(r.angle), r.torque * 1e3, "-", color="C2",
                     label="positive speed")
        axes[2].plot(np.degrees(r.angle), -r.torque * 1e3, "--", color="C2",
                     label="negative speed (mirrored)")
        axes[2].set_xlabel("carrier angle [deg]")
        axes[2].set_ylabel("ripple [mN m]")
        axes[2].set_title(f"angle-dependent ripple, rms {r.rms * 1e3:.3g} mN m", fontsize=9)
        axes[2].grid(alpha=0.3)
        axes[2].legend(fontsize=7)
    _title(fig, f"torque-velocity fit (eq 4.2): {Path(fit.source).name}", fit.synthetic)
    fig.tight_layout()
    return fig


def planetary_figure(result) -> Figure:
    """Both curves with each model structure's best prediction (fig 4.7)."""
    fig = Figure(figsize=(10, 4.2))
    axes = fig.subplots(1, 2)
    styles = {"mesh": ("C1", "--"), "bearing-stiction": ("C3", "-")}
    for ax, key in zip(axes, ("fixed_sun", "fixed_ring")):
        curve = result.curves[key]
        ax.plot(curve.velocity, curve.torque, "o", ms=4, color="C0", label="measured")
        for name, structure in result.fits.items():
            w, T = structure.predicted[key]
            order = np.argsort(w)
            colour, ls = styles[name]
            verdict = "explains" if structure.explains else "rejected"
            ax.plot(w[order], T[order], ls, color=colour,
                    label=f"{name} model ({verdict}, p = {structure.p_value:.2g})")
        ax.set_title(key.replace("_", " "), fontsize=9)
        ax.set_xlabel("carrier speed w [rad/s]")
        ax.set_ylabel("torque T [N m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    synthetic = any(c.synthetic for c in result.curves.values())
    _title(fig, "planetary module: one parameter set for both tests", synthetic)
    fig.tight_layout()
    return fig


def loops_axes(axes, curves):
    for ax, c in zip(axes, curves):
        step = max(1, len(c.deflection) // 3000)
        ax.plot(c.deflection[::step], c.torque[::step], ".", ms=1, color="0.6", label="data")
        lim = c.linear_limit
        phi = np.linspace(-lim, lim, 50)
        for sign, ls in ((1, "-"), (-1, "--")):
            ax.plot(phi + (0.5 * c.play.value * np.sign(phi) if c.play_detected else 0.0),
                    c.K.value * phi + sign * c.hysteresis.value + c.offset.value, ls,
                    color="C3", lw=1.2,
                    label=f"K = {c.K.value:.3g} N m/rad, h = {c.hysteresis.value * 1e3:.2g} mN m"
                    if sign > 0 else None)
        if c.pretension_loss is not None:
            for s in (-1, 1):
                ax.axvline(s * c.pretension_loss, color="C1", lw=0.8, ls=":")
        ax.set_title(f"q = {c.q * 100:.3g} cm" + (f", play {c.play.value * 1e3:.3g} mrad"
                                                    if c.play_detected else ""), fontsize=9)
        ax.set_xlabel("deflection phi [rad]")
        ax.set_ylabel("torque [N m]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=6, loc="upper left")


def stiffness_axes(ax_lin, ax_log, fit, model_K=None):
    """K(q): measured points, the exponential fit and optionally a model curve (fig 4.13)."""
    q = np.array([c.q for c in fit.curves])
    K = np.array([c.K.value for c in fit.curves])
    err = np.array([c.K.stderr for c in fit.curves])
    grid = np.linspace(q.min() - 0.002, q.max() + 0.002, 200)
    for ax in (ax_lin, ax_log):
        ax.errorbar(q * 100, K, yerr=1.96 * err, fmt="o", color="C0",
                    label="linear stiffness of each curve")
        if fit.exponential is not None:
            e = fit.exponential
            ax.plot(grid * 100, e.predict(grid), "-", color="C3",
                    label=f"{e.a1.value:.3g} exp({e.a2.value / 100:.3g} q) + {e.a3.value:.3g}")
        if model_K is not None:
            ax.plot(grid * 100, [model_K(x) for x in grid], "--", color="C2",
                    label="geometric model")
        ax.set_xlabel("pivot position q [cm]")
        ax.set_ylabel("K [N m/rad]")
        ax.grid(alpha=0.3, which="both")
    ax_log.set_yscale("log")
    ax_lin.legend(fontsize=7)


def stiffness_figure(fit, model_K=None) -> Figure:
    """Each loop with its linear fit, and K(q) on linear and log axes (fig 4.10-4.13)."""
    n = len(fit.curves)
    cols = min(4, n)
    rows = math.ceil(n / cols) + 1
    fig = Figure(figsize=(3.6 * cols, 3.0 * rows))
    grid = fig.add_gridspec(rows, cols)
    loops = [fig.add_subplot(grid[i // cols, i % cols]) for i in range(n)]
    loops_axes(loops, fit.curves)
    half = max(1, cols // 2)
    ax_lin = fig.add_subplot(grid[rows - 1, :half])
    ax_log = fig.add_subplot(grid[rows - 1, half:] if cols > 1 else grid[rows - 1, 0])
    stiffness_axes(ax_lin, ax_log, fit, model_K)
    _title(fig, "elastic element: torque-deflection curves and K(q)",
           any(c.synthetic for c in fit.curves))
    fig.tight_layout()
    return fig


def geometry_figure(calibration, curves, start_row, calibrated_row) -> Figure:
    """Measured elastic torque against the geometric model before and after calibration."""
    from .. import characteristics as ch
    from ..springs import GEOMETRIC

    n = len(curves)
    cols = min(4, n)
    rows = math.ceil(n / cols)
    fig = Figure(figsize=(3.6 * cols, 3.0 * rows))
    axes = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for ax, c in zip(axes, curves):
        elastic = c.torque - c.hysteresis.value * c.direction - c.offset.value
        step = max(1, len(elastic) // 2000)
        ax.plot(c.deflection[::step], elastic[::step], ".", ms=1, color="0.6",
                label="measured (hysteresis removed)")
        phi = np.linspace(c.deflection.min(), c.deflection.max(), 200)
        ax.plot(phi, ch.torque_curve(GEOMETRIC, start_row, c.q, phi), "--", color="C1",
                label="geometry before")
        ax.plot(phi, ch.torque_curve(GEOMETRIC, calibrated_row, c.q, phi), "-", color="C3",
                label="calibrated")
        ax.set_title(f"q = {c.q * 100:.3g} cm", fontsize=9)
        ax.set_xlabel("deflection phi [rad]")
        ax.set_ylabel("torque [N m]")
        ax.grid(alpha=0.3)
    for ax in axes[n:]:
        ax.set_visible(False)
    axes[0].legend(fontsize=6, loc="upper left")
    _title(fig, f"geometric model calibrated to the curves (relative rms "
                f"{calibration.rms_before:.3g} -> {calibration.rms_after:.3g})",
           any(c.synthetic for c in curves))
    fig.tight_layout()
    return fig

"""Figures of the characterisation results (Matplotlib, no global pyplot state).

Every function returns a `matplotlib.figure.Figure`; `vsj.plots.save` writes it. A
figure made from synthetic data says so in its title.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .. import characteristics as ch
from ..springs import GEOMETRIC


def _title(fig: Figure, text: str, synthetic: bool) -> None:
    fig.suptitle(text + ("  [synthetic data]" if synthetic else ""), fontsize=10)


def torque_velocity_axes(ax, *, points, curve, constants, samples=None,
                         ripple_removed=False, label="fit", colour="C3"):
    """A torque-velocity fit on ``ax`` from plain arrays: ``samples`` and ``points``
    (speed, torque), the fitted ``curve`` (speed, torque) and its ``constants``
    (c1, c2, c3 of eq 4.2)."""
    if samples is not None:
        w, T = samples
        step = max(1, len(w) // 4000)
        ax.plot(w[::step], T[::step], ".", ms=1, color="0.75", label="samples")
    ax.plot(*points, "o", ms=4, color="C0",
            label="plateau means (ripple removed)" if ripple_removed else "data")
    c1, c2, c3 = constants
    ax.plot(*curve, "-", color=colour, label=f"{label}: {c1:.3g} w + {c2:.3g} atan({c3:.3g} w)")
    ax.set_xlabel("carrier speed w [rad/s]")
    ax.set_ylabel("torque T [N m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")


def friction_axes(ax, fit, label="fit", colour="C3", show_raw=True):
    """Data and fitted curve of one torque-velocity fit on ``ax``."""
    grid = np.linspace(min(fit.velocity.min(), 0), max(fit.velocity.max(), 0), 400)
    torque_velocity_axes(
        ax, points=(fit.velocity, fit.torque), curve=(grid, fit.predict(grid)),
        constants=(fit.c1.value, fit.c2.value, fit.c3.value),
        samples=fit.raw if show_raw and fit.raw is not None and fit.form != "points" else None,
        ripple_removed=fit.ripple is not None and fit.form == "segments", label=label,
        colour=colour)


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
            verdict = ("rejected" if not structure.explains else
                       "passes, chi2 too small" if structure.too_small else "explains")
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


def loop_axes(ax, deflection, torque, *, q, K, hysteresis, offset, linear_limit, play,
              play_detected, pretension_loss):
    """One torque-deflection loop and its linear fit (K, hysteresis, offset, play) on
    ``ax``, from plain numbers in SI units."""
    step = max(1, len(deflection) // 3000)
    ax.plot(deflection[::step], torque[::step], ".", ms=1, color="0.6", label="data")
    phi = np.linspace(-linear_limit, linear_limit, 50)
    for sign, ls in ((1, "-"), (-1, "--")):
        ax.plot(phi + (0.5 * play * np.sign(phi) if play_detected else 0.0),
                K * phi + sign * hysteresis + offset, ls, color="C3", lw=1.2,
                label=f"K = {K:.3g} N m/rad, h = {hysteresis * 1e3:.2g} mN m"
                if sign > 0 else None)
    if pretension_loss is not None:
        for s in (-1, 1):
            ax.axvline(s * pretension_loss, color="C1", lw=0.8, ls=":")
    ax.set_title(f"q = {q * 100:.3g} cm" + (f", play {play * 1e3:.3g} mrad"
                                            if play_detected else ""), fontsize=9)
    ax.set_xlabel("deflection phi [rad]")
    ax.set_ylabel("torque [N m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6, loc="upper left")


def loops_axes(axes, curves):
    """Draw each curve fit of ``curves`` on its axes of ``axes`` (`loop_axes`)."""
    for ax, c in zip(axes, curves):
        loop_axes(ax, c.deflection, c.torque, q=c.q, K=c.K.value,
                  hysteresis=c.hysteresis.value, offset=c.offset.value,
                  linear_limit=c.linear_limit, play=c.play.value,
                  play_detected=c.play_detected, pretension_loss=c.pretension_loss)


def stiffness_points_axes(ax_lin, ax_log, *, q, K, K_stderr, grid, exponential=None,
                          model=None):
    """K(q) on linear and log axes from plain arrays: the measured points with their 95 %
    bars, ``exponential`` (K on ``grid`` and its label) and ``model`` (K on ``grid``,
    the geometric model), each optional."""
    for ax in (ax_lin, ax_log):
        ax.errorbar(q * 100, K, yerr=1.96 * K_stderr, fmt="o", color="C0",
                    label="linear stiffness of each curve")
        if exponential is not None:
            ax.plot(grid * 100, exponential[0], "-", color="C3", label=exponential[1])
        if model is not None:
            ax.plot(grid * 100, model, "--", color="C2", label="geometric model")
        ax.set_xlabel("pivot position q [cm]")
        ax.set_ylabel("K [N m/rad]")
        ax.grid(alpha=0.3, which="both")
    ax_log.set_yscale("log")
    ax_lin.legend(fontsize=7)


def exponential_label(a1: float, a2: float, a3: float) -> str:
    """The legend of an eq 4.5 fit (a2 in 1/m, shown per cm)."""
    return f"{a1:.3g} exp({a2 / 100:.3g} q) + {a3:.3g}"


def stiffness_axes(ax_lin, ax_log, fit, model_K=None):
    """K(q): measured points, the exponential fit and optionally a model curve (fig 4.13)."""
    q = np.array([c.q for c in fit.curves])
    grid = np.linspace(q.min() - 0.002, q.max() + 0.002, 200)
    e = fit.exponential
    stiffness_points_axes(
        ax_lin, ax_log, q=q, K=np.array([c.K.value for c in fit.curves]),
        K_stderr=np.array([c.K.stderr for c in fit.curves]), grid=grid,
        exponential=None if e is None else (e.predict(grid), exponential_label(
            e.a1.value, e.a2.value, e.a3.value)),
        model=None if model_K is None else [model_K(x) for x in grid])


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

"""The datasheet's figures, drawn from `compute`'s data alone (`figures`)."""

from __future__ import annotations

import io
import math

import numpy as np

from ..plots import pyplot

# -- figures ----------------------------------------------------------------------------


def figures(sheet: dict) -> dict[str, tuple[str, bytes]]:
    """Each figure as ``name: (caption, PNG bytes)``."""
    plt = pyplot()
    out = {}
    per_q = sheet["per_q"]
    q_cm = np.array([r["q"] for r in per_q]) * 100
    curves = sheet["torque_deflection"]
    colours = plt.cm.viridis(np.linspace(0.0, 0.9, len(curves)))

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    ax.semilogy(q_cm, [r["output_stiffness"] for r in per_q], "o-", label="end-effector (theta_x)")
    ax.semilogy(q_cm, [r["ring_stiffness"] for r in per_q], "s--", label="one elastic element")
    ax.set_xlabel("pivot position q [cm]")
    ax.set_ylabel("stiffness [N m/rad]")
    ax.invert_xaxis()
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    out["stiffness_vs_q"] = ("Stiffness at zero deflection against the pivot position "
                             "(stiffer to the right).", _png(fig, plt))

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for colour, curve in zip(colours, curves):
        label = f"q = {curve['q'] * 100:.3g} cm"
        axes[0].plot(curve["deflection"], curve["torque"], color=colour, label=label)
        axes[1].plot(curve["deflection"], curve["stiffness"], color=colour, label=label)
        held = curve["max_deflection"]
        axes[0].plot(held, np.interp(held, curve["deflection"], curve["torque"]), "o",
                     color=colour, mfc="none")
    axes[0].set_xlabel("deflection theta_x [rad]")
    axes[0].set_ylabel("torque [N m]")
    axes[1].set_xlabel("deflection theta_x [rad]")
    axes[1].set_ylabel("tangent stiffness [N m/rad]")
    axes[1].set_yscale("symlog", linthresh=0.01)  # negative beyond the torque peak
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    axes[0].plot([], [], "ko", mfc="none", label="maximum deflection")
    axes[0].legend(fontsize=8)
    out["torque_deflection"] = ("Torque-deflection curves and tangent stiffness at several "
                                "pivot positions (kinks: a spring loses its pretension); "
                                "circles: the maximum deflection, the end stop or the "
                                "torque peak, whichever comes first.",
                                _png(fig, plt))

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for colour, curve in zip(colours, curves):
        ax.plot(curve["deflection"], curve["energy"], color=colour,
                label=f"q = {curve['q'] * 100:.3g} cm")
    ax.set_xlabel("deflection theta_x [rad]")
    ax.set_ylabel("stored elastic energy [J]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    out["energy"] = ("Elastic energy stored against deflection.", _png(fig, plt))

    bode = sheet["frequency_response"]
    omega = np.array(bode["omega"])
    for key, ylabel, caption in (
            ("compliance", "|theta_x / tau_x| [rad/(N m)]",
             "End-effector compliance theta_x/tau_x, motors held (Bode plot)."),
            ("motor_to_output", "|theta_x / motor angle| [1]",
             "Motor-to-output transfer: theta_x per motor angle, both motors together "
             "(Bode plot).")):
        fig, (ax_m, ax_p) = plt.subplots(2, 1, figsize=(6.4, 5.2), sharex=True)
        for colour, resp in zip(colours, bode[key]):
            ax_m.loglog(omega / (2 * math.pi), resp["magnitude"], color=colour,
                        label=f"q = {resp['q'] * 100:.3g} cm")
            ax_p.semilogx(omega / (2 * math.pi), np.degrees(resp["phase"]), color=colour)
        ax_m.set_ylabel(ylabel)
        ax_p.set_ylabel("phase [deg]")
        ax_p.set_xlabel("frequency [Hz]")
        for ax in (ax_m, ax_p):
            ax.grid(alpha=0.3, which="both")
        ax_m.legend(fontsize=8)
        out[f"bode_{key}"] = (caption, _png(fig, plt))

    fig, (ax_f, ax_z) = plt.subplots(2, 1, figsize=(6.4, 5.2), sharex=True)
    ax_f.semilogy(q_cm, [r["natural_frequencies"][0] / (2 * math.pi) for r in per_q], "o-",
                  label="undamped natural frequency")
    for r, q in zip(per_q, q_cm):
        for m in r["modes"]:
            ax_f.semilogy(q, m["frequency"] / (2 * math.pi), "kx", ms=4)
            ax_z.plot(q, m["damping"], "kx", ms=4)
        for m in r["modes_viscous"]:
            ax_f.semilogy(q, m["frequency"] / (2 * math.pi), "o", color="C1", mfc="none", ms=5)
            ax_z.plot(q, m["damping"], "o", color="C1", mfc="none", ms=5)
    ax_f.semilogy([], [], "kx", label="modes (|pole|), friction " + sheet["friction"]["treatment"])
    ax_f.semilogy([], [], "o", color="C1", mfc="none", label="modes, viscous friction only")
    ax_f.set_ylabel("frequency [Hz]")
    ax_z.set_ylabel("damping ratio [1]")
    ax_z.set_xlabel("pivot position q [cm]")
    ax_z.invert_xaxis()
    for ax in (ax_f, ax_z):
        ax.grid(alpha=0.3, which="both")
    ax_f.legend(fontsize=8)
    out["modes"] = ("Natural frequencies and damping against the pivot position, with the "
                    "linearised arctan friction (small motions) and with its viscous part "
                    "only (large motions see about that much damping). Real poles have "
                    "damping ratio 1.", _png(fig, plt))

    fig, (ax_q, ax_p) = plt.subplots(2, 1, figsize=(6.4, 5.2), sharex=True)
    for key, style in (("stiffening", "-"), ("softening", "--")):
        tr = sheet["stiffness_change"][key]["trajectory"]
        ax_q.plot(tr["time"], np.array(tr["q"]) * 100, style, label=key)
        ax_p.plot(tr["time"], tr["power"], style, label=key)
    ax_q.set_ylabel("pivot position q [cm]")
    ax_p.set_ylabel("electric power [W]")
    ax_p.set_xlabel("time [s]")
    for ax in (ax_q, ax_p):
        ax.grid(alpha=0.3)
    ax_q.legend(fontsize=8)
    out["stiffness_change"] = ("Stiffness change at the supply voltage: pivot position and "
                               "the stiffness motor's electric power.", _png(fig, plt))
    return out


def _png(fig, plt) -> bytes:
    buffer = io.BytesIO()
    fig.tight_layout()
    fig.savefig(buffer, format="png", dpi=96)
    plt.close(fig)
    return buffer.getvalue()

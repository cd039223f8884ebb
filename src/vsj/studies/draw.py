"""Drawing of the studies (`vsj.studies.study`): one function per study that reads only
its ``data`` (SI units) and returns a `matplotlib.figure.Figure` (no pyplot state), with
pivot positions in cm and times in ms, as the reproduction draws the report's figures.
Matplotlib is imported when a figure is drawn (`vsj.plots.figure`)."""

from __future__ import annotations

import numpy as np

from ..plots import figure

#: Colour of each strategy, the same in every panel.
COLOURS = {"rigid": "tab:gray", "stiffest": "tab:blue", "best fixed": "tab:green",
           "schedule": "tab:red", "instant schedule": "tab:purple"}


def safe_and_fast(data):
    """The safe-and-fast study: the safe speed over the stiffness setting, the optimal
    link speeds and stiffness schedules, the minimum time over fixed settings, the
    voltages, and the engine's strikes against the force bound."""
    fig = figure(figsize=(14, 8.4), layout="constrained")
    (ax_safe, ax_speed, ax_q), (ax_T, ax_volt, ax_hit) = fig.subplots(2, 3)
    safe, limit = data["safe"], data["body"]["force_limit"]
    q_cm = np.asarray(safe["q"]) * 100
    ax_safe.plot(q_cm, safe["speed"], "-o", ms=3, label="elastic joint, every contact")
    ax_safe.plot(q_cm, safe["first_contact_speed"], "--", label="elastic joint, first contact")
    ax_safe.axhline(safe["rigid_speed"], color=COLOURS["rigid"], ls="-.", label="rigid joint")
    ax_safe.axhline(data["no_load_speed"], color="k", lw=0.8, ls=":",
                    label="motors' speed limit")
    ax_safe.set(xlabel="pivot position q [cm] (stiff to soft)",
                ylabel="safe link speed [rad/s]",
                title=f"impact on the {data['body']['name']} within {limit:g} N",
                ylim=(0, None))
    for s in data["strategies"]:
        c = COLOURS.get(s["name"])
        t_ms = np.asarray(s["time"]) * 1e3
        ax_speed.plot(t_ms, s["link_speed"], "-", color=c, lw=1.4,
                      label=f"{s['name']}: {s['T'] * 1e3:.1f} ms")
        ax_volt.plot(t_ms, s["voltage"], "-", color=c, lw=1.2, label=s["name"])
        if s["name"] != "rigid":
            ax_q.plot(t_ms, np.asarray(s["q"]) * 100, "-", color=c, lw=1.4, label=s["name"])
    ax_speed.axhline(float(np.min(safe["speed"])), color="k", lw=0.8, ls="--",
                     label="safe speed (elastic)")
    ax_speed.axhline(safe["rigid_speed"], color=COLOURS["rigid"], lw=0.8, ls="-.")
    ax_speed.set(xlabel="time [ms]", ylabel="link speed [rad/s]",
                 title=f"minimum-time motion of {data['distance']:g} rad, rest to rest")
    ax_q.set(xlabel="time [ms]", ylabel="pivot position q [cm] (stiff to soft)",
             title="stiffness setting along the motion")
    lo, hi = (np.asarray(data["q_range"]) * 100)
    ax_q.axhspan(lo, hi, color="0.9", zorder=0)
    cand = data["candidates"]
    if len(cand["q"]):
        ax_T.plot(np.asarray(cand["q"]) * 100, np.asarray(cand["T"]) * 1e3, "o-",
                  color=COLOURS["best fixed"], ms=3, label="fixed setting")
    for s in data["strategies"]:
        if s["name"] in ("rigid", "schedule", "instant schedule"):
            ax_T.axhline(s["T"] * 1e3, color=COLOURS.get(s["name"]), ls="--", lw=1,
                         label=s["name"])
    ax_T.set(xlabel="pivot position q [cm] (stiff to soft)", ylabel="minimum time [ms]",
             title="minimum time over the stiffness setting")
    ax_volt.set(xlabel="time [ms]", ylabel="motor voltage [V]", title="optimal commands")
    for v in data["verification"]:
        c = COLOURS.get(v["strategy"])
        t = np.asarray(v["instants"]) * 1e3
        ax_hit.plot(t, v["peak"], "o-", color=c, label=f"{v['strategy']}: engine, whole strike")
        ax_hit.plot(t, v["first_peak"], "s--", color=c, mfc="none",
                    label=f"{v['strategy']}: engine, first contact")
        ax_hit.plot(t, v["predicted"], "x", color=c, ms=7,
                    label=f"{v['strategy']}: reduced model")
    ax_hit.axhline(limit, color="k", lw=1, ls="-.", label=f"bound {limit:g} N")
    ax_hit.set(xlabel="instant of the strike [ms]", ylabel="peak contact force [N]",
               title="strikes on a hand surrogate (vsj engine)", ylim=(0, None))
    for ax in (ax_safe, ax_speed, ax_q, ax_T, ax_volt, ax_hit):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return fig


def explosive_motion(data):
    """The explosive-motion study: the optimiser's convergence, the optimal voltage, the
    link's and motor side's speeds, the ring deflection against the end stop, and the
    ratio over fixed stiffness settings."""
    fig = figure(figsize=(14, 8.4), layout="constrained")
    (ax_conv, ax_volt, ax_speed), (ax_defl, ax_sweep, ax_none) = fig.subplots(2, 3)
    ax_none.set_visible(False)
    fixed, history = np.asarray(data["history_fixed"]), np.asarray(data["history"])
    ax_conv.plot(np.arange(len(fixed)), fixed, "o-", ms=3,
                 label=f"profile at q = {data['fixed_q'] * 100:.1f} cm (from the reduced "
                       "model's optimum)")
    ax_conv.plot(len(fixed) - 1 + np.arange(len(history)), history, "s-", ms=3,
                 label="profile and setting together")
    ax_conv.axhline(1.0, color="k", lw=0.8, ls=":", label="rigid joint (1)")
    ax_conv.set(xlabel="SLSQP iteration", ylabel="peak speed / motors' speed limit [-]",
                title="convergence", ylim=(0, None))
    t_ms = np.asarray(data["time"]) * 1e3
    ax_volt.plot(t_ms, data["voltage"], "-", lw=1.2, label="applied")
    ax_volt.plot(np.asarray(data["times"]) * 1e3, data["voltages"], "o", ms=4, label="knots")
    ax_volt.set(xlabel="time [ms]", ylabel="motor voltage [V]", title="optimal profile")
    ax_speed.plot(t_ms, data["speed"], "-", lw=1.4, label="link theta_x")
    ax_speed.plot(t_ms, data["motor_speed"], "-", lw=1.0, label="motor side (rigid kinematics)")
    ax_speed.axhline(data["no_load_speed"], color="k", lw=0.8, ls=":",
                     label="motors' speed limit")
    ax_speed.set(xlabel="time [ms]", ylabel="speed [rad/s]",
                 title=f"ratio {data['ratio']:.2f} at q = {data['q'] * 100:.2f} cm")
    ax_defl.plot(t_ms, data["deflection"], "-", lw=1.2, label="larger ring deflection")
    ax_defl.axhline(data["end_stop"], color="k", lw=1, ls="-.", label="end stop")
    ax_defl.axhline(data["holdable"], color="tab:orange", lw=1, ls="--",
                    label="joint's torque peak")
    ax_defl.set(xlabel="time [ms]", ylabel="|ring deflection| [rad]", title="what limits it",
                ylim=(0, None))
    sweep = data["sweep"]
    if len(sweep["q"]):
        ax_sweep.plot(np.asarray(sweep["q"]) * 100, sweep["ratio"], "o-",
                      label="engine, fixed setting")
    ax_sweep.plot([data["q"] * 100], [data["ratio"]], "r*", ms=12,
                  label="engine, setting optimised")
    ax_sweep.axhline(1.0, color="k", lw=0.8, ls=":", label="rigid joint")
    ax_sweep.axhline(2.0, color="tab:gray", lw=0.8, ls="--", label="hardware VSAs (about 2)")
    ax_sweep.set(xlabel="pivot position q [cm] (stiff to soft)",
                 ylabel="peak speed / motors' speed limit [-]", title="over the setting",
                 ylim=(0, None))
    for ax in (ax_conv, ax_volt, ax_speed, ax_defl, ax_sweep):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return fig


__all__ = ["COLOURS", "explosive_motion", "safe_and_fast"]

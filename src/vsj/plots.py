"""Figures of simulation results (matplotlib, drawn off-screen).

One function per figure; each takes results and a path and writes a PNG (and
an SVG when asked). The report's figures live in `vsj.reproduce`.
"""

from __future__ import annotations

import sys
import textwrap
from pathlib import Path
from collections.abc import Sequence

import numpy as np

from .output import atomic_write
from .simulate import Result

#: Signals shown by `trajectory_figure`, per network, with their display units.
MAIN_SIGNALS = {
    "wrist": [("theta_x", "rad", "end-effector angle theta_x"),
              ("theta_y", "rad", "end-effector angle theta_y"),
              ("phi_1", "rad", "elastic deflection phi_1"),
              ("phi_2", "rad", "elastic deflection phi_2")],
    "planetary-bench": [("source.motor.speed", "rad/s", "carrier drive speed"),
                        ("spring.sensor.compliance.torque", "N m", "measured torque")],
    "elastic-bench": [("phi", "rad", "deflection phi"),
                      ("spring.sensor.compliance.torque", "N m", "measured torque")],
}


def figure(**options):
    """A matplotlib `Figure` outside pyplot (no pyplot import, no figure registry to
    close it from; `save` writes it through the Agg canvas)."""
    # lazy: matplotlib is heavy; imported when a figure is drawn
    from matplotlib.figure import Figure

    return Figure(**options)


def pyplot():
    """matplotlib's pyplot on the off-screen Agg backend (imported on first use)."""
    import matplotlib  # lazy: matplotlib is heavy; imported when a figure is drawn

    matplotlib.use("Agg")
    # lazy: matplotlib is heavy; imported when a figure is drawn
    import matplotlib.pyplot as plt

    return plt


#: Largest number of points drawn per line of a time plot: more than the figure
#: has pixels across, and drawing every sample of a long run is slow.
MAX_POINTS = 2000


def save(fig, path: Path, *, svg: bool = False, tight: bool = True) -> None:
    """Write ``fig`` as PNG (and SVG); ``tight`` crops it to its contents (an extra
    drawing pass: figures laid out with ``tight_layout`` do without)."""
    path = Path(path)
    with atomic_write(path, "wb") as handle:
        fig.savefig(handle, format="png", dpi=120, bbox_inches="tight" if tight else None)
    if svg:
        # the same figure at the same size: the layout computed for the PNG holds for the
        # SVG, which Matplotlib then draws without laying it out again
        engine = fig.get_layout_engine()
        if engine is not None:
            fig.set_layout_engine("none")
        try:
            with atomic_write(path.with_suffix(".svg"), "wb") as handle:
                fig.savefig(handle, format="svg", bbox_inches="tight" if tight else None)
        finally:
            if engine is not None:  # None would mean rcParams' engine, not none
                fig.set_layout_engine(engine)
    if "matplotlib.pyplot" in sys.modules:  # a figure of pyplot's (`figure`'s need not)
        pyplot().close(fig)


def trajectory_figure(runs: Sequence[tuple[str, Result]], network: str, path: Path, *,
                      title: str = "") -> None:
    """Main signals of every case over time, one panel per signal."""
    signals = [s for s in MAIN_SIGNALS.get(network, []) if s[0] in runs[0][1].signals]
    if not signals:
        signals = [(name, runs[0][1].units[name], name) for name in runs[0][1].columns()[:4]]
    fig = figure(figsize=(8, 2.2 * len(signals) + 0.6))
    axes = fig.subplots(len(signals), 1, sharex=True, squeeze=False)
    alphas = np.linspace(0.35, 1.0, len(runs)) if len(runs) > 1 else [1.0]
    for ax, (name, unit, text) in zip(axes[:, 0], signals):
        for (label, result), alpha in zip(runs, alphas):
            every = max(1, -(-len(result.time) // MAX_POINTS))
            ax.plot(result.time[::every], result.signals[name][::every], alpha=alpha, lw=1.2,
                    label=label if len(runs) > 1 else None)
        ax.set_ylabel(f"{text}\n[{unit}]")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [s]")
    if len(runs) > 1:
        axes[0, 0].legend(fontsize=8, ncol=min(len(runs), 5))
    if title:
        fig.suptitle("\n".join(textwrap.wrap(title, 90)), fontsize=10)
    fig.tight_layout()
    save(fig, path, tight=False)


def trajectory_file_figure(trajectory, network: str, path: Path, *, title: str = "") -> None:
    """`trajectory_figure` of a streamed `vsj.output.TrajectoryFile`: each plotted signal
    read from the file at most `MAX_POINTS` samples per line."""
    runs = []
    for k, label in enumerate(trajectory.labels):
        reached = trajectory.reached[k]
        every = max(1, -(-reached // MAX_POINTS))
        names = trajectory.names(k)
        wanted = [s[0] for s in MAIN_SIGNALS.get(network, []) if s[0] in names] or names[:4]
        signals = {}
        for name in wanted:
            picked = []
            for start in range(0, reached, every * 4096):
                stop = min(reached, start + every * 4096)
                picked.append(trajectory.read(name, k, start, stop)[::every])
            signals[name] = np.concatenate(picked) if picked else np.zeros(0)
        units = {name: trajectory.specs[name][0] for name in wanted}
        runs.append((label, Result(time=trajectory.time[:reached:every], signals=signals,
                                   units=units, ledger={}, success=True, message="",
                                   solver={})))
    trajectory_figure(runs, network, path, title=title)

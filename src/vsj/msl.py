"""Drive trains of the Modelica Standard Library, rebuilt from vsj's components.

The MSL's ``Modelica.Mechanics.Rotational.Examples`` come with reference
results that every Modelica tool is regression-tested against (published by
the Modelica Association in MAP-LIB_ReferenceResults). Rebuilding them here
checks vsj's friction engine (clutches, brakes, breakaway peaks, true
stiction) against those references, with `vsj.compare.tube`:

- `friction`: ``Examples.Friction``: a torque source, three inertias, a
  clutch, a spring-damper and a brake that engages at 0.5 s;
- `coupled_clutches`: ``Examples.CoupledClutches``: four inertias coupled by
  three clutches (peak 1.1) that engage and release at different times.

Each `Example` carries the network, its inputs, initial speeds and duration,
and maps the reference's column names onto vsj's signals (`Example.signals`)
and the reference's friction modes onto vsj's stuck flags (`Example.modes`).
The references ship with vsj (`reference`, in ``vsj/data/msl``); `check` runs
the whole comparison and `figure` draws it; ``vsj msl`` does both from the
shell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from collections.abc import Callable, Mapping

import numpy as np

from . import compare
from .components import Brake, Clutch, Inertia, SpringDamper, TorqueSource
from .inputs import Constant, Input, Sine, Step
from .network import Network, Structure
from .plots import pyplot, save
from .simulate import InitialState, Result, SimulationOptions, simulate


@dataclass(frozen=True)
class Example:
    """One MSL drive train: what to simulate and how to read the reference."""

    name: str
    model: str  # the Modelica class the reference belongs to
    reference_file: str  # in vsj/data/msl
    structure: Structure
    inputs: Mapping[str, Input]
    initial: InitialState
    duration: float
    #: reference column -> function of a result giving the same quantity
    signals: Mapping[str, Callable[[Result], np.ndarray]]
    #: reference element (its ``<name>.mode`` column) -> vsj friction element
    modes: Mapping[str, str] = field(default_factory=dict)

    def simulate(self, step: float = 1e-3) -> Result:
        """Run with true stiction at fixed ``step`` [s], a sample every step."""
        return simulate(self.structure, self.inputs, self.duration,
                        options=SimulationOptions(friction="stiction", step=step,
                                                  output_step=step),
                        initial=self.initial, ports=False)


def _angle(flange: str):
    return lambda r: r[flange]


def _speed(flange: str):
    return lambda r: r[f"{flange}.speed"]


def _relative(a: str, b: str, speed: bool):
    """The MSL's ``phi_rel`` / ``w_rel`` of an element: flange b minus flange a."""
    suffix = ".speed" if speed else ""
    return lambda r: r[b + suffix] - r[a + suffix]


def friction() -> Example:
    """``Rotational.Examples.Friction`` (3 s): inertia 3 (1 kg m^2, 100 rad/s)
    driven by 200 sin(100 t) N m until 0.5 s, a clutch (mu 0.5, 160 N, always
    engaged) to inertia 2 (0.05 kg m^2, 90 rad/s), a spring-damper (160 N m/rad,
    1 N m s/rad) to inertia 1 (1 kg m^2, 90 rad/s), which a brake (mu 0.5,
    1600 N) grips from 0.5 s."""
    net = Network("msl-friction")
    net.add(TorqueSource("torque", "torque"), Inertia("inertia3", 1.0),
            Clutch("clutch", fn_max=160.0, mu=0.5), Inertia("inertia2", 0.05),
            SpringDamper("spring", stiffness=160.0, damping=1.0),
            Brake("brake", fn_max=1600.0, mu=0.5), Inertia("inertia1", 1.0))
    net.connect("torque.flange", "inertia3.flange")
    net.connect("inertia3.flange", "clutch.a").connect("clutch.b", "inertia2.flange")
    net.connect("inertia2.flange", "spring.a").connect("spring.b", "brake.flange")
    net.connect("brake.flange", "inertia1.flange")
    a, b, c = "inertia3.flange", "inertia2.flange", "inertia1.flange"
    return Example(
        name="friction", model="Modelica.Mechanics.Rotational.Examples.Friction",
        reference_file="Friction.csv.gz",
        structure=net.assemble(),
        inputs={"torque": Sine(200.0, 100.0 / (2.0 * math.pi), stop=0.5),
                "clutch_force": Constant(1.0), "brake_force": Step(1.0, 0.5)},
        initial=InitialState(speeds={a: 100.0, b: 90.0, c: 90.0}), duration=3.0,
        signals={"clutch.phi_rel": _relative(a, b, False), "clutch.w_rel": _relative(a, b, True),
                 "inertia3.phi": _angle(a), "inertia3.w": _speed(a),
                 "spring.phi_rel": _relative(b, c, False), "spring.w_rel": _relative(b, c, True)},
        modes={"clutch": "clutch", "brake": "brake"})


def coupled_clutches() -> Example:
    """``Rotational.Examples.CoupledClutches`` (1.5 s): four inertias of
    1 kg m^2 in a row (J1 at 10 rad/s, the others at rest), J1 driven by
    10 sin(2 pi 5 t) N m; clutches (mu 0.5, 20 N, peak 1.1) between them:
    clutch 1 pressed by cos(2 pi 0.2 t) (released once that turns negative),
    clutch 2 from 0.4 s, clutch 3 from 0.9 s."""
    net = Network("msl-coupled-clutches")
    net.add(TorqueSource("torque", "torque"),
            *(Inertia(f"J{i}", 1.0) for i in range(1, 5)),
            *(Clutch(f"clutch{i}", fn_max=20.0, mu=0.5, peak=1.1) for i in range(1, 4)))
    net.connect("torque.flange", "J1.flange")
    for i in range(1, 4):
        net.connect(f"J{i}.flange", f"clutch{i}.a").connect(f"clutch{i}.b", f"J{i + 1}.flange")
    signals = {"J1.phi": _angle("J1.flange"), "J1.w": _speed("J1.flange")}
    for i in range(1, 4):
        a, b = f"J{i}.flange", f"J{i + 1}.flange"
        signals[f"clutch{i}.phi_rel"] = _relative(a, b, False)
        signals[f"clutch{i}.w_rel"] = _relative(a, b, True)
    return Example(
        name="coupled-clutches", model="Modelica.Mechanics.Rotational.Examples.CoupledClutches",
        reference_file="CoupledClutches.csv.gz",
        structure=net.assemble(),
        inputs={"torque": Sine(10.0, 5.0), "clutch1_force": Sine(1.0, 0.2, phase=math.pi / 2),
                "clutch2_force": Step(1.0, 0.4), "clutch3_force": Step(1.0, 0.9)},
        initial=InitialState(speeds={"J1.flange": 10.0}), duration=1.5,
        signals=signals, modes={f"clutch{i}": f"clutch{i}" for i in range(1, 4)})


EXAMPLES: dict[str, Callable[[], Example]] = {"friction": friction,
                                               "coupled-clutches": coupled_clutches}


def reference(example: Example) -> dict[str, np.ndarray]:
    """The Modelica Association's published result for ``example`` (shipped with vsj)."""
    path = Path(str(resources.files("vsj") / "data" / "msl" / example.reference_file))
    return compare.read_csv(path)


@dataclass
class Check:
    """Outcome of `check`: a tube report per signal and, per friction element,
    the samples whose stuck flag differs from the reference's mode and how far
    (in steps) each such sample lies from the nearest reference switch."""

    tubes: list[compare.TubeReport]
    modes: dict[str, dict]

    @property
    def passed(self) -> bool:
        """True if every signal stays inside its tube and every stuck-flag difference lies
        within one step of a switch of the reference."""
        return (all(t.inside for t in self.tubes)
                and all(m["worst_steps"] <= 1 for m in self.modes.values()))

    def summary(self) -> str:
        """The tube reports and the stuck-flag differences, one line each."""
        lines = [str(t) for t in self.tubes]
        for name, m in self.modes.items():
            lines.append(f"{name}: stuck flag differs from the reference at {m['differ']} of "
                         f"{m['samples']} samples, each at most {m['worst_steps']} step(s) "
                         f"from a switch of the reference")
        return "\n".join(lines)


def check(example: Example, result: Result, reference: Mapping[str, np.ndarray], *,
          relative: float = compare.RELATIVE, floor: float = 1e-6) -> Check:
    """Compare ``result`` with the reference columns (`vsj.compare.read_csv`).

    Every mapped signal must stay inside the MSL tube; an element's stuck flag
    (stuck = reference mode 0) may differ from the reference only at samples
    within one step of one of the reference's switches."""
    if not result.success:
        raise ValueError(f"{example.name}: the run failed: {result.message}")
    missing = [c for c in [*example.signals, *(f"{m}.mode" for m in example.modes)]
               if c not in reference]
    if missing:
        raise ValueError(f"{example.name}: the reference lacks column(s) {', '.join(missing)}")
    t_ref = reference["time"]
    tubes = [compare.tube(t_ref, reference[col], result.time, fn(result), relative=relative,
                          floor=floor, name=col) for col, fn in example.signals.items()]
    h = float(result.time[1] - result.time[0])
    modes = {}
    for ref_name, element in example.modes.items():
        mode = reference[f"{ref_name}.mode"]
        ref_stuck = compare.on_grid(t_ref, mode, result.time) == 0
        stuck = result[f"friction.{element}.stuck"] > 0.5
        differ = np.flatnonzero(stuck != ref_stuck)
        switches = np.array([t for t, _, _ in compare.changes(t_ref, mode == 0)])
        if differ.size and switches.size:
            gap = np.abs(result.time[differ][:, None] - switches[None, :]).min(axis=1)
            worst = math.ceil(float(gap.max()) / h - 1e-9)
        else:
            worst = 0 if not differ.size else math.inf
        modes[ref_name] = {"differ": int(differ.size), "samples": int(stuck.size),
                           "worst_steps": worst}
    return Check(tubes=tubes, modes=modes)


def figure(example: Example, result: Result, reference: Mapping[str, np.ndarray], outcome: Check,
           path) -> None:
    """One panel per compared signal (the reference, its tube and vsj's samples)
    and one for the stick phases of every friction element, against the
    reference's modes."""
    plt = pyplot()
    names = list(example.signals)
    fig, axes = plt.subplots(len(names) + 1, 1, figsize=(9, 1.9 * (len(names) + 1) + 0.6),
                             sharex=True, squeeze=False)
    t_ref = reference["time"]
    for ax, name, tube in zip(axes[:, 0], names, outcome.tubes):
        y_ref = reference[name]
        top, bottom = compare._window_extremes(t_ref, y_ref, t_ref, tube.half_width)
        ax.fill_between(t_ref, bottom - tube.half_height, top + tube.half_height, color="0.8",
                        lw=0, label="MSL tube")
        ax.plot(t_ref, y_ref, color="k", lw=0.8, label="reference (Dymola)")
        ax.plot(result.time, example.signals[name](result), color="C1", lw=0, marker=".",
                ms=1.5, label="vsj, 1 sample per step")
        ax.set_ylabel(name, fontsize=8)
        ax.set_title(f"{tube.usage:.2g} of the tube used", fontsize=8, loc="right")
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, loc="best", markerscale=6)
    ax = axes[-1, 0]
    for k, (ref_name, element) in enumerate(example.modes.items()):
        ref_stuck = compare.on_grid(t_ref, reference[f"{ref_name}.mode"], result.time) == 0
        ours = result[f"friction.{element}.stuck"] > 0.5
        ax.fill_between(result.time, 2 * k, 2 * k + 0.8 * ref_stuck, step="post", color="0.6",
                        lw=0, label="stuck, reference" if k == 0 else None)
        ax.fill_between(result.time, 2 * k + 0.9, 2 * k + 0.9 + 0.8 * ours, step="post",
                        color="C1", lw=0, label="stuck, vsj" if k == 0 else None)
    ax.set_yticks([2 * k + 0.85 for k in range(len(example.modes))], list(example.modes),
                  fontsize=8)
    ax.legend(fontsize=7, loc="upper right")
    ax.set_xlabel("time [s]")
    fig.suptitle(f"{example.model}: vsj against the MSL reference", fontsize=10)
    fig.tight_layout()
    save(fig, path, tight=False)

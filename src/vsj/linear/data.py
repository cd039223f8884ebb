"""A linear model as plain data: the matrices, names, units and operating point.

`LinearData` holds what `vsj.linear` computes, without python-control (whose
import is slow): the command line and the file functions work on it. It has
the attributes of a `control.StateSpace` that the analysis functions read
(``A``, ``B``, ``C``, ``D``, ``nstates``, ``state_labels``, ...), so they
accept either; `LinearData.statespace` makes the python-control model
(`vsj.linear.LinearModel`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from collections.abc import Sequence

import numpy as np

from ..errors import InputError
from ..friction import LINEAR_TREATMENTS as FRICTION_TREATMENTS

#: Name of the pivot-position input.
PIVOT_INPUT = "q"


def signal_name(name: str) -> str:
    """vsj's dotted name as a python-control signal name (which reserves ``.`` for
    ``system.signal`` in interconnections): dots become underscores."""
    return name.replace(".", "_")


def select(kind: str, wanted: Sequence[str] | None, available: Sequence[str]) -> list[int]:
    """Indices of the ``wanted`` names in ``available`` (all if None); a name may be
    spelt as a run's result spells it (``theta_x.speed``) or as python-control does
    (``theta_x_speed``). `InputError` names unknown or repeated ones."""
    if wanted is None:
        return list(range(len(available)))
    index = {name: i for i, name in enumerate(available)}
    wanted = [w if w in index else signal_name(w) for w in wanted]
    unknown = [w for w in wanted if w not in index]
    if unknown:
        raise InputError(f"unknown {kind}(s) {', '.join(map(repr, unknown))}; available: "
                         f"{', '.join(available)}")
    if len(set(wanted)) != len(wanted):
        raise InputError(f"{kind}s listed twice: {', '.join(wanted)}")
    return [index[w] for w in wanted]


@dataclass
class LinearData:
    """``dx/dt = A x + B u, y = C x + D u`` around an operating point (deviations, SI)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_labels: list[str]
    input_labels: list[str]
    output_labels: list[str]
    state_units: tuple[str, ...]
    input_units: tuple[str, ...]
    output_units: tuple[str, ...]
    operating_point: dict
    friction: str
    info: dict = field(default_factory=dict)
    name: str = "wrist"

    def __post_init__(self):
        self.A, self.B, self.C, self.D = (np.asarray(m, dtype=float)
                                          for m in (self.A, self.B, self.C, self.D))
        self.state_labels = list(self.state_labels)
        self.input_labels = list(self.input_labels)
        self.output_labels = list(self.output_labels)
        self.state_units = tuple(self.state_units)
        self.input_units = tuple(self.input_units)
        self.output_units = tuple(self.output_units)

    @property
    def nstates(self) -> int:
        """Number of states (rows of ``A``)."""
        return self.A.shape[0]

    @property
    def ninputs(self) -> int:
        """Number of inputs (columns of ``B``)."""
        return self.B.shape[1]

    @property
    def noutputs(self) -> int:
        """Number of outputs (rows of ``C``)."""
        return self.C.shape[0]

    def describe(self) -> str:
        """Sizes, friction, pivot, names and modes, as text (`describe`)."""
        return describe(self)

    def statespace(self):
        """The python-control model (a `vsj.linear.LinearModel`)."""
        from .statespace import LinearModel  # lazy: python-control is heavy

        return LinearModel.from_data(self)


def describe(model) -> str:
    """Sizes, friction, pivot, names and modes of a linear model, as text."""
    from .analysis import modes  # circle: vsj.linear.analysis imports this

    lines = [f"linear model {model.name}: {model.nstates} states, {model.ninputs} inputs, "
             f"{model.noutputs} outputs; friction {model.friction} "
             f"({FRICTION_TREATMENTS.get(model.friction, '')})"]
    if "q" in model.operating_point:
        lines.append(f"  pivot q = {model.operating_point['q'] * 100:.4g} cm (held)")
    lines.append("  states:  " + ", ".join(model.state_labels))
    lines.append("  inputs:  " + ", ".join(f"{n} [{u}]" for n, u in
                                             zip(model.input_labels, model.input_units)))
    lines.append("  outputs: " + ", ".join(model.output_labels))
    for mode in modes(model):
        w, pole = mode["frequency"], mode["pole"]
        if w <= 1e-9 * max(1.0, np.max(np.abs(model.A))):
            lines.append("  pole at 0: a free rigid-body motion")
        elif pole.imag == 0.0:
            lines.append(f"  real pole at {pole.real:.4g} rad/s (time constant "
                         f"{1 / w:.4g} s)")
        else:
            lines.append(f"  mode: {w / (2 * math.pi):.4g} Hz ({w:.4g} rad/s), damping "
                         f"ratio {mode['damping']:.3g}")
    return "\n".join(lines)

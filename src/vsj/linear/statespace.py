"""The python-control face of a linear model: `LinearModel`, a `control.StateSpace`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import control
import numpy as np

from .data import LinearData, describe


class LinearModel(control.StateSpace):
    """A `control.StateSpace` of a network around an operating point, with its provenance.

    Besides everything a StateSpace does (``poles()``, ``step_response``,
    ``bode_plot``, interconnection by signal names), it carries:
    ``operating_point`` (values of the states, inputs and outputs, and ``q``),
    ``friction`` (the treatment, a key of `FRICTION_TREATMENTS`), the units of
    every state, input and output, and ``info`` (where it came from).
    Results of python-control operations are plain StateSpace objects.
    """

    def __init__(self, A, B, C, D, *, states: Sequence[str], inputs: Sequence[str],
                 outputs: Sequence[str], state_units: Sequence[str],
                 input_units: Sequence[str], output_units: Sequence[str],
                 operating_point: Mapping, friction: str, info: Mapping | None = None,
                 name: str = "wrist"):
        super().__init__(np.asarray(A, float), np.asarray(B, float), np.asarray(C, float),
                         np.asarray(D, float), states=list(states), inputs=list(inputs),
                         outputs=list(outputs), name=name)
        self.state_units = tuple(state_units)
        self.input_units = tuple(input_units)
        self.output_units = tuple(output_units)
        self.operating_point = dict(operating_point)
        self.friction = friction
        self.info = dict(info or {})

    @classmethod
    def from_data(cls, data: LinearData) -> "LinearModel":
        """The python-control model of plain `LinearData`, with its labels, units, operating
        point and information."""
        return cls(data.A, data.B, data.C, data.D, states=data.state_labels,
                   inputs=data.input_labels, outputs=data.output_labels,
                   state_units=data.state_units, input_units=data.input_units,
                   output_units=data.output_units, operating_point=data.operating_point,
                   friction=data.friction, info=data.info, name=data.name)

    def describe(self) -> str:
        """Sizes, friction, pivot, names and modes, as text (`vsj.linear.data.describe`)."""
        return describe(self)

"""A wrist as a file for the C engine: what ``vsj export-model`` writes.

The document holds the engine's arrays (`vsj.engine.model`) for inputs held
over each control period, the names and units of the inputs, of the step
function's state and of a set of outputs (each a row that multiplies the
state), the initial state and the solver settings. ``vsj_load_model`` of the
C library (``vsj/engine/c/vsj.h``) reads it; ``examples/c/step_wrist.c`` steps
it one control period at a time. JSON numbers are written in their shortest
form that reads back exactly, so a C program steps the very model Python
does.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from . import __version__
from .params import Parameters
from .simulate import InitialState, SimulationOptions
from .stepper import METHODS, Stepper
from .wrist import WristOptions

FORMAT = "vsj-model"
VERSION = 2

#: The engine arrays, in the order of ``vsj_model``.
ENGINE_ARRAYS = ("dims", "mass", "Minv", "xp", "xc", "xv", "up", "uc", "uv", "par", "code",
                 "src_ch", "src_pos0", "knots", "coef", "cum", "first", "count", "table")


def wrist_stepper(params: Parameters, wrist_options: WristOptions | None = None, *,
                  options: SimulationOptions | None = None, method: str = "dopri",
                  period: float = 1e-3, substeps: int = 4) -> Stepper:
    """The step function of a wrist, as the C engine will run it."""
    return Stepper.wrist(params, wrist_options, period, options=options, method=method,
                         substeps=substeps)


def model_document(stepper: Stepper, *, params: Parameters | None = None,
                   initial: InitialState | None = None, inputs=None,
                   wrist_options: WristOptions | None = None) -> dict:
    """The export document of a stepper (JSON-ready). Its initial state is
    ``initial`` with the velocity sources already running at ``inputs`` (as
    `Stepper.initial_state`; default: at rest)."""
    state0 = stepper.initial_state(initial, inputs)
    signals = [s.name for s in stepper.structure.signals]
    rows = stepper.angle_rows(signals)
    engine = {name: np.asarray(getattr(stepper.model, name)).ravel().tolist()
              for name in ENGINE_ARRAYS}
    doc = {
        "format": FORMAT,
        "version": VERSION,
        "vsj": __version__,
        "description": (f"network {stepper.structure.name!r} for the C engine of vsj: inputs "
                        f"held over each control period; state [x, p, i, sigma] (see vsj.h)"),
        "network": stepper.structure.name,
        "model_options": asdict(wrist_options) if wrist_options is not None else None,
        "parameters": None if params is None else {"name": params.meta.get("name"),
                                                    "origin": params.origin,
                                                    "hash": params.hash()},
        "solver": {"method": stepper.method, "period": stepper.period, "rtol": stepper.rtol,
                   "atol": stepper.atol, "step": stepper.step_size,
                   "substeps": stepper.substeps, "max_steps": stepper.max_steps,
                   "friction": stepper.options.friction},
        "inputs": [{"name": n, "unit": u} for n, u in zip(stepper.input_names,
                                                          stepper.input_units)],
        "state": [{"name": n, "unit": u} for n, u in zip(stepper.state_names,
                                                         stepper.state_units)],
        "initial_state": state0.tolist(),
        "outputs": [{"name": name, "unit": "rad", "row": row.tolist()}
                    for name, row in zip(signals, rows)],
        "engine": engine,
    }
    return doc


def write_model(path: Path, document: dict) -> None:
    """Write an export document (atomically: a failed write leaves no half file)."""
    from .output import atomic_write

    with atomic_write(Path(path)) as handle:
        json.dump(document, handle, allow_nan=False)
        handle.write("\n")


__all__ = ["wrist_stepper", "model_document", "write_model", "METHODS", "FORMAT", "VERSION"]

"""A wrist as a file for the C engine: what ``vsj export-model`` writes.

`model_document` describes a stepper as plain data: the engine's arrays
(`vsj.engine.model`) for inputs held over each control period, the names and
units of the inputs, of the step function's state and of a set of outputs (each a
row that multiplies the state), the initial state and the solver settings.
`program_bytes` writes what the C library reads (``vsj_load_model``, see
``engine/c/load.c``): those settings and names, then the model's own binary form
(``engine/c/blob.c``, the arrays exactly as Python holds them, to the bit), with a
checksum. ``examples/c/step_wrist.c`` steps such a file one control period at a
time, and the FMU carries one.
"""

from __future__ import annotations

import struct
from dataclasses import asdict
from pathlib import Path

import numpy as np

from . import __version__
from .engine.model import ARRAYS
from .engine.plan import METHODS as SCHEME_CODES
from .output import atomic_write
from .params import Parameters
from .simulate import InitialState, SimulationOptions
from .stepper import METHODS, Stepper
from .wrist import WristOptions

FORMAT = "vsj-model"
VERSION = 3
#: The program file's format version (engine/c/load.c reads this one only).
PROGRAM_VERSION = 3

#: The engine arrays, in the order of ``vsj_model`` (c/vsj_layout.h).
ENGINE_ARRAYS = ARRAYS


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
    engine["sizes"] = dict(stepper.model.sizes)
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


def _fnv1a(data: bytes) -> int:
    h = 14695981039346656037
    for byte in data:
        h = ((h ^ byte) * 1099511628211) & 0xFFFFFFFFFFFFFFFF
    return h


def _name(text: str) -> bytes:
    raw = text.encode("utf-8")
    return struct.pack("<q", len(raw)) + raw + b"\0" * (-len(raw) % 8)


def program_bytes(document: dict, stepper: Stepper) -> bytes:
    """The file the C library reads (engine/c/load.c): settings, names, the initial
    state, the output rows, the stepper's model in its binary form, a checksum."""
    solver = document["solver"]
    parts = [b"VSJP", struct.pack("<IQ", PROGRAM_VERSION, 0),
             struct.pack("<qddddqq", SCHEME_CODES[solver["method"]], solver["period"],
                         solver["rtol"], solver["atol"], solver["step"], solver["substeps"],
                         solver["max_steps"]),
             struct.pack("<q", len(document["inputs"]))]
    parts += [_name(i["name"]) for i in document["inputs"]]
    state = np.asarray(document["initial_state"], dtype="<f8")
    parts += [struct.pack("<q", len(state)), state.tobytes(),
              struct.pack("<q", len(document["outputs"]))]
    parts += [_name(o["name"]) for o in document["outputs"]]
    parts += [np.asarray([o["row"] for o in document["outputs"]], dtype="<f8").tobytes()]
    blob = stepper.plan.native.to_bytes()
    parts += [struct.pack("<q", len(blob)), blob, b"\0" * (-len(blob) % 8)]
    data = b"".join(parts)
    return data + struct.pack("<Q", _fnv1a(data))


def write_model(path: Path, document: dict, stepper: Stepper) -> None:
    """Write the program file of ``stepper`` (atomically: a failed write leaves no half
    file)."""
    with atomic_write(Path(path), "wb") as handle:
        handle.write(program_bytes(document, stepper))


__all__ = ["wrist_stepper", "model_document", "program_bytes", "write_model", "METHODS",
           "FORMAT", "VERSION", "PROGRAM_VERSION"]

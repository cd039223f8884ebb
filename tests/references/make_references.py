"""Regression references: trajectories of the main scenarios, stored for the tube tests.

Run from the repository root with vsj installed::

    python tests/references/make_references.py

Each reference is a scenario of `vsj.scenario` (built-in), possibly with a
changed friction law or elastic model, simulated case by case with
`vsj.simulate.simulate` exactly as `vsj simulate` runs it. The file
``<name>.npz`` holds, per case, the sample times (every `DECIMATE`-th output
sample), the signals named by `kept`, the stick/slip transition count and the
ledger's relative residual. `tests/test_regression.py` compares the current
engine with them inside tubes in the manner of the Modelica Standard Library's
regression tests.

All were recorded from the C core once the bundled parameter set counted table
4.1's I_C once, the end-effector included (issue 21); the first set had been
recorded from the numba engine (vsj 0.1.0, commit 43b50eb) and agreed with the
C core inside these tubes.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from vsj import params as parameters
from vsj import scenario as scenarios

HERE = Path(__file__).resolve().parent
#: Keep every DECIMATE-th output sample (10 ms at the scenarios' 1 ms output step).
DECIMATE = 10

#: The DC-motor variant of fig 4.15: the primary motors are armature circuits
#: (`vsj.components.DCMotor`) fed sine voltages 90 degrees apart, two stiffness
#: settings, 4 s (the motors' electrical and the wrist's mechanical dynamics).
DC_MOTORS = {
    "duration": "4 s",
    "model": {"motors": "dc"},
    "inputs": {
        "voltage_1": {"kind": "sine", "amplitude": "1 V", "frequency": "0.5 Hz",
                    "phase": "0 deg", "fade_in": "1 s"},
        "voltage_2": {"kind": "sine", "amplitude": "1 V", "frequency": "0.5 Hz",
                    "phase": "90 deg", "fade_in": "1 s"},
    },
    "cases": [{"label": "q=-1.5cm", "initial": {"q": "-1.5 cm"}},
              {"label": "q=0.5cm", "initial": {"q": "0.5 cm"}}],
}

#: name -> (built-in scenario, overrides of its top-level keys: the [model] and
#: [solver] tables are merged key by key (`MERGED`), any other value replaces the
#: scenario's)
REFERENCES = {
    "fig-4.15-arctan": ("fig-4.15", {}),
    "fig-4.15-stiction": ("fig-4.15", {"solver": {"friction": "stiction"}}),
    "fig-4.15-geometric": ("fig-4.15", {"model": {"elastic": "geometric"}}),
    "fig-4.15-dc-motors": ("fig-4.15", DC_MOTORS),
    "fig-4.14": ("fig-4.14", {}),
    "elastic-bench": ("elastic-bench", {}),
    "planetary-fixed-sun": ("planetary-fixed-sun", {}),
    "planetary-fixed-ring": ("planetary-fixed-ring", {}),
}


#: Top-level tables that an override amends rather than replaces.
MERGED = ("model", "solver")


def kept(name: str) -> bool:
    """Signals in a reference: angles, speeds, the pivot position, and the torques of
    the sources and springs (what a user reads off a run)."""
    if name.startswith(("port.", "friction.", "load.", "motor.")):
        return False
    return not name.endswith((".power", ".energy", ".stiffness"))


def load(name: str):
    """The scenario of reference ``name``, with its overrides applied."""
    base, over = REFERENCES[name]
    scen = scenarios.load(base)
    table = dict(scen.table)
    for key, value in over.items():
        if key in MERGED:
            merged = dict(table.get(key, {}))
            merged.update(value)
            table[key] = merged
        else:
            table[key] = value
    import tomli_w

    return scenarios.loads(tomli_w.dumps(table), f"reference {name}")


def run(name: str) -> dict[str, np.ndarray]:
    """Simulate every case of reference ``name``; arrays keyed ``case/what``."""
    scen = load(name)
    params = parameters.default()
    out = {}
    for case in scen.cases:
        result = scenarios.prepare_case(scen, case, params).run(ports=False)
        if not result.success:
            raise RuntimeError(f"{name} [{case.label}]: {result.message}")
        out[f"{case.label}/time"] = result.time[::DECIMATE]
        for signal in result.columns():
            if kept(signal):
                out[f"{case.label}/{signal}"] = result[signal][::DECIMATE]
        out[f"{case.label}/transitions"] = np.array(sum(result.transitions.values()))
        out[f"{case.label}/relative_residual"] = np.array(result.ledger["relative_residual"])
    return out


def main(names: list[str]) -> None:
    for name in names or list(REFERENCES):
        arrays = run(name)
        np.savez_compressed(HERE / f"{name}.npz", **arrays)
        cases = sorted({key.split("/")[0] for key in arrays})
        print(json.dumps({"reference": name, "cases": cases,
                          "transitions": {c: int(arrays[f"{c}/transitions"]) for c in cases}}))


if __name__ == "__main__":
    main(sys.argv[1:])

"""Regression references: trajectories of the main scenarios, stored for the tube tests.

Run from the repository root with vsj installed::

    python tests/references/make_references.py [NAME ...] [--errors-only]

(``--errors-only`` keeps the stored trajectories and measures their global errors
again.)

Each reference is a scenario of `vsj.scenario` (built-in), possibly with a
changed friction law or elastic model, simulated case by case with
`vsj.simulate.simulate` exactly as `vsj simulate` runs it. The file
``<name>.npz`` holds, per case, the sample times (every `DECIMATE`-th output
sample), the signals named by `kept`, the stick/slip transition count, the
ledger's relative residual and where the stick/slip pattern changes
(`pattern_changes`). `tests/test_regression.py` compares the current
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
#: The adaptive schemes' tolerances every reference was recorded at (the simulator's
#: default then, since loosened to `vsj.engine.plan.RTOL`), under the scenarios' own
#: [solver] keys: the tubes hold runs at the tolerance of their reference, whatever the
#: default.
RECORDED = {"rtol": 1e-8, "atol": 1e-10}


def kept(name: str) -> bool:
    """Signals in a reference: angles, speeds, the pivot position, and the torques of
    the sources and springs (what a user reads off a run)."""
    if name.startswith(("port.", "friction.", "load.", "motor.")):
        return False
    return not name.endswith((".power", ".energy", ".stiffness"))


def load(name: str, solver: dict | None = None):
    """The scenario of reference ``name``, with its overrides applied (and ``solver``
    merged into its [solver] table, if given)."""
    base, over = REFERENCES[name]
    scen = scenarios.load(base)
    table = dict(scen.table)
    table["solver"] = {**RECORDED, **table.get("solver", {})}
    for key, value in list(over.items()) + [("solver", solver or {})]:
        if key in MERGED:
            merged = dict(table.get(key, {}))
            merged.update(value)
            table[key] = merged
        else:
            table[key] = value
    import tomli_w

    return scenarios.loads(tomli_w.dumps(table), f"reference {name}")


def pattern_changes(result) -> np.ndarray:
    """Per output sample, whether any friction element's stick/slip state differs at
    the sample before or after it: there a held force is decided at a threshold and
    may take any value of its Coulomb set (see tests/test_regression.py)."""
    stuck = [result[s] for s in result.columns() if s.endswith(".stuck")]
    change = np.zeros(len(result.time), dtype=bool)
    if stuck:
        flips = np.any(np.diff(np.array(stuck), axis=1) != 0.0, axis=0)
        change[1:] |= flips
        change[:-1] |= flips
    return change


def run(name: str, solver: dict | None = None, params=None,
        labels=None) -> dict[str, np.ndarray]:
    """Simulate every case of reference ``name`` (or those in ``labels``); arrays keyed
    ``case/what``. ``solver`` amends the scenario's [solver] table (a tighter rtol, a
    shorter step); ``params`` replaces the bundled parameter set."""
    scen = load(name, solver)
    params = parameters.default() if params is None else params
    out = {}
    for case in scen.cases:
        if labels is not None and case.label not in labels:
            continue
        result = scenarios.prepare_case(scen, case, params).run(ports=False)
        if not result.success:
            raise RuntimeError(f"{name} [{case.label}]: {result.message}")
        out[f"{case.label}/time"] = result.time[::DECIMATE]
        for signal in result.columns():
            if kept(signal):
                out[f"{case.label}/{signal}"] = result[signal][::DECIMATE]
        out[f"{case.label}/transitions"] = np.array(sum(result.transitions.values()))
        out[f"{case.label}/relative_residual"] = np.array(result.ledger["relative_residual"])
        out[f"{case.label}/pattern_change"] = pattern_changes(result)[::DECIMATE]
    return out


#: A smooth run's error is measured against reruns at REFINE and REFINE^2 times its rtol.
#: The first distance is its truncation error (the rerun's is about REFINE of it). The
#: second is what remains once truncation error is gone: where the friction laws'
#: slopes are steep, the speeds amplify round-off, so that reruns at any tolerance
#: scatter by about that much (a machine that rounds otherwise lands elsewhere in it).
REFINE = 0.01
#: Suffix of the keys that hold each signal's measured global error.
ERROR = "@error"


def smooth_cases(name: str, solver: dict | None = None) -> dict[str, float]:
    """The cases of reference ``name`` (its [solver] amended by ``solver``) that an
    adaptive scheme integrates (dopri or rosenbrock), with their rtol."""
    from vsj.simulate import choose_solver

    scen = load(name, solver)
    out = {}
    for case in scen.cases:
        structure = scenarios.prepare_case(scen, case, parameters.default()).structure
        if choose_solver(structure, case.options) != "timestep":
            out[case.label] = case.options.rtol
    return out


def global_errors(name: str, current: dict, params=None, labels=None,
                  solver: dict | None = None) -> dict[str, np.ndarray]:
    """Each kept signal's error in the smooth cases of ``current`` (a `run` of ``name``
    with its [solver] amended by ``solver``): its largest distance from a rerun at
    `REFINE` times the rtol, plus that rerun's largest distance from one at `REFINE`
    squared times the rtol (the scatter that no tolerance removes), the reruns by the
    same scheme. Keyed ``case/signal@error``."""
    cases = {c: rtol for c, rtol in smooth_cases(name, solver).items()
             if (labels is None or c in labels) and f"{c}/time" in current}
    if not cases:
        return {}
    assert len(set(cases.values())) == 1, "one rtol per reference"
    rtol = next(iter(cases.values()))
    refined = run(name, {**(solver or {}), "rtol": REFINE * rtol}, params, set(cases))
    finer = run(name, {**(solver or {}), "rtol": REFINE ** 2 * rtol}, params, set(cases))
    out = {}
    for key, values in refined.items():
        case, what = key.split("/", 1)
        if case in cases and what not in ("time", "transitions", "relative_residual",
                                           "pattern_change"):
            out[key + ERROR] = np.array(np.max(np.abs(current[key] - values))
                                        + np.max(np.abs(values - finer[key])))
    return out


def main(names: list[str], errors_only: bool = False) -> None:
    """Record the references ``names`` (default all); with ``errors_only`` keep each
    stored trajectory and measure its global errors again."""
    for name in names or list(REFERENCES):
        if errors_only:
            stored = np.load(HERE / f"{name}.npz")
            arrays = {k: stored[k] for k in stored.files if not k.endswith(ERROR)}
        else:
            arrays = run(name)
        arrays.update(global_errors(name, arrays))
        np.savez_compressed(HERE / f"{name}.npz", **arrays)
        cases = sorted({key.split("/")[0] for key in arrays})
        print(json.dumps({"reference": name, "cases": cases,
                          "transitions": {c: int(arrays[f"{c}/transitions"]) for c in cases}}))


if __name__ == "__main__":
    args = sys.argv[1:]
    main([a for a in args if a != "--errors-only"], errors_only="--errors-only" in args)

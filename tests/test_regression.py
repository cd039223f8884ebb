"""Regression against stored trajectories with the Modelica Standard Library's tube.

`tests/references/make_references.py` recorded the main scenarios: fig 4.15
with the arctan law, with stiction, with the geometric elastic model and with
DC motors, fig 4.14, the elastic bench and both planetary benches. Every kept
signal of every case must lie inside the MSL tube around its reference
(`vsj.compare.tube`: the reference swept by a rectangle of half-width ``X`` in
time and half-height ``Y`` in value, each a fraction of the reference's
duration and range, with an absolute floor).

The tube sizes are tighter than the MSL's 2e-3 (`vsj.compare.RELATIVE`), which
is sized for different tools solving the same model; here the same engine
re-runs its own model, so any drift beyond round-off is a change of behaviour:

* smooth friction laws, integrated adaptively to rtol 1e-8: `SMOOTH` (issue
  17's acceptance), a vertical tube (no width in time);
* the time-stepper with stiction, whose stick/slip decisions at round-off
  thresholds may flip single steps: `STICTION`, with a half-width in time of
  1e-4 of the duration (one 1 ms step of fig 4.15's 10 s), so a switch that
  comes a step early or late does not fail.

With stiction the number of stick/slip transitions must agree within
`TRANSITIONS`, and the energy ledger must close as it did. A change of one
parameter by 1 % leaves the tube in every main scenario, so the test can fail.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from vsj import compare
from vsj import scenario as scenarios

REFERENCES = Path(__file__).parent / "references"
_spec = importlib.util.spec_from_file_location("make_references",
                                               REFERENCES / "make_references.py")
make_references = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_references)

#: (relative half-height, relative half-width in time) of the tube.
SMOOTH = (1e-6, 0.0)
STICTION = (1e-4, 1e-4)
#: Relative tolerance on the count of stick/slip transitions.
TRANSITIONS = 0.01
#: Floor of the tube's half-height [the signal's unit], for signals that stay constant (q).
FLOOR = 1e-9
#: Each main scenario with a 1 % change of a parameter it depends on.
CHANGES = {
    "fig-4.15-arctan": ("transmission.viscous", "0.00303 N m s/rad"),
    "fig-4.15-stiction": ("transmission.stiction", "0.0101 N m"),
    "fig-4.15-geometric": ("elastic_element.spring_stiffness", "201.22 N/m"),
    "fig-4.15-dc-motors": ("motor.resistance", "2.323 ohm"),
    "fig-4.14": ("elastic_element.a1", "0.202 N m/rad"),
    "elastic-bench": ("elastic_element.lever_stiction", "0.003232 N m"),
    "planetary-fixed-sun": ("planetary.mesh_stiction", "0.0012625 N m"),
    "planetary-fixed-ring": ("planetary.carrier_bearing_viscous", "0.000101 N m s/rad"),
}
#: Bookkeeping entries of a reference that are not signals.
NOT_SIGNALS = ("time", "transitions", "relative_residual")


def _tube_size(name: str) -> tuple[float, float]:
    scen = make_references.load(name)
    stiction = any(case.options.friction == "stiction" for case in scen.cases)
    return STICTION if stiction else SMOOTH


def tube_reports(name: str, current, labels=None) -> list[compare.TubeReport]:
    """Every kept signal of reference ``name`` (cases ``labels``, default all)
    against the current arrays ``current`` (keyed like the reference)."""
    reference = np.load(REFERENCES / f"{name}.npz")
    relative, time_relative = _tube_size(name)
    reports = []
    for key in reference.files:
        case, what = key.split("/", 1)
        if what in NOT_SIGNALS or (labels is not None and case not in labels):
            continue
        reports.append(compare.tube(reference[f"{case}/time"], reference[key],
                                    current[f"{case}/time"], current[key], relative=relative,
                                    time_relative=time_relative, floor=FLOOR, name=key))
    return reports


def test_every_main_scenario_has_a_reference():
    built_in = set(scenarios.builtin_names())
    recorded = {base for base, _ in make_references.REFERENCES.values()}
    assert recorded == built_in, f"scenarios without a reference: {built_in - recorded}"
    assert set(CHANGES) == set(make_references.REFERENCES)


@pytest.mark.parametrize("name", list(make_references.REFERENCES))
def test_scenario_stays_inside_its_reference_tube(name):
    reference = np.load(REFERENCES / f"{name}.npz")
    current = make_references.run(name)
    assert set(current) == set(reference.files), "the signals of the reference changed"
    for key in reference.files:
        what = key.split("/", 1)[1]
        if what == "time":
            assert np.array_equal(reference[key], current[key]), key
        elif what == "transitions":
            ref, now = int(reference[key]), int(current[key])
            assert abs(now - ref) <= TRANSITIONS * ref, f"{key}: {now}, reference {ref}"
        elif what == "relative_residual":
            assert float(current[key]) <= max(10 * float(reference[key]), 1e-12), key
    reports = tube_reports(name, current)
    assert reports and all(r.samples > 1 for r in reports)
    outside = [str(r) for r in reports if not r.inside]
    assert not outside, "\n".join(outside)


@pytest.mark.parametrize("name", list(CHANGES))
def test_a_one_percent_parameter_change_leaves_the_tube(name, params):
    """The tube is tight enough to see a 1 % change of one parameter (first case only)."""
    key, value = CHANGES[name]
    scen = make_references.load(name)
    case = scen.cases[0]
    changed = params.with_overrides({key: value}, origin="test")
    result = scenarios.prepare_case(scen, case, changed).run(ports=False)
    assert result.success, result.message
    step = make_references.DECIMATE
    current = {f"{case.label}/time": result.time[::step]}
    current.update({f"{case.label}/{s}": result[s][::step] for s in result.columns()})
    reports = tube_reports(name, current, labels={case.label})
    assert max(r.usage for r in reports) > 1.0, f"{key} +1 % stays inside every tube of {name}"


def test_a_one_percent_stiffness_change_leaves_even_the_msl_tube(params):
    """With MSL's own size (2e-3 of the range and of the duration), a 1 % stiffer
    spring still moves the elastic deflection of fig 4.15 outside."""
    scen = make_references.load("fig-4.15-geometric")
    case = scen.cases[0]
    changed = params.with_overrides(dict([CHANGES["fig-4.15-geometric"]]), origin="test")
    result = scenarios.prepare_case(scen, case, changed).run(ports=False)
    reference = np.load(REFERENCES / "fig-4.15-geometric.npz")
    step = make_references.DECIMATE
    report = compare.tube(reference[f"{case.label}/time"], reference[f"{case.label}/phi_1"],
                          result.time[::step], result["phi_1"][::step], name="phi_1")
    assert not report.inside, str(report)

"""Regression against stored trajectories with the Modelica Standard Library's tube.

`tests/references/make_references.py` recorded the main scenarios: fig 4.15
with the arctan law, with stiction, with the geometric elastic model and with
DC motors, fig 4.14, the elastic bench and both planetary benches. Every kept
signal of every case must lie inside the MSL tube around its reference
(`vsj.compare.tube`: the reference swept by a rectangle of half-width ``X`` in
time and half-height ``Y`` in value), with an absolute floor.

The references were recorded on one machine; another CPU, compiler, libm or
BLAS rounds differently. Each tube is therefore sized from what the numerics
allow a correct rerun on any machine, never from differences seen on one:

* smooth friction laws (adaptive Dormand-Prince at the scenario's ``rtol``): the
  reference and the rerun each lie within their own error ``e`` of the exact
  solution (another machine takes other steps). Each run's ``e`` is measured for
  every signal: its distance from a rerun at ``rtol / 100`` (its truncation error),
  plus that rerun's distance from one at ``rtol / 10000`` (the scatter that no
  tolerance removes: where the friction laws' slopes are steep the speeds amplify
  round-off). The tube allows ``e_reference + e_rerun``; it has no width in time;
* the time-stepper with true stiction repeats its arithmetic step for step: what
  differs across machines is round-off, and the stick/slip decisions it can tip.
  Each step decides each element's impulse to `IMPULSE_REL` of the slip scale,
  so the states may drift by at most steps x elements x `IMPULSE_REL` of their
  range (the height), and a decision tipped at a threshold moves a transition by
  one step (the half-width). At a step where an element sticks or slips free, the
  held forces are decided at the threshold and may take any value of their
  Coulomb set: source torques are not compared at samples where the stick/slip
  pattern changes (in the reference or in the rerun).

Each smooth signal's measured error is stored with its reference (recorded there by
`make_references.global_errors`) and measured again in the rerun; the tube allows their
sum. The ledger must close as the numerics say it does (`check_ledger`), and the number
of stick/slip transitions must agree within `transitions_tolerance`. A change of one
parameter by 1 % leaves the tube in every main scenario, so the test can fail.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from vsj import compare
from vsj import scenario as scenarios
from vsj.engine.core import IMPULSE_REL
from vsj.simulate import choose_solver

REFERENCES = Path(__file__).parent / "references"
_spec = importlib.util.spec_from_file_location("make_references",
                                               REFERENCES / "make_references.py")
make_references = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_references)

#: Floor of the tube's half-height [the signal's unit], for signals that stay constant (q).
FLOOR = 1e-9
#: Round-off of the ledger per step: each booked term is a product of a few doubles,
#: rounded to about 1e-16 each; ten of them per step and term.
LEDGER_ROUNDOFF_PER_STEP = 1e-15
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
NOT_SIGNALS = ("time", "transitions", "relative_residual", "pattern_change")
ERROR = make_references.ERROR


def settings(name: str) -> dict[str, dict]:
    """Per case of reference ``name``: its solver, tolerance, step and size."""
    scen = make_references.load(name)
    out = {}
    for case in scen.cases:
        prepared = scenarios.prepare_case(scen, case, make_references.parameters.default())
        options = case.options
        out[case.label] = {
            "solver": choose_solver(prepared.structure, options), "rtol": options.rtol,
            "step": options.step, "steps": case.duration / options.step,
            "elements": len(prepared.structure.frictions)}
    return out


def is_effort(signal: str) -> bool:
    """Source torques: the reactions that a held friction element shares."""
    return signal.startswith("source.") and signal.endswith(".torque")


def tube_reports(name: str, current, labels=None) -> list[compare.TubeReport]:
    """Every kept signal of reference ``name`` (cases ``labels``, default all)
    against the current arrays ``current`` (keyed like the reference, with the
    smooth signals' measured global errors, `make_references.global_errors`)."""
    reference = np.load(REFERENCES / f"{name}.npz")
    cases = settings(name)
    reports = []
    for key in reference.files:
        case, what = key.split("/", 1)
        if what in NOT_SIGNALS or key.endswith(ERROR) or (labels is not None
                                                           and case not in labels):
            continue
        run = cases[case]
        t_ref, y_ref = reference[f"{case}/time"], reference[key]
        t, y = current[f"{case}/time"], current[key]
        span = max(float(np.ptp(y_ref)), FLOOR)
        if run["solver"] != "timestep":
            # each run lies within its own global error of the exact solution
            error = float(reference[key + ERROR]) + float(current[key + ERROR])
            relative, width = max(error / span, np.finfo(float).tiny), 0.0
        else:
            relative = run["steps"] * max(run["elements"], 1) * IMPULSE_REL
            width = run["step"] / float(t_ref[-1] - t_ref[0])
            if is_effort(what):
                keep = ~(reference[f"{case}/pattern_change"]
                         | current[f"{case}/pattern_change"])
                keep[[0, -1]] = True
                t_ref, y_ref, t, y = t_ref[keep], y_ref[keep], t[keep], y[keep]
        reports.append(compare.tube(t_ref, y_ref, t, y, relative=relative, time_relative=width,
                                    floor=FLOOR, name=key))
    return reports


def transitions_tolerance(reference: int) -> int:
    """How far a rerun's count of stick/slip transitions may move: a decision tipped
    at a round-off threshold can create or remove a stick phase of a step or two (its
    start and its end: 2), and one phase in a hundred may be that short."""
    return max(2, int(np.ceil(0.01 * reference)))


def check_ledger(name: str, current) -> None:
    """The ledger closes as the numerics say: smooth runs to their rtol (every term is
    integrated by the same error-controlled steps as the state); time-stepper runs to
    round-off, or, where its springs are non-linear, with a residual that falls at the
    spring integration's second order when the step halves."""
    cases = settings(name)
    halved = None
    for case, run in cases.items():
        residual = float(current[f"{case}/relative_residual"])
        if run["solver"] != "timestep":
            assert residual <= run["rtol"], f"{case}: residual {residual:.3g}"
            continue
        if residual <= run["steps"] * LEDGER_ROUNDOFF_PER_STEP:
            continue
        if halved is None:
            halved = make_references.run(name, {"step": f"{run['step'] / 2!r} s"})
        finer = float(halved[f"{case}/relative_residual"])
        # second order: ratio 4 when the step halves, first order 2: their geometric mean
        assert residual / finer > 2 ** 1.5, f"{case}: residual {residual:.3g}, at h/2 {finer:.3g}"


def test_every_main_scenario_has_a_reference():
    built_in = set(scenarios.builtin_names())
    recorded = {base for base, _ in make_references.REFERENCES.values()}
    assert recorded == built_in, f"scenarios without a reference: {built_in - recorded}"
    assert set(CHANGES) == set(make_references.REFERENCES)


@pytest.mark.parametrize("name", list(make_references.REFERENCES))
def test_scenario_stays_inside_its_reference_tube(name):
    reference = np.load(REFERENCES / f"{name}.npz")
    current = make_references.run(name)
    current.update(make_references.global_errors(name, current))
    assert set(current) == set(reference.files), "the signals of the reference changed"
    for key in reference.files:
        what = key.split("/", 1)[1]
        if what == "time":
            assert np.array_equal(reference[key], current[key]), key
        elif what == "transitions":
            ref, now = int(reference[key]), int(current[key])
            assert abs(now - ref) <= transitions_tolerance(ref), f"{key}: {now}, reference {ref}"
    check_ledger(name, current)
    reports = tube_reports(name, current)
    assert reports and all(r.samples > 1 for r in reports)
    outside = [str(r) for r in reports if not r.inside]
    assert not outside, "\n".join(outside)


#: References rerun with the Rosenbrock steps: a bench driven through ramps (corners in
#: its input) with a stiff, lightly damped torque sensor, and the wrist on DC motors
#: (armature circuits in the state).
ROSENBROCK = ("planetary-fixed-sun", "fig-4.15-dc-motors")


@pytest.mark.parametrize("name", ROSENBROCK)
def test_the_rosenbrock_steps_stay_inside_the_reference_tube(name):
    """Another scheme at the reference's tolerance lies within its own measured error
    of the exact solution, as the reference does: the same tube holds it, and its
    ledger closes to its tolerance."""
    solver = {"method": "rosenbrock"}
    current = make_references.run(name, solver)
    current.update(make_references.global_errors(name, current, solver=solver))
    check_ledger(name, current)
    reports = tube_reports(name, current)
    assert reports and all(r.samples > 1 for r in reports)
    outside = [str(r) for r in reports if not r.inside]
    assert not outside, "\n".join(outside)


def _changed_run(name: str, params):
    """The first case of reference ``name`` with one parameter changed by 1 %, with its
    own global errors."""
    key, value = CHANGES[name]
    changed = params.with_overrides({key: value}, origin="test")
    label = make_references.load(name).cases[0].label
    current = make_references.run(name, params=changed, labels={label})
    current.update(make_references.global_errors(name, current, changed, {label}))
    return label, current


@pytest.fixture(scope="module")
def changed_run(params):
    """`_changed_run` of a reference name, made once in this module: the last test below
    looks at the same changed fig-4.15-geometric run as the tube test of that scenario
    (the run is deterministic, and neither test changes it)."""
    made = {}

    def get(name: str):
        if name not in made:
            made[name] = _changed_run(name, params)
        return made[name]

    return get


@pytest.mark.parametrize("name", list(CHANGES))
def test_a_one_percent_parameter_change_leaves_the_tube(name, changed_run):
    """The tube is tight enough to see a 1 % change of one parameter (first case only)."""
    label, current = changed_run(name)
    reports = tube_reports(name, current, labels={label})
    key = CHANGES[name][0]
    assert max(r.usage for r in reports) > 1.0, f"{key} +1 % stays inside every tube of {name}"


def test_a_one_percent_stiffness_change_leaves_even_the_msl_tube(changed_run):
    """With MSL's own size (2e-3 of the range and of the duration), a 1 % stiffer
    spring still moves the elastic deflection of fig 4.15 outside."""
    label, current = changed_run("fig-4.15-geometric")
    reference = np.load(REFERENCES / "fig-4.15-geometric.npz")
    report = compare.tube(reference[f"{label}/time"], reference[f"{label}/phi_1"],
                          current[f"{label}/time"], current[f"{label}/phi_1"], name="phi_1")
    assert not report.inside, str(report)

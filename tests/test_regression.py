"""Regression against stored trajectories, in the manner of the Modelica Standard Library.

`tests/references/make_references.py` recorded the main scenarios (from the
numba engine, before the C core replaced it). Each signal here must stay
inside a tube around its reference: a half-width of `SMOOTH_TUBE` (smooth
friction laws, integrated adaptively to rtol 1e-8) or `STICTION_TUBE` (the
time-stepper, whose stick/slip decisions at round-off thresholds may flip
single steps) times the signal's range. With stiction the number of stick/slip
transitions must agree within `TRANSITIONS`, and the energy ledger must close
as it did.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

REFERENCES = Path(__file__).parent / "references"
_spec = importlib.util.spec_from_file_location("make_references",
                                               REFERENCES / "make_references.py")
make_references = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(make_references)

#: Tube half-width, relative to each signal's range (issue 17's acceptance).
SMOOTH_TUBE = 1e-6
STICTION_TUBE = 1e-4
#: Relative tolerance on the count of stick/slip transitions.
TRANSITIONS = 0.01
#: Floor of a signal's range [its unit], for signals that stay constant (q).
FLOOR = 1e-9


def _is_stiction(name: str) -> bool:
    scen = make_references.load(name)
    return any(case.options.friction == "stiction" for case in scen.cases)


@pytest.mark.parametrize("name", list(make_references.REFERENCES))
def test_scenario_stays_inside_its_reference_tube(name):
    reference = np.load(REFERENCES / f"{name}.npz")
    current = make_references.run(name)
    assert set(current) == set(reference.files), "the signals of the reference changed"
    tube = STICTION_TUBE if _is_stiction(name) else SMOOTH_TUBE
    for key in reference.files:
        case, what = key.split("/", 1)
        ref, now = reference[key], current[key]
        if what == "time":
            assert np.array_equal(ref, now)
        elif what == "transitions":
            assert abs(int(now) - int(ref)) <= TRANSITIONS * int(ref), key
        elif what == "relative_residual":
            assert float(now) <= max(10 * float(ref), 1e-12), key
        else:
            width = tube * max(np.ptp(ref), FLOOR)
            worst = np.max(np.abs(now - ref))
            assert worst <= width, f"{key}: off by {worst:.3g}, tube {width:.3g}"


def test_the_tube_is_tight_enough_to_see_a_parameter_change(params):
    """A 1 % change of one friction parameter leaves the tube: the test can fail."""
    from vsj import scenario as scenarios

    scen = make_references.load("fig-4.15-arctan")
    case = scen.cases[0]
    changed = params.with_overrides({"transmission.viscous": "0.00303 N m s/rad"}, origin="t")
    result = scenarios.prepare_case(scen, case, changed).run(ports=False)
    ref = np.load(REFERENCES / "fig-4.15-arctan.npz")[f"{case.label}/theta_x"]
    now = result["theta_x"][::make_references.DECIMATE]
    assert np.max(np.abs(now - ref)) > 10 * SMOOTH_TUBE * np.ptp(ref)

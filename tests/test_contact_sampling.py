"""Safety figures that do not depend on the output step (`vsj.simulate.refine`): a run's
contacts sampled again from its plan where its samples could miss a contact or its peak,
against the same run sampled uniformly and finely; the samples it adds lie on the run's
own trajectory; the time-stepper's events its step cannot resolve are marked so."""

from __future__ import annotations

import copy
import json
import pickle
from dataclasses import replace

import numpy as np
import pytest

from scenario_checks import write
from test_environment_scenarios import edit
from vsj import scenario as scenarios
from vsj.cli import main
from vsj.params import default
from vsj.safety import contact_events
from vsj.safety.run_report import report, summary
from vsj.simulate import refine

#: The wall of tests/test_environment_scenarios.py made stiff (1e9 N/m): each impact
#: lasts about 25 us, and the tip bounces on it again and again, the later impacts
#: falling wholly between two samples of the default 1 ms grid. The smooth arctan law
#: on dopri, whose steps resolve the impacts.
STIFF = edit('stiffness = "2e4 N/m"', 'stiffness = "1e9 N/m"',
             edit('friction = "stiction"\nmethod = "timestep"\n', 'friction = "arctan"\n',
                  edit('duration = "0.3 s"', 'duration = "0.25 s"')))
#: Spacing of the uniform reference sampling [s]: 50 samples over a 25 us impact.
FINE = 5e-7


def prepared(text: str):
    scen = scenarios.loads(text, "env.toml")
    (case,) = scen.cases
    return scenarios.prepare_case(scen, case, default())


def test_a_stiff_walls_impacts_read_the_same_from_the_default_grid_as_from_a_fine_one():
    """Every impact and its peak force, read from the 1 ms grid with the run's plan, as
    from the same run sampled every 0.5 us; from the 1 ms samples alone most impacts
    are missed and the largest peak is under-read."""
    prep = prepared(STIFF)
    result = prep.run()
    assert result.success, result.message
    assert result.time[1] - result.time[0] == pytest.approx(1e-3)
    figures = report(result, prep.structure, plan=prep.plan)["wall"]
    alone = report(replace(result, plan=None), prep.structure)["wall"]  # the samples alone
    assert result.plan is prep.plan  # a run carries its plan: report(result) refines too
    assert report(result, prep.structure) == report(result, prep.structure, plan=prep.plan)
    # copies share the (immutable) plan and refine alike; a pickled result has no plan
    for copied in (copy.copy(result), copy.deepcopy(result)):
        assert copied.plan is prep.plan
        assert report(copied, prep.structure)["wall"] == figures
    deep = copy.deepcopy(result)
    assert deep.signals["contact.wall.force"] is not result.signals["contact.wall.force"]
    assert pickle.loads(pickle.dumps(result)).plan is None

    names = ["contact.wall.force", "contact.wall.penetration", "contact.wall.rate"]
    times = np.arange(int(round(0.25 / FINE)) + 1) * FINE
    t, s = refine._sample(prep.plan, times, names)
    assert len(t) == len(times)
    reference = contact_events(t, s["contact.wall.force"])
    assert len(reference) > 20  # the tip bounces on the wall many times
    assert all(ev["resolved"] for ev in figures)
    assert len(figures) == len(reference)
    for ev, ref in zip(figures, reference):
        # the same contact: its start within the reference's spacing and the refined
        # samples' (each at most 1 ms / 32^k)
        assert abs(ev["start"] - ref.start) <= FINE + ev["sample_resolution"]
        # a sampled peak lies below the true one by at most |F''| h^2 / 8: for a half-sine
        # of n samples (pi / n)^2 / 8 of the peak: 5e-4 for the reference's 50, and the
        # refined samples' `REL_TOL`
        assert ev["peak_force"] == pytest.approx(ref.peak_force, rel=refine.REL_TOL + 5e-4)
    # the 1 ms samples alone: few of the impacts if any, the largest under-read by far
    assert len(alone) < len(reference) / 4
    assert max((ev["peak_force"] for ev in alone), default=0.0) \
        < 0.1 * max(ev["peak_force"] for ev in figures)


def test_the_added_samples_lie_on_the_runs_own_trajectory():
    """The samples a run already has keep their bits, and every added sample is what a
    run sampled there gives: the engine's steps do not depend on the samples. The
    time-stepper's added samples lie on its steps."""
    for text, step in ((STIFF, None),
                       (edit('method = "timestep"\n', 'method = "timestep"\nstep = "0.25 ms"\n'),
                        2.5e-4)):
        prep = prepared(text)
        result = prep.run()
        names = ["contact.wall.force", "contact.wall.penetration", "contact.wall.rate"]
        t, s = refine.contact_samples(prep.plan, result.time, {n: result[n] for n in names})
        assert len(t) > len(result.time) and np.all(np.diff(t) > 0.0)
        kept = np.isin(t, result.time)
        assert np.count_nonzero(kept) == len(result.time)
        for name in names:
            assert np.array_equal(s[name][kept], result[name])
        added = t[~kept]
        again_t, again = refine._sample(prep.plan, added, names)
        for name in names:
            assert np.array_equal(again[name], s[name][~kept])
        if step is not None:
            assert np.array_equal(np.round(added / step) * step, added)


def test_the_time_stepper_marks_the_impacts_its_step_cannot_resolve(tmp_path, capsys):
    """Against the stiff wall, the time-stepper's 1 ms step is 40 times an impact's
    duration: its events are marked as not resolved, in meta.json and in the line `vsj
    simulate` prints. The 2e4 N/m wall at a 0.05 ms step is resolved."""
    stiff = edit('friction = "arctan"\n', 'friction = "stiction"\nmethod = "timestep"\n', STIFF)
    prep = prepared(stiff)
    figures = report(prep.run(), prep.structure, plan=prep.plan)["wall"]
    assert figures and not any(ev["resolved"] for ev in figures)
    assert "not resolved" in summary({"wall": figures})[0]

    out = tmp_path / "out"
    assert main(["simulate", str(write(tmp_path, stiff)), "--out", str(out)]) == 0
    assert "event(s) not resolved" in capsys.readouterr().out
    (case,) = json.loads((out / "meta.json").read_text())["cases"]
    assert case["safety"]["wall"] and not any(ev["resolved"] for ev in case["safety"]["wall"])

    fine = edit('method = "timestep"\n', 'method = "timestep"\nstep = "0.05 ms"\n')
    prep = prepared(fine)
    figures = report(prep.run(), prep.structure, plan=prep.plan)["wall"]
    assert figures and all(ev["resolved"] for ev in figures)
    assert "not resolved" not in summary({"wall": figures})[0]


def test_each_of_the_interval_tests_flags_what_it_is_for():
    """`suspect_intervals` on hand-made samples one second apart, each case flagged by one
    test and left alone when its evidence is absent."""
    t = np.array([0.0, 1.0])

    def flagged(force, depth, rate, work=None):
        return bool(refine.suspect_intervals(t, np.array(force), np.array(depth),
                                             np.array(rate), work)[0])

    # apart at both ends: the ledger's work of the contact changed, so it touched between
    assert flagged([0, 0], [-1, -1], [0, 0], np.array([0.5, 0.7]))
    assert not flagged([0, 0], [-1, -1], [0, 0], np.array([0.5, 0.5]))
    # without the ledger: approaching at 0.6 m/s, 1 m away, could touch; at 0.4 could not
    assert flagged([0, 0], [-1, -2], [0.6, -3], None)
    assert not flagged([0, 0], [-1, -2], [0.4, -0.1], None)
    # in contact at both ends, leaving fast at the start and returning at the end: may part
    assert flagged([1, 1], [0.5, 0.5], [-0.3, 0.3])
    assert not flagged([1, 1], [0.5, 0.5], [-0.2, 0.2])
    # the penetration turns inside: its largest value may exceed both ends' by up to
    # min(0.5 + 1, 0.5 + 1) - 0.5 = 1, far more than REL_TOL of it; with rates 1e-4 by
    # 1e-4, below REL_TOL of 0.5001
    assert flagged([1, 1], [0.5, 0.5], [1.0, -1.0])
    assert not flagged([1, 1], [0.5, 0.5], [1e-4 * 0.4, -1e-4 * 0.4])
    # a sharp sampled peak: three samples 1, 2, 1 (second difference 2 > 8e-3 of 2)
    t3 = np.array([0.0, 1.0, 2.0])
    sharp = refine.suspect_intervals(t3, np.array([1.0, 2.0, 1.0]), np.ones(3), np.zeros(3))
    assert sharp.tolist() == [True, True]
    flat = refine.suspect_intervals(t3, np.array([1.999, 2.0, 1.999]), np.ones(3), np.zeros(3))
    assert flat.tolist() == [False, False]

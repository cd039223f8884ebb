"""vsj against the Modelica Standard Library's published reference results.

`vsj.msl` rebuilds MSL drive trains from vsj components; each run at 1 ms
steps must stay inside the MSL regression tube (2e-3 of each signal's span in
time and range, `vsj.compare.tube`) around the Modelica Association's
reference (src/vsj/data/msl), and its clutches and brakes must stick and slip
when the reference's do, within one step.
"""

from dataclasses import replace

import numpy as np
import pytest

from vsj import compare, msl
from vsj.inputs import Constant

from test_motor import LEDGER_ROUNDOFF_PER_STEP

EPS = np.finfo(float).eps


@pytest.fixture(scope="module", params=list(msl.EXAMPLES))
def case(request):
    example = msl.EXAMPLES[request.param]()
    return example, msl.reference(example), example.simulate(1e-3)


def test_every_signal_stays_inside_the_msl_tube(case):
    example, reference, result = case
    outcome = msl.check(example, result, reference)
    assert len(outcome.tubes) == len(example.signals) >= 6
    for tube in outcome.tubes:
        assert tube.inside, str(tube)
        assert tube.samples == len(result.time)


def test_stick_and_slip_agree_with_the_reference_within_one_step(case):
    example, reference, result = case
    outcome = msl.check(example, result, reference)
    h = result.time[1] - result.time[0]
    for name, element in example.modes.items():
        assert outcome.modes[name]["worst_steps"] <= 1, outcome.summary()
        ref_switches = compare.changes(reference["time"], reference[f"{name}.mode"] == 0)
        ours = compare.changes(result.time, result[f"friction.{element}.stuck"] > 0.5)
        assert len(ours) == len(ref_switches) >= 1, name
        for (t_ref, before, after), (t_ours, b, a) in zip(ref_switches, ours):
            assert (before, after) == (b, a)
            # the first sample that shows the switch comes after it, at most a step later
            # (sample times are k h, rounded to a few ulps of their size)
            slack = 8 * EPS * max(t_ref, 1.0)
            assert t_ref - slack <= t_ours <= t_ref + h + slack, (name, t_ref, t_ours)


def test_the_energy_ledger_closes_with_clutches_and_brakes(case):
    example, _, result = case
    # linear springs and dampers, exact impulses: the ledger closes to its round-off, a
    # few roundings per booked term and step
    assert result.ledger["relative_residual"] <= result.solver["steps"] * LEDGER_ROUNDOFF_PER_STEP
    heat = [result.ledger["dissipated"][f"friction {e}"] for e in example.modes.values()]
    assert min(heat) > 0.0


def test_the_tube_sees_a_wrong_parameter():
    # the same drive train with its clutch pressed 5 % less leaves the tube:
    # the check can fail
    example = msl.friction()
    reference = msl.reference(example)
    weaker = replace(example, inputs={**example.inputs, "clutch_force": Constant(0.95)})
    outcome = msl.check(weaker, weaker.simulate(1e-3), reference)
    assert not outcome.passed
    assert any(not t.inside for t in outcome.tubes)


def test_the_reference_reader_names_the_faulty_line(tmp_path):
    bad = tmp_path / "ref.csv"
    bad.write_text('"time","x"\n0,1\n0.1,oops\n')
    with pytest.raises(Exception, match=r"ref.csv, line 3"):
        compare.read_csv(bad)
    bad.write_text('"t","x"\n0,1\n0.1,2\n')
    with pytest.raises(Exception, match="no 'time' column"):
        compare.read_csv(bad)
    bad.write_text('"time","x"\n0,1\n0.2,2\n0.1,3\n')
    with pytest.raises(Exception, match="line 4: time goes backwards"):
        compare.read_csv(bad)


def test_the_tube_follows_the_msl_definition():
    # a step in the reference: a late result is inside while it stays within
    # the half-width in time, outside beyond it
    t_ref = np.array([0.0, 1.0, 1.0, 2.0])
    y_ref = np.array([0.0, 0.0, 1.0, 1.0])
    t = np.linspace(0.0, 2.0, 2001)
    for lag, inside in ((0.003, True), (0.006, False)):
        y = (t >= 1.0 + lag).astype(float)
        report = compare.tube(t_ref, y_ref, t, y, relative=2e-3)
        assert report.half_width == pytest.approx(0.004, rel=EPS, abs=0.0)  # 2e-3 x 2 s
        assert report.inside is inside, (lag, report)
    # the height: 2e-3 of the range, not of the value
    y = np.where(t >= 1.0, 1.0, 0.0) + 0.0019
    assert compare.tube(t_ref, y_ref, t, y).inside
    assert not compare.tube(t_ref, y_ref, t, y + 0.0002, time_relative=0.0).inside


def test_vsj_msl_writes_a_checked_result_set(tmp_path, capsys):
    import json

    from vsj.cli import main

    assert main(["msl", "friction", "--out", str(tmp_path), "--no-plot"]) == 0
    printed = capsys.readouterr().out
    assert "clutch.w_rel: inside 3001 samples" in printed
    record = json.loads((tmp_path / "msl-friction.json").read_text())
    assert record["passed"] is True and len(record["tubes"]) == 6
    assert max(t["usage"] for t in record["tubes"]) < 1
    assert main(["verify", str(tmp_path)]) == 0
    assert main(["msl", "clutches", "--out", str(tmp_path)]) == 2
    assert "allowed: friction, coupled-clutches" in capsys.readouterr().err
    assert main(["msl", "friction", "--step", "0.5 s", "--out", str(tmp_path)]) == 2

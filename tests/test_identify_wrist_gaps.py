"""A log with a gap in its sampling (a logger's dropout) is fitted as the stretches
either side of it, never across it, and the gap is named with its line (issue 31,
item 7)."""

from __future__ import annotations


from vsj import measurements, synth
from vsj.identification.wrist import fit_wrist
from vsj.identification.wrist_model import Setup

from test_identify_wrist import experiment

FREE = ("differential.inertia_x", "transmission.stiction")
#: Two-sided bound on (estimate - truth) / standard error: a calibrated standard error
#: (test_identify_wrist) puts a sound estimate beyond 4 of them with probability 6e-5.
Z_BOUND = 4.0


def test_a_gap_in_a_log_is_named_and_not_fitted_across(params, tmp_path):
    data = synth.wrist(experiment(duration=6.0), params, seed=11)
    columns = {k: (v[0].copy(), v[1]) for k, v in data.columns.items()}
    t = columns["time"][0]
    half = len(t) // 2
    t[half:] += 100.0  # the logger stopped for 100 s half way
    path = tmp_path / "gap.csv"
    measurements.write_log(path, columns, data.comments)
    log = measurements.read_log(path, {**{c: "rad" for c in ()}, **_known()})
    fit = fit_wrist([log], params, Setup(free=FREE), starts=1)
    gap_line = int(log.lines[half])
    notes = [n for n in fit.notes if "no samples for" in n]
    assert len(notes) == 1 and f"line {gap_line}" in notes[0] and "100 s" in notes[0]
    for e in fit.estimates:
        assert e.status == "determined"
        assert abs(e.value - params[e.name]) <= Z_BOUND * e.stderr, (e.name, e.value, e.stderr)


def _known():
    from vsj.identification.wrist_model import all_known_columns

    return all_known_columns()

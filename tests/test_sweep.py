"""vsj sweep: runs equal single runs, whatever the scheduler; resume; failures; bad files."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from vsj import scenario as scenarios
from vsj import sweep
from vsj.cli import main
from vsj.simulate import InitialState, simulate
from vsj.sweep import analysis, runner, sampling, schedulers, store
from vsj.sweep.spec import Distribution

SPEC = """
[sweep]
scenario = "fig-4.15"
duration = "1 s"
seed = 7
samples = 2

[vary]
q = { values = ["-1 cm", "0.5 cm"] }
"elastic_element.lever_length" = { values = ["{lever}", "1 cm"] }
"transmission.stiction" = { distribution = "normal", mean = "10 mN m", sd = "3 mN m" }

[signals]
reference_x = "planetary.sun_teeth / (planetary.sun_teeth + planetary.ring_teeth) / transmission.ratio * (motor_1 + motor_2) / 2"

[metrics]
deflection = { kind = "peak", signal = "phi_1", start = "0.5 s" }
lag = { kind = "lag", signal = "theta_x", reference = "reference_x", frequency = "0.5 Hz" }
tracking = { kind = "tracking_rms", signal = "theta_x", reference = "reference_x" }
energy = { kind = "energy_dissipated" }
spread = "max(phi_1) - min(phi_1)"

[output]
keep = ["theta_x", "phi_1", "spring.vsm_1.deflection", "friction.tr_1.friction.power"]
every = "20 ms"
"""


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory, params):
    from vsj.units import format_quantity

    lever = format_quantity(params["elastic_element.lever_length"], "cm", digits=17)
    path = tmp_path_factory.mktemp("spec") / "spec.toml"
    path.write_text(SPEC.replace("{lever}", lever))
    return path


@pytest.fixture(scope="module")
def reference(spec_file, tmp_path_factory):
    """The sweep run in this process, one chunk per two runs."""
    out = tmp_path_factory.mktemp("ref") / "out"
    assert main(["sweep", str(spec_file), "--out", str(out), "--chunk", "2",
                 "--workers", "1", "--no-plot"]) == 0
    return out


def _arrays(out):
    ds = store.open_dataset(out / store.ZARR)
    return {name: ds[name].values for name in ("signals", "metrics", "status", "steps",
                                               "q", "transmission.stiction")}


def _same(a, b):
    x, y = _arrays(a), _arrays(b)
    for name in x:
        assert np.array_equal(x[name], y[name], equal_nan=True), name
    assert (a / store.METRICS).read_bytes() == (b / store.METRICS).read_bytes()


def test_runs_equal_single_runs_and_failures_are_recorded(reference, params):
    ds = store.open_dataset(reference / store.ZARR)
    status = ds["status"].values
    lever = ds["elastic_element.lever_length"].values
    # a 1 cm lever does not reach past the pivot: those runs are not built, the rest run
    assert np.array_equal(status == 0, lever > 0.02)
    record = store.read_manifest(reference)
    assert record["complete"] and len(record["failed_runs"]) == 4
    assert all("lever_length" in m for m in record["failed_runs"].values())
    csv_rows = (reference / store.METRICS).read_text().splitlines()
    assert len(csv_rows) == 9 and "lever_length must exceed" in csv_rows[-1]
    assert np.all(np.isfinite(ds["metrics"].values[status == 0]))
    assert np.all(ds["metrics"].sel(metric="energy").values[status == 0] > 0)

    scen = scenarios.load("fig-4.15")
    keep = ds["signal"].values.tolist()
    stride = 20  # output.every / the scenario's output_step
    for r in np.flatnonzero(status == 0):
        overrides = {"transmission.stiction": f"{float(ds['transmission.stiction'][r])!r} N*m",
                     "elastic_element.lever_length":
                         f"{float(ds['elastic_element.lever_length'][r])!r} m"}
        case = scen.cases[0]
        run_params = params.with_overrides(overrides, origin="test")
        prep = scenarios.prepare_case(scen, case, run_params)
        single = simulate(prep.structure, prep.inputs, 1.0, options=case.options,
                          initial=InitialState(q=float(ds["q"][r])), ports=False)
        for j, name in enumerate(keep):
            assert np.array_equal(single[name][::stride], ds["signals"].values[r, :, j]), name


def test_one_run_equals_vsj_simulate_on_the_command_line(reference, tmp_path):
    import xarray as xr

    ds = store.open_dataset(reference / store.ZARR)
    r = int(np.flatnonzero(ds["status"].values == 0)[-1])
    scen = (scenarios._builtin_dir() / "fig-4.15.toml").read_text()
    scen = scen[:scen.index("[[cases]]")].replace('duration = "10 s"', 'duration = "1 s"')
    scen += (f'\n[initial]\nq = "{float(ds["q"][r])!r} m"\n[params]\n'
             f'"transmission.stiction" = "{float(ds["transmission.stiction"][r])!r} N*m"\n'
             f'"elastic_element.lever_length" = '
             f'"{float(ds["elastic_element.lever_length"][r])!r} m"\n')
    path = tmp_path / "one.toml"
    path.write_text(scen)
    assert main(["simulate", str(path), "--out", str(tmp_path / "o"), "--no-plot"]) == 0
    with xr.open_dataset(tmp_path / "o" / "trajectory.nc") as single:
        for j, name in enumerate(ds["signal"].values.tolist()):
            assert np.array_equal(single[name].values[0, ::20], ds["signals"].values[r, :, j])


def test_chunk_size_and_worker_processes_do_not_change_the_results(reference, spec_file,
                                                                   tmp_path):
    out = tmp_path / "out"
    assert main(["sweep", str(spec_file), "--out", str(out), "--chunk", "3",
                 "--workers", "2", "--no-plot"]) == 0
    _same(reference, out)


def test_the_last_chunks_run_as_shorter_tasks_whose_parts_join_to_the_chunk(spec_file):
    chunk, runs = 63, 1000
    chunks = [(i, a, np.arange(a, min(runs, a + chunk))) for i, a in
              enumerate(range(0, runs, chunk))]
    plan = schedulers.tasks(chunks, 2)
    # every run once, in order, each task inside its own chunk
    assert np.array_equal(np.concatenate([v for _, _, v in plan]), np.arange(runs))
    assert all(v[0] == a and a // chunk == i == v[-1] // chunk for i, a, v in plan)
    # whole chunks while many runs are left, then ever shorter parts, the last ones
    # a chunk cut into the most parts allowed
    sizes = [len(v) for _, _, v in plan]
    assert sizes[:len(chunks) // 2] == [chunk] * (len(chunks) // 2)
    longest = [max(len(v) for i, _, v in plan if i == k) for k in range(len(chunks))]
    assert longest == sorted(longest, reverse=True)
    assert sizes[-1] <= math.ceil(chunk / schedulers.MAX_PARTS)
    assert max(sum(i == k for i, _, _ in plan) for k in range(len(chunks))) \
        == schedulers.MAX_PARTS
    assert schedulers.tasks(chunks, 1) == chunks  # one worker waits for nobody

    # parts run apart and joined carry the bits of the chunk run whole
    job = runner.job_for(sweep.load(spec_file))
    values = sampling.design(sweep.load(spec_file))[0][:4]
    whole = runner.run_chunk(job, 0, values, threads=1)
    parts = [runner.run_chunk(job, a, values[a:b], threads=1) for a, b in ((2, 4), (0, 1),
                                                                          (1, 2))]
    joined = runner.ChunkResult.joined(parts)
    assert joined.start == 0 and joined.messages == whole.messages
    for name in ("kept", "metrics", "status", "steps"):
        assert getattr(joined, name).tobytes() == getattr(whole, name).tobytes(), name
    with pytest.raises(ValueError, match="from run 2 does not follow the runs 0 to 0"):
        runner.ChunkResult.joined([parts[0], parts[1]])


def test_workers_take_the_pass_through_parameters_found_where_the_sweep_starts(
        spec_file, monkeypatch):
    job = runner.probed(runner.job_for(sweep.load(spec_file)))
    assert set(job.passthrough) == {"transmission.stiction"}
    assert job.key == runner.job_for(sweep.load(spec_file)).key

    def no_probe(self, values):
        raise AssertionError("a worker compiled a probe")

    monkeypatch.setattr(runner.Prepared, "_probe_arrays", no_probe)
    fresh = runner.Prepared(job)  # as a worker process makes it
    assert fresh.passthrough.keys() == job.passthrough.keys()


def test_a_local_dask_cluster_gives_the_same_zarr(reference, spec_file, tmp_path):
    pytest.importorskip("dask.distributed")
    out = tmp_path / "out"
    assert main(["sweep", str(spec_file), "--out", str(out), "--chunk", "2",
                 "--scheduler", "local", "--workers", "2", "--no-plot"]) == 0
    _same(reference, out)


def test_the_local_cluster_runs_its_workers_with_the_quiet_settings():
    """The settings reach the worker processes and the scheduler made with them, and
    this process's own settings are left as they were."""
    import dask
    from dask.distributed import Client

    before = {key: dask.config.get(key, None) for key in schedulers.QUIET}
    with schedulers.local_cluster(1) as cluster, Client(cluster) as client:
        seen = client.run(lambda: {key: dask.config.get(key) for key in schedulers.QUIET})
        stealing = client.run_on_scheduler(
            lambda dask_scheduler: "stealing" in dask_scheduler.extensions)
    assert list(seen.values()) == [schedulers.QUIET]
    assert stealing is False
    assert {key: dask.config.get(key, None) for key in schedulers.QUIET} == before


def test_an_interrupted_sweep_resumed_equals_the_uninterrupted_one(reference, spec_file,
                                                                   tmp_path, monkeypatch):
    out = tmp_path / "out"
    real = schedulers.execute

    def killed_after_two(*args, **kwargs):
        finished = 0
        for item in real(*args, **kwargs):  # chunks, and None where they are written
            if item is not None:
                if finished == 2:
                    raise KeyboardInterrupt
                finished += 1
            yield item

    monkeypatch.setattr(schedulers, "execute", killed_after_two)
    args = ["sweep", str(spec_file), "--out", str(out), "--workers", "1", "--no-plot"]
    assert main([*args, "--chunk", "2"]) == 130
    record = store.read_manifest(out)
    assert sorted(record["done"]) == ["0", "1"] and not record["complete"]
    assert not (out / store.METRICS).exists()
    status = store.open_dataset(out / store.ZARR)["status"].values
    assert np.all(status[4:] == store.NOT_RUN) and np.all(status[:4] != store.NOT_RUN)
    # a process killed while writing chunk 2 leaves part of its region written
    import xarray as xr

    xr.Dataset({"status": ("run", np.array([5, 5]))}).to_zarr(
        out / store.ZARR, region={"run": slice(4, 6)}, consolidated=False)
    monkeypatch.setattr(schedulers, "execute", real)
    assert main(args) == 2  # not without --resume
    assert main([*args, "--resume"]) == 0
    _same(reference, out)
    assert store.read_manifest(out)["done"] == store.read_manifest(reference)["done"]


@pytest.mark.parametrize("write_every", [0.0, 1e9])
def test_the_scheduler_says_when_to_write_what_finished(spec_file, write_every):
    """Workers' chunks are yielded as they finish, and None where the caller writes what
    it holds: after each at once with 0, never before the end with a long interval."""
    job = runner.probed(runner.job_for(sweep.load(spec_file)))
    values, _ = sampling.design(job.spec)
    chunks = [(i, 2 * i, values[2 * i:2 * i + 2]) for i in range(3)]
    items = list(schedulers.execute(job, chunks, None, workers=2, write_every=write_every))
    assert sorted(item[0] for item in items if item is not None) == [0, 1, 2]
    written = [item is None for item in items]
    if write_every == 0.0:  # chunks that finish together are written together
        assert written[-1] and not written[0]
        assert not any(a and b for a, b in zip(written, written[1:]))
    else:
        assert not any(written)


@pytest.mark.parametrize("scheduler", [None, "local"])
def test_a_finished_chunk_is_written_when_due_not_when_the_next_finishes(spec_file,
                                                                          tmp_path, scheduler):
    """A run that is not built (a 1 cm lever) finishes at once, a run of 1000 s of the
    wrist hundreds of milliseconds later (each one task: a run is not split); the
    first's write is due 50 ms after it finished, so the scheduler, this machine's
    worker processes or a Dask cluster's, wakes for it before the second is done."""
    path = tmp_path / "long.toml"
    path.write_text(spec_file.read_text().replace('duration = "1 s"', 'duration = "1000 s"'))
    job = runner.probed(runner.job_for(sweep.load(path)))
    values, _ = sampling.design(job.spec)
    lever = job.spec.varied.index("elastic_element.lever_length")
    short, built = values[values[:, lever] < 0.015][:1], values[values[:, lever] > 0.015][:1]
    chunks = [(0, 0, short), (1, 1, built)]
    items = list(schedulers.execute(job, chunks, scheduler, workers=2, write_every=0.05))
    assert [None if item is None else item[0] for item in items] == [0, None, 1]
    assert items[0][1].status.tolist() == [runner.SETUP_FAILED]


def test_a_stopped_sweep_writes_the_chunks_it_holds(spec_file, tmp_path, monkeypatch):
    """Chunks held for a later write (here: never due) are written and recorded when the
    sweep is stopped, and only they: the store and the manifest agree."""
    monkeypatch.setattr(sweep, "WRITE_EVERY", 1e9)
    real = schedulers.execute

    def stopped_at_the_third(*args, **kwargs):
        finished = 0
        for item in real(*args, **kwargs):
            assert item is not None  # nothing is due before the stop
            if finished == 2:
                raise KeyboardInterrupt
            finished += 1
            yield item

    monkeypatch.setattr(schedulers, "execute", stopped_at_the_third)
    out = tmp_path / "out"
    assert main(["sweep", str(spec_file), "--out", str(out), "--chunk", "2", "--workers", "2",
                 "--no-plot"]) == 130
    done = store.read_manifest(out)["done"]
    assert len(done) == 2
    status = store.open_dataset(out / store.ZARR)["status"].values
    recorded = np.zeros(len(status), dtype=bool)
    for entry in done.values():
        recorded[slice(*entry["runs"])] = True
    assert np.all(status[recorded] != store.NOT_RUN)
    assert np.all(status[~recorded] == store.NOT_RUN)


def test_chunks_past_the_held_bytes_are_written_at_once(spec_file, tmp_path, monkeypatch):
    """Held chunks are bounded by bytes as well as by time: past `HOLD_BYTES` (here any
    chunk) each is written before the next is taken, though no write is due."""
    monkeypatch.setattr(sweep, "WRITE_EVERY", 1e9)
    monkeypatch.setattr(sweep, "HOLD_BYTES", 1)
    real = schedulers.execute
    out = tmp_path / "out"
    seen = []

    def counted(*args, **kwargs):
        for item in real(*args, **kwargs):
            assert item is not None  # nothing is due
            if seen:  # the chunks taken before this one are recorded
                assert len(store.read_manifest(out)["done"]) == len(seen)
            seen.append(item[0])
            yield item

    monkeypatch.setattr(schedulers, "execute", counted)
    assert main(["sweep", str(spec_file), "--out", str(out), "--chunk", "2", "--workers", "2",
                 "--no-plot"]) == 0
    assert len(seen) == 4 and len(store.read_manifest(out)["done"]) == 4


def test_a_failure_to_write_what_a_stopped_sweep_holds_does_not_hide_what_stopped_it(
        spec_file, tmp_path, monkeypatch):
    """A worker's failure ends the sweep with that failure; the chunks it held could not
    be written (a full disk) is said beside it, and none is recorded."""
    monkeypatch.setattr(sweep, "WRITE_EVERY", 1e9)
    real = schedulers.execute

    def failed_at_the_second(*args, **kwargs):
        for n, item in enumerate(real(*args, **kwargs)):
            if n == 1:
                raise RuntimeError("a worker failed")
            yield item

    def full(self, finished):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(schedulers, "execute", failed_at_the_second)
    monkeypatch.setattr(store.Writer, "write", full)
    out = tmp_path / "out"
    with pytest.raises(RuntimeError, match="a worker failed") as info:
        sweep.run(sweep.load(spec_file), out, chunk=2, workers=2, plots=False,
                  show_progress=False)
    assert any("were not written" in note and "No space left" in note
               for note in info.value.__notes__)
    assert store.read_manifest(out)["done"] == {}


@pytest.mark.parametrize("edit, words", [
    (('"transmission.stiction" =', '"transmission.stiffness" ='),
     ["vary.\"transmission.stiffness\"", "unknown parameter 'transmission.stiffness'"]),
    (('mean = "10 mN m"', 'mean = "-10 mN m"'),
     ["vary.\"transmission.stiction\".mean", "'-10 mN m'", "outside the range"]),
    (('kind = "peak"', 'kind = "peek"'), ["metrics.deflection.kind", "'peek'", "unknown metric"]),
    (('spread = "max(phi_1) - min(phi_1)"', 'spread = "max(phi_9)"'),
     ["metrics.spread.expression", "phi_9"]),
    (('spread = "max(phi_1) - min(phi_1)"', 'spread = "__import__(\'os\')"'),
     ["metrics.spread.expression", "not allowed"]),
    (('q = { values', 'q = { value'), ["vary.q", "distribution"]),
    (('every = "20 ms"', 'every = "20 s"'), ["output.every = 20 s", "longer than the run"]),
    (('scenario = "fig-4.15"', 'scenario = "fig-9.99"'),
     ["sweep.scenario = 'fig-9.99'", "unknown scenario"]),
    (('[vary]', '[covariance]\nfile = "nothere.json"\n\n[vary]'),
     ["covariance.file = ", "nothere.json", "cannot read covariance file"]),
])
def test_bad_sweep_files_exit_2_before_any_run(spec_file, tmp_path, capsys, edit, words):
    bad = tmp_path / "bad.toml"
    bad.write_text(spec_file.read_text().replace(*edit))
    out = tmp_path / "out"
    assert main(["sweep", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err
    for word in words:
        assert word in err
    assert not out.exists()


def test_sobol_indices_of_the_ishigami_function_match_the_analytic_values():
    """Ishigami & Homma (1990), a = 7, b = 0.1, x_i uniform on [-pi, pi]; analytic
    indices from Saltelli et al., Global Sensitivity Analysis: The Primer (2008), 4.4."""
    a, b = 7.0, 0.1
    inputs = tuple(Distribution(f"x{i}", "uniform", {"low": -math.pi, "high": math.pi},
                                -math.pi, math.pi) for i in (1, 2, 3))
    unit = sampling.unit_design("random", "sobol", 2 ** 12, 3, seed=11)
    x = sampling.to_values(unit, inputs)
    y = np.sin(x[:, 0]) + a * np.sin(x[:, 1]) ** 2 + b * x[:, 2] ** 4 * np.sin(x[:, 0])
    r = analysis.sensitivity("sobol", sampling.sensitivity_problem(inputs), unit, y, seed=11)
    variance = a ** 2 / 8 + b * math.pi ** 4 / 5 + b ** 2 * math.pi ** 8 / 18 + 0.5
    v1 = 0.5 * (1 + b * math.pi ** 4 / 5) ** 2
    v2 = a ** 2 / 8
    v13 = b ** 2 * math.pi ** 8 * (1 / 18 - 1 / 50)
    s1 = [v1 / variance, v2 / variance, 0.0]
    st = [(v1 + v13) / variance, v2 / variance, v13 / variance]
    # SALib's confidence half-widths are z sigma of a bootstrap (z for CONFIDENCE, 1.96);
    # six checks at 4.3 sigma each fail a sound estimate with probability 1e-4 together
    # (at the half-widths themselves, one in four)
    widen = 4.3 / norm.ppf(0.5 + analysis.CONFIDENCE / 2)
    for k in range(3):
        assert abs(r["S1"][k] - s1[k]) <= widen * r["S1_conf"][k], (k, r)
        assert abs(r["ST"][k] - st[k]) <= widen * r["ST_conf"][k], (k, r)


def test_sobol_indices_of_a_metric_that_does_not_vary_are_nan():
    """A constant output has no variance for the inputs to share: its indices are
    undefined, NaN with a note, not SALib's 0 +- 0 (and no warning of a division by zero)."""
    import warnings

    inputs = tuple(Distribution(f"x{i}", "uniform", {"low": 0.0, "high": 1.0}, 0.0, 1.0)
                   for i in (1, 2))
    unit = sampling.unit_design("random", "sobol", 2 ** 6, 2, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = analysis.sensitivity("sobol", sampling.sensitivity_problem(inputs), unit,
                                 np.full(len(unit), 1.5), seed=3)
    assert all(math.isnan(v) for k in ("S1", "S1_conf", "ST", "ST_conf") for v in r[k])
    assert "same in every run" in r["note"]


def test_a_sobol_sweep_reports_indices_and_a_page(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text("""
[sweep]
scenario = "fig-4.15"
duration = "0.5 s"
samples = 4
[vary]
"transmission.stiction" = { distribution = "uniform", low = "5 mN m", high = "15 mN m" }
"transmission.viscous" = { distribution = "lognormal", median = "3 mN m s", sigma = 0.3 }
[metrics]
deflection = { kind = "peak", signal = "phi_1" }
[output]
every = "50 ms"
""")
    out = tmp_path / "out"
    assert main(["sweep", str(path), "--out", str(out), "--method", "sobol",
                 "--workers", "1"]) == 0
    text = capsys.readouterr().out
    assert "S1" in text and "transmission.stiction" in text
    assert sweep.run_count(sweep.with_method(sweep.load(path), "sobol")) == 16
    page = (out / "summary.html").read_text()
    assert "Sensitivity (sobol)" in page and "data:image/png;base64" in page
    assert (out / "sensitivity.csv").read_text().count("\n") == 3


def test_pass_through_parameters_retune_a_shared_model_bit_for_bit(spec_file):
    """Friction levels reach the compiled arrays unchanged, so their runs retune one
    compiled model; the lever length changes the geometry, so its runs are compiled."""
    from vsj.engine.retune import find_passthrough, retune
    p = runner.prepared(runner.job_for(sweep.load(spec_file)))
    assert set(p.passthrough) == {"transmission.stiction"}
    (slots,) = p.passthrough["transmission.stiction"]
    assert slots[0] == "par" and len(slots[1]) == 2  # the transmission's two bearings
    values = np.array([-0.01, p.base_params["elastic_element.lever_length"], 0.0123456789])
    run = runner._build(p, values)
    alone = runner._compiled(p, p.parameters_for(values)).model
    ran, compiled = run.plan.model._asdict(), alone._asdict()
    for name in compiled:
        if name != "src_pos0":
            assert np.asarray(ran[name]).tobytes() == np.asarray(compiled[name]).tobytes(), name
    assert not np.array_equal(run.plan.model.par, p.base_model.par)

    # a quantity that enters as a product is not pass-through, one that enters as it is is
    def build(v):
        return {"par": np.array([v["a"], 3.0 * v["b"]]), "mass": np.array([1.0])}

    found = find_passthrough(build, {"a": 1.0, "b": 1.0}, {"a": [2.0, 5.0], "b": [2.0, 5.0]})
    assert list(found) == ["a"]
    assert retune(build({"a": 1.0, "b": 1.0}), found, {"a": 7.5})["par"].tolist() == [7.5, 3.0]


def test_runs_that_need_only_state_and_sources_skip_observe_with_the_same_bits(spec_file,
                                                                               tmp_path):
    path = tmp_path / "light.toml"
    path.write_text(spec_file.read_text().replace(
        ', "spring.vsm_1.deflection", "friction.tr_1.friction.power"', "").replace(
        'energy = { kind = "energy_dissipated" }\n', ""))
    job = runner.job_for(sweep.load(path))
    p = runner.prepared(job)
    lever = p.base_params["elastic_element.lever_length"]
    # the first two runs retune one model from other pivot angles (their sources' inputs
    # are evaluated once, started from each run's angles); the third has its own model
    values = np.array([[-0.01, lever, 0.012], [0.004, lever, 0.009],
                       [0.002, 1.05 * lever, 0.011]])
    assert p.light
    light = runner.run_chunk(job, 0, values, threads=1)
    p.light = False
    try:
        full = runner.run_chunk(job, 0, values, threads=1)
    finally:
        p.light = True
    assert light.status.tolist() == [0, 0, 0]
    assert not np.array_equal(light.kept[0], light.kept[1])
    assert light.kept.tobytes() == full.kept.tobytes()
    assert light.metrics.tobytes() == full.metrics.tobytes()

    # runs of one model at other pivot positions start motor_s (which drives the pivot)
    # at other angles: the sources' inputs are evaluated once and each run's starting
    # angles added, as the engine adds them
    origin = p.origin(p.structure, p.base_model)
    plans = [origin.started(InitialState(q=q), p.u0) for q in (-0.01, 0.0, 0.004)]
    assert len({plan.model.src_pos0.tobytes() for plan in plans}) == 3
    batch = runner.run_batch(plans, p.t_out)
    parts = runner._light_columns(p, [runner._Run(p.base_params, plan) for plan in plans],
                                  batch.states)
    n_t, still = len(p.t_out), np.zeros((len(p.t_out), p.layout.n_frictions))
    for i, plan in enumerate(plans):
        observed = plan.engine().observe(p.t_out, batch.states[i], still)
        for name in ("x", "v", "current", "sigma", "u"):
            assert np.array_equal(parts[name][i * n_t:(i + 1) * n_t],
                                  observed[:, p.columns[name]]), name


def test_the_trajectory_file_reads_back_as_the_cases_dataset(tmp_path, params):
    """`write_cases` writes netCDF without xarray; xarray reads it back as the dataset
    `cases_dataset` builds, including a failed run's missing samples and a signal one
    case lacks."""
    import dataclasses

    import xarray as xr

    from vsj.output import cases_dataset, write_cases

    scen = scenarios.load("fig-4.15")
    case = scen.cases[0]
    full = scenarios.prepare_case(scen, case, params).run(duration=0.2)
    short = dataclasses.replace(
        full, time=full.time[:7], success=False,
        signals={k: v[:7] for k, v in full.signals.items() if k != "theta_y"},
        units={k: u for k, u in full.units.items() if k != "theta_y"})
    runs = [("q=0.0cm", full), ("échec", short)]
    write_cases(tmp_path / "t.nc", runs)
    with xr.open_dataset(tmp_path / "t.nc") as ds:
        xr.testing.assert_identical(ds.load(), cases_dataset(runs))
        assert np.isnan(ds["theta_y"].values[1]).all()
        assert np.isnan(ds["theta_x"].values[1, 7:]).all()


def test_a_constant_expression_is_a_constant_signal(tmp_path):
    """A [signals] expression without a signal or ``t`` is documented as a constant
    signal: kept, it holds its value at every sample, and metrics use it as a signal."""
    spec = tmp_path / "constant.toml"
    spec.write_text("""
[sweep]
scenario = "fig-4.15"
duration = "0.2 s"
[vary]
q = { values = ["-1 cm"] }
[signals]
level = "1 + 2"
[metrics]
offset = { kind = "tracking_peak", signal = "level", reference = "theta_x" }
[output]
keep = ["level", "theta_x"]
every = "20 ms"
""")
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-plot"]) == 0
    ds = store.open_dataset(out / store.ZARR)
    kept = ds["signals"].sel(signal="level").values
    assert kept.shape[-1] == 11 and np.all(kept == 3.0)
    theta = ds["signals"].sel(signal="theta_x").values
    # the metric's own subtraction and maximum (its largest offset falls on a kept
    # sample; |a - b| = |b - a| in IEEE arithmetic): equal up to an ulp
    assert ds["metrics"].sel(metric="offset").values[0] == pytest.approx(
        np.max(np.abs(3.0 - theta)), rel=np.finfo(float).eps, abs=0.0)


def test_each_metric_of_a_block_of_runs_is_its_run_alone():
    """Every metric kind and reduction, evaluated on a block of runs at once (as a chunk
    evaluates them), gives each run the bits it has in a block of its own, and the number
    its definition gives."""
    from vsj.sweep.metrics import Context, Evaluator
    from vsj.sweep.spec import Metric

    rng = np.random.default_rng(5)
    t = np.arange(201) * 0.01
    t.flags.writeable = False
    runs = 6
    lag = rng.uniform(0.01, 0.05, runs)
    tau = rng.uniform(0.05, 0.3, runs)
    signals = {"r": np.sin(2 * np.pi * t) * np.ones((runs, 1)),
               "s": np.sin(2 * np.pi * (t - lag[:, None])),
               "step": 1.0 - np.exp(-t / tau[:, None]),
               "p": -rng.uniform(0.0, 1.0, (runs, len(t)))}
    k = rng.uniform(1.0, 2.0, runs)
    transitions = rng.integers(0, 9, runs)
    kinds = {"peak": {"signal": "s", "start": 0.5}, "rms": {"signal": "s"},
             "mean": {"signal": "s", "stop": 1.2}, "final": {"signal": "s"},
             "tracking_rms": {"signal": "s", "reference": "r"},
             "tracking_peak": {"signal": "s", "reference": "r", "start": 0.3},
             "lag": {"signal": "s", "reference": "r", "frequency": 1.0, "start": 0.5},
             "settling_time": {"signal": "step", "tolerance": 0.02},
             "energy_dissipated": {}, "stick_slip_transitions": {}}
    reductions = ["max", "min", "mean", "std", "rms", "peak", "final", "initial", "integral"]
    metrics = [Metric(kind, kind, options, f"metrics.{kind}") for kind, options in kinds.items()]
    metrics += [Metric(f"{f}(s)", "expression", {"expression": f"{f}(s) * k + 1"},
                       f"metrics.{f}") for f in reductions]
    evaluators = [Evaluator(m, set(signals), {"k"}, {}, ["p"]) for m in metrics]

    def context(rows):
        return Context(t, lambda name: signals[name][rows], {"k": k[rows, None]},
                       transitions[rows])

    block = np.column_stack([e(context(slice(None))) for e in evaluators])
    for i in range(runs):
        alone = [e(context(slice(i, i + 1)))[0] for e in evaluators]
        assert np.array_equal(block[i], alone)
    got = dict(zip([m.name for m in metrics], block.T))
    s, r, step, p = (signals[n] for n in ("s", "r", "step", "p"))
    at = {"start": t >= 0.5 - 1e-12, "stop": t <= 1.2 + 1e-12, "0.3": t >= 0.3 - 1e-12}

    def each(fn, x, window=slice(None)):
        """``fn`` of each run's samples in ``window``, one run at a time."""
        return np.array([fn(row[window]) for row in x])

    assert np.array_equal(got["peak"], each(lambda v: np.max(np.abs(v)), s, at["start"]))
    assert np.array_equal(got["rms"], each(lambda v: np.sqrt(np.mean(v ** 2)), s))
    assert np.array_equal(got["mean"], each(np.mean, s, at["stop"]))
    assert np.array_equal(got["final"], s[:, -1])
    assert np.array_equal(got["tracking_rms"], each(lambda v: np.sqrt(np.mean(v ** 2)), s - r))
    assert np.array_equal(got["tracking_peak"],
                          each(lambda v: np.max(np.abs(v)), s - r, at["0.3"]))
    # pure sines: their least-squares fit is exact, up to the solve's rounding
    assert np.allclose(got["lag"], lag, rtol=0, atol=1e-12)
    # the first sample at or after the time the exponential enters its 2 % band
    final = step[:, -1]
    entered = -tau * np.log(np.exp(-t[-1] / tau) + 0.02 * final)
    assert np.all((got["settling_time"] >= entered - 1e-12)
                  & (got["settling_time"] < entered + 0.01))
    assert np.allclose(got["energy_dissipated"], -np.trapezoid(p, t, axis=1), rtol=1e-14)
    assert np.array_equal(got["stick_slip_transitions"], transitions)
    reduced = {"max": np.max(s, axis=1), "min": np.min(s, axis=1), "mean": np.mean(s, axis=1),
               "std": np.std(s, axis=1), "rms": np.sqrt(np.mean(s ** 2, axis=1)),
               "peak": np.max(np.abs(s), axis=1), "final": s[:, -1], "initial": s[:, 0],
               "integral": np.trapezoid(s, t, axis=1)}
    for f, value in reduced.items():
        # one multiplication and one addition after the reduction (integral: the
        # trapezoids summed in another order than numpy's)
        assert np.allclose(got[f"{f}(s)"], value * k + 1, rtol=1e-14, atol=1e-15), f


def test_a_chunk_measured_in_groups_of_runs_gives_the_same_numbers(spec_file, monkeypatch):
    """A chunk's signals and metrics are evaluated on groups of its runs that fit
    `BLOCK_BYTES`; groups of one run give the bits of the whole chunk at once."""
    job = runner.job_for(sweep.load(spec_file))
    values, _ = sampling.design(job.spec)
    whole = runner.run_chunk(job, 0, values, threads=1)
    monkeypatch.setattr(runner, "BLOCK_BYTES", 1)
    apart = runner.run_chunk(job, 0, values, threads=1)
    assert np.isfinite(whole.metrics[whole.status == 0]).all()
    assert np.array_equal(whole.kept, apart.kept, equal_nan=True)
    assert np.array_equal(whole.metrics, apart.metrics, equal_nan=True)


def test_a_sweep_reports_the_kernel_time_of_the_chunks_it_ran(spec_file, tmp_path):
    """`Outcome.kernel` sums the chunks' time in the batch kernel: positive and within
    the sweep's wall time on its one in-process worker; none for a resumed sweep that
    finds nothing left to run."""
    spec = sweep.load(spec_file)
    outcome = sweep.run(spec, tmp_path / "out", workers=1, plots=False, show_progress=False)
    assert outcome.ran == 8 and 0.0 < outcome.kernel < outcome.seconds
    again = sweep.run(spec, tmp_path / "out", resume=True, workers=1, plots=False,
                      show_progress=False)
    assert again.ran == 0 and again.kernel == 0.0


def test_a_varied_parameter_the_scenarios_model_does_not_read_is_warned_of(spec_file):
    """fig-4.15 uses the exponential elastic model (eq 4.5), which does not read the lever's
    length: this spec varies it only to have runs that a parameter relation refuses. The
    sweep says so before it runs; varying what the model reads gives no warning."""
    info = runner.describe(runner.job_for(sweep.load(spec_file)))
    assert len(info["warnings"]) == 1
    text = info["warnings"][0]
    assert str(spec_file) in text and 'vary."elastic_element.lever_length"' in text
    assert "'exponential' elastic model" in text and "fig-4.15" in text
    read_only = "\n".join(line for line in spec_file.read_text().splitlines()
                          if not line.startswith('"elastic_element.lever_length"'))
    info = runner.describe(runner.job_for(sweep.loads(read_only, "read.toml")))
    assert info["warnings"] == []


def test_a_metric_that_is_not_a_finite_number_is_warned_of(tmp_path):
    """A metric whose expression divides by zero or takes the log of 0 gave NaN or inf in
    runs recorded ok, with an empty cell in metrics.csv and no word; the sweep now names
    the metric, how many runs and the first value."""
    spec = sweep.loads('[sweep]\nscenario = "fig-4.15"\nduration = "0.2 s"\nseed = 1\n'
                       '[vary]\nq = { from = "-1 cm", to = "0 cm", count = 2 }\n'
                       '[metrics]\nfine = "max(phi_1)"\nratio = "max(phi_1) / 0"\n'
                       'logged = "log(0 * max(phi_1))"\n', "nan.toml")
    said = []
    outcome = sweep.run(spec, tmp_path / "out", workers=1, plots=False, show_progress=False,
                        announce=said.append)
    assert outcome.failed == 0
    texts = [t for t in outcome.warnings if "not a finite number" in t]
    assert [t.split("'")[1] for t in texts] == ["ratio", "logged"]
    assert all("in 2 of 2 runs that succeeded (run 0:" in t for t in texts)
    assert [f"warning: {t}" for t in texts] == [s for s in said if "finite" in s]


@pytest.mark.parametrize("text, unit", [
    ("max(phi_1) - min(phi_1)", "rad"),        # a spread keeps the unit
    ("-mean(theta_x) + 0.1", "rad"),           # a bare number takes the unit beside it
    ("rms(abs(theta_x - phi_1))", "rad"),
    ("max(theta_x.speed)", "rad/s"),
    ("100 * max(phi_1)", ""),                  # a scale: cm or deg? not said
    ("max(phi_1) / max(phi_2)", ""),           # a ratio
    ("max(phi_1) - max(theta_x.speed)", ""),   # units that do not add
    ("log(max(phi_1))", ""),
    ("max(phi_1) - transmission.viscous", ""),  # a parameter
])
def test_an_expression_metric_has_the_unit_its_signals_give_it(text, unit):
    """metrics.csv heads each metric with its unit; an expression's is inferred only
    where it follows plainly (sums of one unit, functions that keep it), else left
    empty rather than guessed."""
    from vsj.sweep.metrics import expression_unit

    units = {"phi_1": "rad", "phi_2": "rad", "theta_x": "rad", "theta_x.speed": "rad/s"}
    assert expression_unit(text, units) == unit


def test_metrics_csv_heads_an_expression_metric_with_its_unit(tmp_path):
    spec = sweep.loads('[sweep]\nscenario = "fig-4.15"\nduration = "0.2 s"\nseed = 1\n'
                       '[vary]\nq = { from = "-1 cm", to = "0 cm", count = 2 }\n'
                       '[metrics]\nspread = "max(phi_1) - min(phi_1)"\n'
                       'ratio = "max(phi_1) / max(phi_2)"\n', "units.toml")
    sweep.run(spec, tmp_path / "out", workers=1, plots=False, show_progress=False)
    header = (tmp_path / "out" / "metrics.csv").read_text().splitlines()[0]
    assert header.endswith(",spread [rad],ratio")

"""vsj design (issue 37): the optimiser's front against a brute-force grid, the prototype
against the front, a killed run resumed bit for bit, a written design evaluated again by
other vsj commands, and bad design files refused with the key named."""

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from pymoo.indicators.hv import HV
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

from vsj import params
from vsj.cli import main
from vsj.design import Problem, evaluate, loads, optimise, prototype, results
from vsj.design.evaluate import objective_matrix

#: Two cheap objectives that pull apart: a soft softest setting against a stiff
#: stiffest one, over two of the springs' geometry parameters.
RANGE = """
[design]
seed = 7
population = 40
generations = {generations}
[parameters]
"elastic_element.rest_length" = {{ min = "1 cm", max = "2 cm" }}
"elastic_element.anchor_y" = {{ min = "2 cm", max = "3.2 cm" }}
[objectives]
min_stiffness = {{}}
max_stiffness = {{}}
"""
#: Grid points per parameter of the brute-force front (10 000 designs in all).
GRID = 100


@pytest.fixture(scope="module")
def range_run(tmp_path_factory):
    """1600 evaluations (40 designs, 40 generations) of the two-objective problem."""
    out = tmp_path_factory.mktemp("range")
    spec = loads(RANGE.format(generations=40), str(out / "range.toml"))
    (out / "range.toml").write_text(spec.text)
    outcome = optimise.run(spec, out, workers=1)
    results.write(outcome, out, plots=False)
    return spec, outcome, out


def _front(F):
    return F[NonDominatedSorting().do(F, only_non_dominated_front=True)]


def test_the_front_reaches_99_percent_of_the_hypervolume_of_a_brute_force_grid(range_run):
    spec, outcome, _ = range_run
    problem = outcome.problem
    assert 1000 <= len(outcome.archive.x) <= 2000
    grid = [(a, b) for a in np.linspace(0.01, 0.02, GRID) for b in np.linspace(0.02, 0.032, GRID)]
    evaluated = [evaluate(problem, x) for x in grid]
    rows = np.array([row for row, message in evaluated if not message])
    grid_front = _front(objective_matrix(problem, rows))
    _, archive_rows, _, _ = outcome.archive.arrays(problem)
    found = objective_matrix(problem, archive_rows[outcome.front])
    # the reference point: the grid front's worst value of each objective, a tenth of its
    # span beyond, so that the points at the front's ends count
    worst, best = grid_front.max(axis=0), grid_front.min(axis=0)
    reference = worst + 0.1 * (worst - best)
    indicator = HV(ref_point=reference)
    ratio = indicator(found) / indicator(grid_front)
    assert ratio >= 0.99, f"front's hypervolume is {ratio:.4f} of the grid's"
    assert len(outcome.front) >= 10  # a front, not a point: the objectives pull apart


def test_the_prototype_lies_on_or_inside_the_front_and_the_page_says_by_how_much(range_run):
    spec, outcome, out = range_run
    problem = outcome.problem
    x, row, message = prototype(problem)
    assert message == ""
    assert all(v.lo <= b <= v.hi for v, b in zip(spec.variables, x))
    _, archive_rows, _, _ = outcome.archive.arrays(problem)
    front = objective_matrix(problem, archive_rows[outcome.front])
    proto = objective_matrix(problem, row[None, :])[0]
    # on or inside: the prototype beats no design of the front in every objective
    beaten = [k for k, f in enumerate(front) if np.all(proto <= f) and np.any(proto < f)]
    assert beaten == [], f"the prototype dominates front designs {beaten}"
    page = (out / results.PAGE).read_text()
    lines = results.improvements(problem, archive_rows[outcome.front], row)
    assert len(lines) == 2 and all(line in page.replace("&#x27;", "'") for line in lines)
    # the prototype is inside here: some design improves each objective at no worse other
    dominated = [k for k, f in enumerate(front) if np.all(f <= proto)]
    assert dominated and all("%" in line for line in lines)


def test_the_pareto_file_holds_the_front_with_units_and_the_prototype(range_run):
    spec, outcome, out = range_run
    with xr.open_dataset(out / results.PARETO, engine="scipy") as ds:
        assert ds.sizes["design"] == len(outcome.front)
        assert list(ds["parameter"].values) == spec.names
        assert list(ds["objective"].values) == ["min_stiffness", "max_stiffness"]
        assert list(ds["objective_sense"].values) == ["min", "max"]
        assert list(ds["constraint"].values) == ["parameter_relations"]
        assert np.all(ds["margins"].values > 0)
        assert ds.attrs["design_sha256"] == spec.sha256()


SLOW = """
[design]
seed = 3
population = 8
generations = 10
batch = 2
[parameters]
"elastic_element.rest_length" = { min = "1 cm", max = "2 cm" }
"elastic_element.spring_stiffness" = { min = "100 N/m", max = "300 N/m" }
[objectives]
stiffness_ratio = {}
max_energy = {}
[constraints]
no_slack = { deflection = "0.02 rad" }
"""


def _state(out: Path):
    with open(out / optimise.CHECKPOINT, "rb") as handle:
        return pickle.load(handle)


def test_a_killed_optimisation_resumes_to_the_same_front_bit_for_bit(tmp_path):
    spec_path = tmp_path / "slow.toml"
    spec_path.write_text(SLOW)
    spec = loads(SLOW, str(spec_path))
    whole = optimise.run(spec, tmp_path / "whole", workers=1)
    killed = tmp_path / "killed"
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    # two worker processes: the resumed run's designs also match those of one process
    child = subprocess.Popen([sys.executable, "-m", "vsj", "design", str(spec_path), "--out",
                              str(killed), "--workers", "2", "--no-plot"], env=env,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not (killed / optimise.CHECKPOINT).exists() or _state(killed)["generation"] < 2:
            assert child.poll() is None, "the run ended before it could be killed"
            assert time.monotonic() < deadline
            time.sleep(0.02)
        assert child.poll() is None
        os.killpg(child.pid, signal.SIGKILL)
    finally:
        child.wait()
    stopped = _state(killed)["generation"]
    assert 2 <= stopped < spec.generations
    assert main(["design", str(spec_path), "--out", str(killed), "--resume", "--workers", "1",
                 "--no-plot"]) == 0
    resumed = _state(killed)
    assert resumed["generation"] == spec.generations
    assert np.array_equal(np.array(resumed["archive"].x), np.array(whole.archive.x))
    assert np.array_equal(np.array(resumed["archive"].rows), np.array(whole.archive.rows),
                          equal_nan=True)
    with xr.open_dataset(killed / results.PARETO, engine="scipy") as ds:
        _, rows, _, _ = whole.archive.arrays(whole.problem)
        assert np.array_equal(ds["objectives"].values, rows[whole.front][:, :2])
        assert np.array_equal(ds["parameters"].values,
                              np.array(whole.archive.x)[whole.front])


def test_a_written_design_gives_the_recorded_objectives_in_the_datasheet(range_run, tmp_path,
                                                                          capsys):
    spec, outcome, out = range_run
    index = len(outcome.front) // 2
    spec_path = out / "range.toml"
    assert main(["design", str(spec_path), "--out", str(out), "--write-params",
                 str(index)]) == 0
    written = out / f"design-{index}.toml"
    # the file and the message name the model the objectives are of, and the command
    command = f"vsj datasheet --params {written} --elastic {spec.elastic}"
    assert command in capsys.readouterr().out
    assert f"--elastic {spec.elastic}' gives the same numbers" in written.read_text()
    loaded = params.load(written)
    with xr.open_dataset(out / results.PARETO, engine="scipy") as ds:
        recorded = dict(zip(ds["objective"].values.tolist(), ds["objectives"].values[index]))
        for name, value in zip(ds["parameter"].values.tolist(), ds["parameters"].values[index]):
            assert loaded[name] == value  # written exactly
    capsys.readouterr()
    assert main(["datasheet", "--params", str(written), "--points", str(spec.q_points),
                 "--elastic", spec.elastic, "--out", str(tmp_path / "sheet")]) == 0
    sheet = json.loads((tmp_path / "sheet" / "datasheet.json").read_text())["ratings"]
    # the same laws on the same grid: equal but for rounding in the sums (1e-9 relative)
    assert sheet["output_stiffness_min"]["value"] == pytest.approx(recorded["min_stiffness"],
                                                                   rel=1e-9)
    assert sheet["output_stiffness_max"]["value"] == pytest.approx(recorded["max_stiffness"],
                                                                   rel=1e-9)


LAG = """
[design]
elastic = "exponential"
[parameters]
"elastic_element.a1" = { min = "0.1 N m/rad", max = "0.3 N m/rad" }
[objectives]
tracking_lag = { stiffness = "0.3 N m/rad" }
impact_force = { stiffness = "0.3 N m/rad" }
"""


def test_a_written_design_gives_the_recorded_lag_and_impact_force_in_the_study(tmp_path, capsys):
    spec = loads(LAG, str(tmp_path / "lag.toml"))
    problem = Problem(spec, params.default())
    x = [0.25]
    row, message = evaluate(problem, x)
    assert message == ""
    q = row[problem.index("q_at_0p3")]
    assert row[problem.index("stiffness_reach_0p3")] > 0
    path = tmp_path / "design.toml"
    path.write_text(results.params_text(spec, tmp_path, spec.names, x, "a design", {}))
    capsys.readouterr()
    assert main(["study", "tracking-safety", "--params", str(path), "--q", f"{float(q)!r} m",
                 "--out", str(tmp_path / "study")]) == 0
    study = json.loads((tmp_path / "study" / "tracking-safety.json").read_text())
    # the same simulations of the same design: equal to rounding (1e-9 relative)
    assert study["lag"][0] == pytest.approx(row[0], rel=1e-9)
    assert study["peak_force"][0] == pytest.approx(row[1], rel=1e-9)


@pytest.mark.parametrize("change, key", [
    (('"elastic_element.rest_length"', '"elastic_element.rest_lenght"'),
     "elastic_element.rest_lenght"),
    (('min = "1 cm"', 'min = "1 N"'), "min"),
    (('min = "1 cm", max = "2 cm"', 'min = "2 cm", max = "1 cm"'), "rest_length"),
    (("min_stiffness = {}", "min_stifness = {}"), "min_stifness"),
    (("max_stiffness = {}", 'max_stiffness = { sense = "up" }'), "sense"),
    (("seed = 7", 'seed = 7\nelastic = "exponential"'), "does not read elastic_element.rest_length"),
])
def test_a_bad_design_file_is_refused_naming_the_key(tmp_path, capsys, change, key):
    path = tmp_path / "bad.toml"
    path.write_text(RANGE.format(generations=2).replace(*change))
    assert main(["design", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert key in err and "Traceback" not in err and str(path) in err


def test_an_infeasible_problem_is_reported_as_such(tmp_path, capsys):
    path = tmp_path / "infeasible.toml"
    path.write_text(RANGE.format(generations=1).replace("population = 40", "population = 4")
                    + '[constraints]\nend_stop = { torque = "1000 N m" }\n')
    assert main(["design", str(path), "--out", str(tmp_path / "out"), "--workers", "1",
                 "--no-plot"]) == 1
    err = capsys.readouterr().err
    assert "no feasible design" in err and "Traceback" not in err
    assert "No feasible design" in (tmp_path / "out" / results.PAGE).read_text()
    with xr.open_dataset(tmp_path / "out" / results.PARETO, engine="scipy") as ds:
        assert "design" not in ds.sizes and ds.attrs["feasible_evaluations"] == 0


def test_generations_on_dask_give_the_designs_of_one_process(tmp_path):
    """Each generation is a batch on the same cluster, the problem scattered once."""
    spec = loads(RANGE.format(generations=3).replace("population = 40", "population = 8"),
                 str(tmp_path / "dask.toml"))
    here = optimise.run(spec, tmp_path / "here", workers=1)
    there = optimise.run(spec, tmp_path / "there", scheduler="local", workers=1)
    assert np.array_equal(np.array(there.archive.x), np.array(here.archive.x))
    assert np.array_equal(np.array(there.archive.rows), np.array(here.archive.rows),
                          equal_nan=True)


def test_nsga3_stopped_after_a_generation_resumes_to_the_same_designs(tmp_path):
    """NSGA-III's state pickles too (its tournament is pymoo's, wrapped at module level);
    an interruption right after a checkpoint is the kill test's case in one process."""
    text = (RANGE.format(generations=3).replace("population = 40",
                                                 'population = 12\nalgorithm = "nsga3"')
            + "stiffness_ratio = {}\n")
    spec = loads(text, str(tmp_path / "nsga3.toml"))
    whole = optimise.run(spec, tmp_path / "whole", workers=1)

    def stop(text):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        optimise.run(spec, tmp_path / "stopped", workers=1, say=stop)
    assert _state(tmp_path / "stopped")["generation"] == 1
    resumed = optimise.run(spec, tmp_path / "stopped", resume=True, workers=1)
    assert resumed.ran == 2 and len(resumed.archive.x) == 36
    assert np.array_equal(np.array(resumed.archive.x), np.array(whole.archive.x))
    assert np.array_equal(resumed.front, whole.front)


@pytest.mark.parametrize("algorithm", ["nsga2", "nsga3"])
def test_every_random_draw_comes_from_the_seeded_generator(tmp_path, monkeypatch, algorithm):
    """A generator made without a seed would make two runs with one seed differ: none is
    made while the optimiser runs, ties of equally infeasible designs included (designs
    that miss the end-stop torque or are unstable meet in its tournaments)."""
    unseeded = []
    make = np.random.default_rng

    def probe(seed=None, *args, **kwargs):
        if seed is None:
            unseeded.append(seed)
        return make(seed, *args, **kwargs)

    spec = loads(RANGE.format(generations=6).replace(
        "population = 40", f'population = 12\nalgorithm = "{algorithm}"')
        + '[constraints]\nend_stop = { torque = "0.11 N m" }\n', str(tmp_path / "a.toml"))
    monkeypatch.setattr(np.random, "default_rng", probe)
    outcome = optimise.run(spec, tmp_path / "out", workers=1)
    infeasible = sum(1 for s, r in zip(outcome.archive.status, outcome.archive.rows)
                     if s != 0 or min(r[2:]) < 0)
    assert infeasible >= 5 and unseeded == []

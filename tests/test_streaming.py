"""Long runs streamed (issue 31, item 14): `vsj simulate` writes each block of samples
into trajectory.nc as the engine produces it, so memory stays flat however long the
run; the blocks do not change the result, so the streamed file holds exactly what a run
kept in memory gives."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import xarray as xr

from vsj import scenario as scenarios
from vsj.cli import main
from vsj.errors import InputError
from vsj.output import verify, write_cases, write_trajectory
from vsj.simulate import driver

from conftest import SHORT_SCENARIO

#: A block of a few hundred samples: many blocks even in a short run.
SMALL_BLOCK_BYTES = 2 ** 18


def _scenario(tmp_path, text: str, name: str) -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


STICTION = SHORT_SCENARIO.replace('friction = "arctan"', 'friction = "stiction"').replace(
    'duration = "0.3 s"', 'duration = "1.5 s"').replace('output_step = "10 ms"',
                                                       'output_step = "1 ms"')
SMOOTH = SHORT_SCENARIO.replace('duration = "0.3 s"', 'duration = "1.5 s"').replace(
    'output_step = "10 ms"', 'output_step = "1 ms"') + """
[[cases]]
label = "stiff"
initial = { q = "-1.5 cm" }

[[cases]]
label = "soft"
initial = { q = "0.5 cm" }
"""


#: the same with the Rosenbrock steps (their Hermite samples between steps, a block's
#: end anywhere in a step)
ROSENBROCK = SMOOTH.replace('friction = "arctan"', 'friction = "arctan"\nmethod = "rosenbrock"')


@pytest.mark.parametrize("text", [SMOOTH, ROSENBROCK, STICTION],
                         ids=["dopri", "rosenbrock", "time-stepper"])
def test_streamed_file_equals_the_run_kept_in_memory(tmp_path, monkeypatch, text):
    """Streamed in small blocks (many of them) against the same run kept in memory in
    one block: every value of every signal equal to the bit, and the CSV made from the
    file equal, byte for byte, to the one made from the results in memory."""
    path = _scenario(tmp_path, text, "run.toml")
    runs = scenarios.run(path)
    whole = [(run.case.label, run.result) for run in runs]
    assert all(r.success for _, r in whole)
    expected = {SMOOTH: "dopri", ROSENBROCK: "rosenbrock", STICTION: "timestep"}[text]
    assert all(r.solver["name"] == expected for _, r in whole)
    write_cases(tmp_path / "memory.nc", whole)
    write_trajectory(tmp_path / "memory.csv", whole)
    monkeypatch.setattr(driver, "BLOCK_BYTES", SMALL_BLOCK_BYTES)
    assert _samples_per_block(path) < len(whole[0][1].time) / 4  # many blocks
    out = tmp_path / "out"
    assert main(["simulate", path, "--out", str(out), "--csv", "--no-plot"]) == 0
    streamed, memory = xr.open_dataset(out / "trajectory.nc"), \
        xr.open_dataset(tmp_path / "memory.nc")
    assert set(streamed.data_vars) == set(memory.data_vars)
    for name in memory.data_vars:
        assert np.array_equal(streamed[name].values, memory[name].values, equal_nan=True), name
        assert streamed[name].attrs.get("units") == memory[name].attrs.get("units"), name
    assert list(streamed.case.values) == list(memory.case.values)
    assert (out / "trajectory.csv").read_bytes() == (tmp_path / "memory.csv").read_bytes()
    assert verify(out) == []


def _samples_per_block(path) -> int:
    from vsj import params
    from vsj.engine import compile_model

    scen = scenarios.load(path)
    case = scenarios.prepare_case(scen, scen.cases[0], params.default())
    layout = compile_model(case.structure, case.inputs, scen.cases[0].duration)[1]
    return driver.block_samples(case.structure, layout, True)


def test_a_failed_run_streams_what_it_reached_and_nan_after(tmp_path, monkeypatch, params):
    """A run that leaves the pivot's range part of the way: the file holds its samples up
    to the failure, NaN after, as the run kept in memory does."""
    text = SHORT_SCENARIO.replace('duration = "0.3 s"', 'duration = "2 s"') + """
[inputs.motor_s]
kind = "constant"
value = "200 rad/s"
"""
    path = _scenario(tmp_path, text, "fails.toml")
    run = scenarios.run(path)[0]
    assert not run.result.success and "pivot" in run.result.message
    reached = len(run.result.time)
    monkeypatch.setattr(driver, "BLOCK_BYTES", SMALL_BLOCK_BYTES)
    out = tmp_path / "out"
    assert main(["simulate", path, "--out", str(out), "--no-plot"]) == 1
    ds = xr.open_dataset(out / "trajectory.nc")
    theta = ds["theta_x"].values[0]
    assert 0 < reached < len(theta)
    assert np.array_equal(theta[:reached], run.result["theta_x"])
    assert np.all(np.isnan(theta[reached:]))
    assert int(ds["success"].values[0]) == 0
    ds.close()
    reference = tmp_path / "memory.nc"  # written from memory: the samples reached only
    write_cases(reference, [(run.case.label, run.result)])
    memory = xr.open_dataset(reference)
    assert np.array_equal(memory["theta_x"].values[0], theta[:reached])


def test_the_memory_guard_reads_the_process_limit(tmp_path):
    """Under an address-space limit (ulimit -v) that the run's samples would exceed in
    memory, the Python API refuses the run up front and names the limit, while vsj
    simulate, which streams, runs it within the same limit."""
    text = SHORT_SCENARIO.replace('duration = "0.3 s"', 'duration = "300 s"').replace(
        'output_step = "10 ms"', 'output_step = "1 ms"')
    path = _scenario(tmp_path, text, "long.toml")
    out = tmp_path / "out"
    code = f"""
import resource, sys
from vsj import scenario
from vsj.cli import main
from vsj.errors import InputError
with open("/proc/self/status") as handle:
    mapped = [int(l.split()[1]) * 1024 for l in handle if l.startswith("VmSize:")][0]
# room for 300 s of samples' blocks, not for the samples themselves (0.3 GiB)
resource.setrlimit(resource.RLIMIT_AS, (mapped + 2 ** 29, resource.RLIM_INFINITY))
try:
    scenario.run({path!r})
except InputError as exc:
    print("refused:", exc)
else:
    sys.exit(1)
sys.exit(3 if main(["simulate", {path!r}, "--out", {str(out)!r}, "--no-plot"]) == 0 else 2)
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 3, done.stdout + done.stderr
    assert "address-space limit (ulimit -v)" in done.stdout
    assert "stream the run to a file" in done.stdout
    ds = xr.open_dataset(out / "trajectory.nc")
    assert ds.sizes["time"] == 300001 and not np.isnan(ds["theta_x"].values).any()


def test_a_killed_long_simulation_leaves_nothing_and_reruns_identically(tmp_path):
    """vsj simulate killed (SIGKILL) at random moments of a run of many blocks, then run
    again: the directory holds exactly what an uninterrupted run writes, no temporary
    file is left beside or in it."""
    text = SHORT_SCENARIO.replace('duration = "0.3 s"', 'duration = "60 s"').replace(
        'output_step = "10 ms"', 'output_step = "1 ms"')
    path = _scenario(tmp_path, text, "long.toml")
    parent = tmp_path / "work"
    parent.mkdir()
    out = parent / "out"
    argv = [sys.executable, "-m", "vsj", "simulate", path, "--out", str(out), "--no-plot"]
    # the uninterrupted run, timed for the kills below, is the reference every rerun
    # must equal byte for byte
    started = time.perf_counter()
    assert subprocess.run(argv, capture_output=True).returncode == 0
    whole = time.perf_counter() - started
    expected = (out / "trajectory.nc").read_bytes()
    assert verify(out) == []
    rng = random.Random(31)
    for _ in range(4):
        import shutil

        shutil.rmtree(out, ignore_errors=True)
        process = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(rng.uniform(0.2, 0.9) * whole)
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        deadline = time.monotonic() + 30  # the watchdog clears the staging directory
        while any(p.name.startswith(".") for p in parent.iterdir()) \
                and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not [p.name for p in parent.iterdir() if p.name.startswith(".")]
        assert subprocess.run(argv, capture_output=True).returncode == 0
        assert (out / "trajectory.nc").read_bytes() == expected
        assert verify(out) == []
        assert not [p.name for p in out.iterdir() if p.name.startswith(".")]


def test_the_memory_guard_reads_the_control_groups_limit(tmp_path, monkeypatch):
    """A control group's limit less its use bounds what a run may take: with 64 MiB left
    in the group, a run whose samples need more is refused up front, naming the limit;
    an unlimited group ("max", cgroup v2's word) leaves the decision to the others."""
    limit, usage = tmp_path / "memory.max", tmp_path / "memory.current"
    limit.write_text(f"{2 ** 31}\n")
    usage.write_text(f"{2 ** 31 - 2 ** 26}\n")
    monkeypatch.setattr(driver, "CGROUP_FILES", ((str(limit), str(usage)),))
    left, what = driver.available_memory()
    assert what == "the control group's memory limit" and left == 2 ** 26
    text = SHORT_SCENARIO.replace('duration = "0.3 s"', 'duration = "300 s"').replace(
        'output_step = "10 ms"', 'output_step = "1 ms"')
    with pytest.raises(InputError, match="control group's memory limit"):
        scenarios.run(str(_scenario(tmp_path, text, "long.toml")))
    limit.write_text("max\n")
    assert driver.available_memory()[1] != "the control group's memory limit"

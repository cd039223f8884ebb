"""vsj sweep hardened (issue 31): resume checks what the runs depend on, finished chunks are
checked, damaged stores are rebuilt, vsj verify checks sweeps and names foreign files,
write failures end with a remedy, and bad windows, frequencies and pivot positions are
refused before any run."""

from __future__ import annotations

import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import zarr

from vsj import sweep
from vsj.cli import main
from vsj.output import MANIFEST, verify
from vsj.sweep import schedulers, store

SPEC = """
[sweep]
scenario = "fig-4.15"
duration = "0.3 s"
params = "child.toml"
seed = 7
samples = 2

[vary]
q = { values = ["-1 cm", "0.5 cm"] }
"transmission.viscous" = { distribution = "normal", mean = "3 mN m s", sd = "1 mN m s" }

[metrics]
deflection = { kind = "peak", signal = "phi_1", start = "0.1 s" }
tracking = { kind = "tracking_rms", signal = "theta_x", reference = "phi_1" }

[output]
keep = ["theta_x", "phi_1"]
every = "20 ms"
"""
#: A parameter set that extends another, which holds the value item 1 changes.
PARENT = """extends = "second_prototype"
[transmission]
stiction = { value = "4 mN m", source = "test" }
"""
CHILD = 'extends = "sets/parent.toml"\n'
#: Runs per chunk of every sweep here: one, so that each run is a chunk of its own.
CHUNK = ["--chunk", "1", "--workers", "1", "--no-plot"]


def _inputs(directory):
    """The sweep file and its parameter files, the parent in a subdirectory (``extends``
    paths are relative to the file that names them, not to the working directory)."""
    (directory / "sets").mkdir(parents=True, exist_ok=True)
    (directory / "sets" / "parent.toml").write_text(PARENT)
    (directory / "child.toml").write_text(CHILD)
    (directory / "s.toml").write_text(SPEC)
    return directory / "s.toml"


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted sweep: 4 runs, one chunk each; its spec and output directory."""
    base = tmp_path_factory.mktemp("reference")
    spec = _inputs(base)
    out = base / "out"
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK]) == 0
    return spec, out


def _arrays(out):
    group = zarr.open_group(out / store.ZARR, mode="r")
    return {name: group[name][...] for name in ("signals", "metrics", "status", "steps", "q",
                                                "transmission.viscous")}


def _same(a, b):
    """The two sweeps hold the same numbers, bit for bit, and the same metrics.csv."""
    x, y = _arrays(a), _arrays(b)
    for name in x:
        assert x[name].tobytes() == y[name].tobytes(), name
    assert (a / store.METRICS).read_bytes() == (b / store.METRICS).read_bytes()


def _copy(reference, tmp_path):
    """The reference's sweep file, and a copy of its directory in ``tmp_path``."""
    spec, out = reference
    shutil.copytree(out, tmp_path / "out")
    return spec, tmp_path / "out"


def _interrupted(spec, out, monkeypatch, after=2):
    """The sweep killed (Ctrl-C) once ``after`` chunks are done."""
    real = schedulers.execute

    def interrupted(*args, **kwargs):
        finished = 0
        for item in real(*args, **kwargs):  # chunks, and None where they are written
            if item is not None:
                if finished == after:
                    raise KeyboardInterrupt
                finished += 1
            yield item

    monkeypatch.setattr(schedulers, "execute", interrupted)
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK]) == 130
    monkeypatch.setattr(schedulers, "execute", real)
    assert len(store.read_manifest(out)["done"]) == after


def _unfinish(out, drop=()):
    """``out`` as a process killed after its chunks but ``drop`` left it: the chunks
    ``drop`` not recorded, the tables not written."""
    record = json.loads((out / store.MANIFEST).read_text())
    for index in drop:
        record["done"].pop(str(index))
    record["complete"] = False
    record.pop("files", None)
    (out / store.MANIFEST).write_text(json.dumps(record))
    (out / store.METRICS).unlink()
    (out / "summary.html").unlink()


# --- item 1: the resumed sweep's parameter set is the resolved one -------------------

def test_resume_refuses_a_parameter_set_changed_in_a_file_it_extends(reference, tmp_path,
                                                                      monkeypatch, capsys):
    spec = _inputs(tmp_path)
    out = tmp_path / "out"
    _interrupted(spec, out, monkeypatch)
    before = _arrays(out)
    parent = tmp_path / "sets" / "parent.toml"
    parent.write_text(PARENT.replace("4 mN m", "40 mN m"))
    capsys.readouterr()
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 2
    err = capsys.readouterr().err
    assert "parameter set" in err and "child.toml" in err
    assert "transmission.stiction: 0.004 N*m there, 0.04 N*m now" in err
    assert len(store.read_manifest(out)["done"]) == 2
    for name, values in _arrays(out).items():
        assert values.tobytes() == before[name].tobytes(), name
    # the same value written in other units is the same parameter set; and the parent is
    # found from the child's directory, whatever the working directory
    parent.write_text(PARENT.replace('"4 mN m"', '"0.004 N m"'))
    monkeypatch.chdir(tmp_path / "sets")
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 0
    _same(reference[1], out)


# --- item 3: finished chunks are checked on resume ---------------------------------

def test_changed_truncated_and_deleted_chunks_are_run_again(reference, tmp_path, capsys):
    spec, out = _copy(reference, tmp_path)
    _unfinish(out, drop=[3])
    group = zarr.open_group(out / store.ZARR, mode="r+")
    group["metrics"][2:3] = group["metrics"][2:3] * 1.01  # a chunk file with other numbers
    chunk = out / store.ZARR / "signals" / "c" / "1" / "0" / "0"
    chunk.write_bytes(chunk.read_bytes()[:len(chunk.read_bytes()) // 2])
    (out / store.ZARR / "status" / "c" / "0").unlink()
    capsys.readouterr()
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 0
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    for index in (0, 1, 2):
        assert f"chunk {index} (run {index}): " in captured.err
    assert "4 runs (4 now, 0 failed)" in captured.out  # three run again, and the last
    _same(reference[1], out)
    assert verify_sweep(out) == []


def verify_sweep(out):
    return store.verify(out)


# --- item 4: vsj verify checks sweeps, and names foreign files ----------------------

def test_verify_checks_a_sweep_and_names_what_is_wrong(reference, tmp_path, capsys):
    spec, out = _copy(reference, tmp_path)
    assert main(["verify", str(out)]) == 0
    assert "a complete sweep of 4 runs" in capsys.readouterr().out
    (out / "trajectory.csv").write_text("t,x\n")
    (out / store.ZARR / "notes.txt").write_text("mine")
    (out / "summary.html").unlink()
    group = zarr.open_group(out / store.ZARR, mode="r+")
    group["metrics"][1:2] = -1.0
    assert main(["verify", str(out)]) == 1
    err = capsys.readouterr().err
    assert "trajectory.csv: a foreign file" in err
    assert "sweep.zarr/notes.txt: a foreign file" in err
    assert "summary.html is missing" in err
    assert "chunk 1 (run 1): its numbers differ" in err
    assert len(err.strip().splitlines()) == 5  # the directory and those four
    spec, out = _copy(reference, tmp_path / "unfinished")
    _unfinish(out, drop=[3])
    assert main(["verify", str(out)]) == 1
    assert [line.strip() for line in capsys.readouterr().err.strip().splitlines()[1:]] == [
        "the sweep is unfinished (3 of 4 chunks done, tables not written): run the sweep's "
        "command again with --resume"]
    # a manifest that calls the sweep complete with a chunk left out of it: that chunk's
    # runs would go unchecked (here changed too)
    spec, out = _copy(reference, tmp_path / "dropped")
    record = store.read_manifest(out)
    del record["done"]["2"]
    (out / store.MANIFEST).write_text(json.dumps(record))
    zarr.open_group(out / store.ZARR, mode="r+")["metrics"][2:3] = -1.0
    assert main(["verify", str(out)]) == 1
    assert "sweep.json calls the sweep complete but records 1 of its 4 chunks as not done " \
        "(chunk 2)" in capsys.readouterr().err
    # a manifest edited to call a run failed (or a failed one ok): the chunks' hashes cover
    # the store, the failures are checked against the store's status
    spec, out = _copy(reference, tmp_path / "failures")
    record = store.read_manifest(out)
    record["failed_runs"]["3"] = "boom"
    (out / store.MANIFEST).write_text(json.dumps(record))
    assert main(["verify", str(out)]) == 1
    assert "chunk 3 (run 3): the failed runs it records (3) are not those whose status in " \
        "sweep.zarr failed (none)" in capsys.readouterr().err


SHORT = """name = "short"
network = "wrist"
duration = "0.1 s"
[solver]
friction = "arctan"
output_step = "10 ms"
[inputs.motor_1]
kind = "sine"
amplitude = "2 rad/s"
frequency = "2 Hz"
"""


def test_verify_names_foreign_files_of_a_result_set_and_never_waits_on_a_fifo(tmp_path):
    scenario = tmp_path / "short.toml"
    scenario.write_text(SHORT)
    out = tmp_path / "out"
    assert main(["simulate", str(scenario), "--out", str(out)]) == 0
    assert verify(out) == []
    (out / "trajectory.csv").write_text("t,x\n0,0\n")
    assert verify(out) == [f"trajectory.csv: a foreign file (not recorded in {MANIFEST})"]
    (out / "trajectory.csv").unlink()
    (out / "meta.json").unlink()
    os.mkfifo(out / "meta.json")  # where a file the manifest lists should be
    os.mkfifo(out / "pipe")
    # a read that waited for a FIFO's writer would wait forever: run it where it can be
    # stopped (a minute is far beyond the second the check of two small files takes)
    done = subprocess.run([sys.executable, "-m", "vsj", "verify", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    assert "meta.json is not a regular file" in done.stderr
    assert "pipe: a foreign file" in done.stderr


# --- item 5: resuming a finished sweep, or one killed before its tables ------------

def test_resume_of_a_finished_sweep_writes_the_same_tables(reference, tmp_path, capsys):
    spec, out = _copy(reference, tmp_path)
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 0
    assert "4 runs (0 now, 0 failed)" in capsys.readouterr().out
    _same(reference[1], out)


def test_a_sweep_killed_before_its_tables_gets_them_on_resume(reference, tmp_path, capsys):
    spec, out = _copy(reference, tmp_path)
    _unfinish(out)
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 0
    assert "4 runs (0 now, 0 failed)" in capsys.readouterr().out
    _same(reference[1], out)
    assert verify_sweep(out) == []


def test_a_probe_file_left_by_a_killed_sweep_is_removed_on_resume(reference, tmp_path, capsys):
    """vsj names a file for a moment to learn whether the directory takes unnamed ones; a
    sweep killed then leaves it behind. It is vsj's, so a resume removes it."""
    spec, out = _copy(reference, tmp_path)
    _unfinish(out)
    probe = out / ".probe.vsj-tmp-044bc52e"
    probe.write_bytes(b"")
    assert "left by an interrupted vsj sweep" in " ".join(verify_sweep(out))
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 0
    assert not probe.exists()
    _same(reference[1], out)
    assert verify_sweep(out) == []


# --- item 9: windows and pivot positions refused before any run --------------------

@pytest.mark.parametrize("edit, words", [
    (('start = "0.1 s"', 'start = "50 s"'),
     ["metrics.deflection", "start = '50 s'", "holds 0 of the run's samples"]),
    (('start = "0.1 s"', 'start = "-1 s"'),
     ["metrics.deflection.start = '-1 s'", ">= 0 s"]),
    (('start = "0.1 s"', 'start = "0.2 s", stop = "0.1 s"'),
     ["metrics.deflection.stop = '0.1 s'", "after start"]),
    (('q = { values = ["-1 cm", "0.5 cm"] }', 'q = { from = "-10 cm", to = "1 cm", count = 3 }'),
     ["vary.q.from = '-10 cm'", "outside the range [-2.2 cm, 2 cm]"]),
    (('q = { values = ["-1 cm", "0.5 cm"] }', 'q = { values = ["-1 cm", "3 cm"] }'),
     ["vary.q.values[1] = '3 cm'", "outside the range [-2.2 cm, 2 cm]"]),
    (('q = { values = ["-1 cm", "0.5 cm"] }',
      'q = { distribution = "uniform", low = "-10 cm", high = "0.5 cm" }'),
     ["vary.q.low = '-10 cm'", "outside the range [-2.2 cm, 2 cm]"]),
    # item 11: a lag at 0 Hz (a phase over 2 pi f)
    (('tracking = { kind = "tracking_rms", signal = "theta_x", reference = "phi_1" }',
      'lag = { kind = "lag", signal = "theta_x", reference = "phi_1", frequency = "0 Hz" }'),
     ["metrics.lag.frequency = '0 Hz'", "> 0 Hz"]),
    (('tracking = { kind = "tracking_rms", signal = "theta_x", reference = "phi_1" }',
      'lag = { kind = "lag", signal = "theta_x", reference = "phi_1", frequency = "30 Hz" }'),
     ["metrics.lag.frequency = '30 Hz'", "Nyquist frequency 25 Hz"]),
])
def test_bad_windows_frequencies_and_pivot_positions_exit_2_before_any_run(
        tmp_path, capsys, edit, words):
    spec = _inputs(tmp_path)
    assert edit[0] in SPEC
    spec.write_text(SPEC.replace(*edit))
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK]) == 2
    err = capsys.readouterr().err
    assert str(spec) in err and "Traceback" not in err
    for word in words:
        assert word in err
    assert not out.exists()


def test_a_distribution_of_q_is_truncated_to_the_pivot_range(tmp_path, capsys, params):
    """A normal q centred inside the pivot range with a spread 2.5 times its half width
    (about 2/3 of the untruncated draws fall outside): every run's q is drawn within
    [q_min, q_max], as parameters are within their schema ranges, and every run is
    built."""
    from vsj.sweep import sampling

    spec = _inputs(tmp_path)
    spec.write_text(SPEC.replace('q = { values = ["-1 cm", "0.5 cm"] }',
                                 'q = { distribution = "normal", mean = "0 cm", sd = "5 cm" }')
                    .replace('duration = "0.3 s"', 'duration = "0.2 s"')
                    .replace("samples = 2", "samples = 4"))
    lo, hi = params["pivot.q_min"], params["pivot.q_max"]
    untruncated, _ = sampling.design(sweep.load(spec))
    assert np.any((untruncated[:, 0] < lo) | (untruncated[:, 0] > hi))  # the seed's draws
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK]) == 0
    assert "4 runs (4 now, 0 failed)" in capsys.readouterr().out
    q = _arrays(out)["q"]
    assert np.all((q >= lo) & (q <= hi))


# --- item 11: damaged stores and failed writes -------------------------------------

@pytest.mark.parametrize("damage", ["metadata", "store"])
def test_a_damaged_or_deleted_store_is_rebuilt_on_resume(reference, tmp_path, capsys,
                                                        damage):
    spec, out = _copy(reference, tmp_path)
    _unfinish(out, drop=[3])
    if damage == "metadata":
        (out / store.ZARR / "metrics" / "zarr.json").write_text("{")
        (out / store.ZARR / "q" / "zarr.json").write_text('{"zarr_format": 3,')
    else:
        shutil.rmtree(out / store.ZARR)
    capsys.readouterr()
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 0
    captured = capsys.readouterr()
    assert "rebuilt from the sweep's inputs" in captured.err
    # the metadata rebuilt, the chunks' numbers were intact; a deleted store runs all
    ran = 1 if damage == "metadata" else 4
    assert f"4 runs ({ran} now, 0 failed)" in captured.out
    _same(reference[1], out)
    assert verify_sweep(out) == []


def test_a_damaged_manifest_is_refused_with_its_name(reference, tmp_path, capsys):
    spec, out = _copy(reference, tmp_path)
    (out / store.MANIFEST).write_text('{"runs": 4')
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 2
    assert "sweep.json is not valid JSON" in capsys.readouterr().err
    os.unlink(out / store.MANIFEST)
    os.mkfifo(out / store.MANIFEST)
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 2
    assert "FIFO" in capsys.readouterr().err


def _sweep_process(spec, out, *extra, limit=None, one_by_one=False):
    """``vsj sweep`` in a process of its own; ``limit``: the largest file it may write
    [bytes] (RLIMIT_FSIZE: a longer write fails as on a full disk; Python ignores the
    SIGXFSZ that comes with it); ``one_by_one``: each chunk written as it finishes
    (`vsj.sweep.WRITE_EVERY` 0), not with the others that finish within seconds."""
    def limited():
        import resource

        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    command = ("import sys, vsj.sweep; from vsj.cli import main; "
               f"vsj.sweep.WRITE_EVERY = {0.0 if one_by_one else 'vsj.sweep.WRITE_EVERY'}; "
               "sys.exit(main(sys.argv[1:]))")
    return subprocess.Popen([sys.executable, "-c", command, "sweep", str(spec), "--out",
                             str(out), *CHUNK, *extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=limited if limit is not None else None)


def _manifest_bytes(reference_out, chunks: int) -> int:
    """Bytes of the reference's sweep.json as it stood with ``chunks`` chunks done."""
    record = json.loads((reference_out / store.MANIFEST).read_text())
    record["done"] = {k: v for k, v in record["done"].items() if int(k) < chunks}
    record["complete"] = False
    record.pop("files", None)
    return len((json.dumps(record, indent=1) + "\n").encode())


def test_a_write_that_fails_mid_sweep_ends_with_exit_1_and_resume_finishes(reference,
                                                                          tmp_path):
    """A file system that takes no more (here: no file longer than sweep.json with two
    chunks done, so recording the third fails; the chunks written one by one) ends the
    sweep with exit 1 and the remedy; ``--resume`` with room again finishes it as if
    nothing happened."""
    spec = _inputs(tmp_path)
    out = tmp_path / "out"
    two, three = _manifest_bytes(reference[1], 2), _manifest_bytes(reference[1], 3)
    chunk_files = [p.stat().st_size for p in (reference[1] / store.ZARR).rglob("*")
                   if p.is_file()]
    assert max(chunk_files) < two < three
    process = _sweep_process(spec, out, limit=(two + three) // 2, one_by_one=True)
    _, err = process.communicate(timeout=300)
    assert process.returncode == 1, err
    assert "Traceback" not in err
    assert f"{out / store.MANIFEST}: writing the sweep failed (File too large)" in err
    assert "the finished chunks are kept" in err and "run the same command with --resume" in err
    assert sorted(store.read_manifest(out)["done"]) == ["0", "1"]
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 0
    _same(reference[1], out)
    assert verify_sweep(out) == []


# --- item 13: a changed covariance file is named -----------------------------------

def test_resume_names_a_changed_covariance_file(tmp_path, monkeypatch, capsys, params):
    spec = _inputs(tmp_path)
    viscous = params["transmission.viscous"]
    fit = {"names": ["transmission.viscous"], "parameters": {"transmission.viscous": viscous},
           "covariance": [[(0.1 * viscous) ** 2]]}
    (tmp_path / "fit.json").write_text(json.dumps(fit))
    spec.write_text(SPEC.replace(
        '"transmission.viscous" = { distribution = "normal", mean = "3 mN m s", sd = "1 mN m s" }\n',
        "").replace("[metrics]", '[covariance]\nfile = "fit.json"\n\n[metrics]'))
    out = tmp_path / "out"
    _interrupted(spec, out, monkeypatch)
    fit["parameters"]["transmission.viscous"] = 1.5 * viscous
    (tmp_path / "fit.json").write_text(json.dumps(fit))
    capsys.readouterr()
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, "--resume"]) == 2
    err = capsys.readouterr().err
    assert f"the covariance file {tmp_path / 'fit.json'} has changed" in err
    assert "NumPy" not in err


# --- item 14: the sweep's size up front ---------------------------------------------

def test_a_sweep_larger_than_the_free_space_is_refused_before_any_run(tmp_path, capsys):
    """Ten million runs keeping ten signals at every millisecond of 2000 s: 1.6e15 bytes
    of numbers, beyond any disk this runs on; refused up front, saying so."""
    spec = _inputs(tmp_path)
    spec.write_text(SPEC.replace('duration = "0.3 s"', 'duration = "2000 s"')
                    .replace('q = { values = ["-1 cm", "0.5 cm"] }',
                             'q = { from = "-1 cm", to = "1 cm", count = 1000000 }')
                    .replace("samples = 2", "samples = 10")
                    .replace('keep = ["theta_x", "phi_1"]',
                             'keep = ["theta_x", "theta_y", "phi_1", "phi_2", "q", "q.rate", '
                             '"theta_x.speed", "theta_y.speed", "phi_1.speed", "phi_2.speed"]')
                    .replace('every = "20 ms"', 'every = "1 ms"'))
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--no-plot"]) == 2
    err = capsys.readouterr().err
    shown = re.search(r"10000000 runs .* up to ([\d.]+) PB on disk", err)
    assert shown is not None, err
    numbers = 10_000_000 * 2_000_001 * 10 * 8  # the kept signals alone
    assert float(shown.group(1)) >= float(f"{numbers / 1e15:.3g}")  # shown to 3 digits
    assert "free: not enough room; nothing was run" in err
    assert not out.exists()


def test_a_sweep_says_how_much_it_writes_before_it_runs(reference, tmp_path, capsys):
    spec = _inputs(tmp_path)
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out"), *CHUNK]) == 0
    err = capsys.readouterr().err
    plan = re.search(r"4 runs in 4 chunks, 4 to run: up to ([\d.]+ [kMG]?B) on disk", err)
    assert plan is not None, err
    written = sum(p.stat().st_size for p in (tmp_path / "out").rglob("*") if p.is_file())
    number, unit = plan.group(1).split()
    bound = float(number) * {"B": 1, "kB": 1e3, "MB": 1e6, "GB": 1e9}[unit]
    assert written <= bound


# --- kill -9 at random moments, then resume ------------------------------------------

def _done(out) -> int:
    """Chunks the manifest of ``out`` records done (-1 without a readable manifest)."""
    try:
        return len(json.loads((out / store.MANIFEST).read_text())["done"])
    except (OSError, ValueError):
        return -1


def test_kill_9_at_random_moments_then_resume_equals_the_uninterrupted_sweep(reference,
                                                                             tmp_path):
    """Each round starts the sweep (resuming once one is recorded), waits until a random
    number of its chunks is done and then a random part of a chunk's time (a chunk
    takes some 50 ms here), and kills the process with SIGKILL: before its manifest,
    between chunks, while a chunk or the tables are written. A last resume finishes
    it. The result is the uninterrupted sweep's, bit for bit; the files beside it are
    untouched and no temporary file is left."""
    spec = _inputs(tmp_path)
    neighbour = tmp_path / "notes.txt"
    neighbour.write_text("mine")
    inputs = {p: p.read_bytes() for p in (spec, tmp_path / "child.toml", neighbour,
                                          tmp_path / "sets" / "parent.toml")}
    out = tmp_path / "out"
    rng = random.Random(31)
    killed = 0
    for _ in range(3):
        recorded = (out / store.MANIFEST).exists()
        if recorded and store.read_manifest(out)["complete"]:
            break
        process = _sweep_process(spec, out, *(["--resume"] if recorded else []))
        target = rng.randint(max(0, _done(out)), 4)
        while process.poll() is None:
            if _done(out) >= target:
                time.sleep(rng.uniform(0.0, 0.06))
                process.send_signal(signal.SIGKILL)
                killed += process.wait() == -signal.SIGKILL
                break
            time.sleep(0.002)
        process.communicate()
    assert killed >= 1
    resume = ["--resume"] if (out / store.MANIFEST).exists() else []
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK, *resume]) == 0
    _same(reference[1], out)
    assert verify_sweep(out) == []
    left = [p for p in tmp_path.rglob("*") if "vsj-tmp" in p.name or p.name.endswith(".partial")]
    assert left == []
    assert {p: p.read_bytes() for p in inputs} == inputs


def test_files_named_as_a_sweeps_but_recorded_by_none_are_refused_untouched(
        reference, tmp_path, capsys):
    """A directory that holds a sweep's file names but no sweep.json (another program's
    sweep.zarr or metrics.csv, or what is left after sweep.json was deleted) is refused
    with exit 2 and left as it was; a store frame a new sweep was making when it was
    killed (before it recorded the sweep: vsj's attributes on its group) is taken over."""
    spec = _inputs(tmp_path)
    for name, make in (("sweep.zarr/mine.txt", "precious"), ("metrics.csv", "a,b\n1,2\n"),
                       ("summary.html", "<p>mine</p>")):
        out = tmp_path / f"out-{name.split('/')[0]}"
        (out / name).parent.mkdir(parents=True)
        (out / name).write_text(make)
        before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
        assert main(["sweep", str(spec), "--out", str(out), *CHUNK]) == 2
        err = capsys.readouterr().err
        assert "no sweep records" in err and name.split("/")[0] in err, err
        assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before
    # the reference's own frame, its manifest gone: what a sweep killed before recording
    # it leaves
    _, out = _copy(reference, tmp_path)
    for name in (store.MANIFEST, store.METRICS):
        (out / name).unlink()
    for name in os.listdir(out):
        if name not in (store.ZARR,):
            shutil.rmtree(out / name) if (out / name).is_dir() else (out / name).unlink()
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK]) == 0
    capsys.readouterr()
    _same(reference[1], out)


def test_a_sweep_whose_every_run_failed_exits_1(tmp_path, capsys):
    """Runs that fail are recorded and the sweep goes on; when none succeeded, the sweep
    produced no numbers and exits 1 (each failure still recorded)."""
    spec = tmp_path / "failing.toml"
    spec.write_text(SPEC.replace('params = "child.toml"\n', "").replace(
        '"transmission.viscous" = { distribution = "normal", mean = "3 mN m s", '
        'sd = "1 mN m s" }', '"elastic_element.lever_length" = { values = ["1 cm", "5 cm"] }'))
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), *CHUNK]) == 1
    err = capsys.readouterr().err
    assert "4 run(s) failed" in err and "every run of the sweep failed" in err
    assert len(store.read_manifest(out)["failed_runs"]) == 4


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (children, their children, ...), from /proc."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        try:
            with open(f"/proc/{entry}/status") as handle:
                ppid = int(re.search(r"\nPPid:\t(\d+)\n", handle.read()).group(1))
            children.setdefault(ppid, []).append(int(entry))
        except (OSError, ValueError, AttributeError):
            continue
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def _alive(pid: int) -> bool:
    """Whether ``pid`` runs (a zombie, ended but not yet reaped by an init that may never
    reap it in a container, does not)."""
    try:
        with open(f"/proc/{pid}/status") as handle:
            return "\nState:\tZ" not in handle.read()
    except OSError:
        return False


def _cmdline(pid: int) -> bytes:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as handle:
            return handle.read()
    except OSError:
        return b""


def test_a_sweep_killed_outright_takes_its_fork_server_and_workers_with_it(tmp_path):
    """The default scheduler's workers are forked from a fork server. Python's workers
    wait on a queue whose writing end they hold, and they keep the server alive: a sweep
    killed with SIGKILL left all three running. They now end with it."""
    spec = _inputs(tmp_path)
    spec.write_text(SPEC.replace('duration = "0.3 s"', 'duration = "3 s"')
                    .replace("samples = 2", "samples = 20"))
    run = subprocess.Popen([sys.executable, "-m", "vsj", "sweep", str(spec), "--out",
                            str(tmp_path / "out"), "--chunk", "1", "--workers", "2",
                            "--no-plot"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60.0
        server = []
        while run.poll() is None and time.monotonic() < deadline and not server:
            below = _descendants(run.pid)
            server = [p for p in below if b"multiprocessing.forkserver" in _cmdline(p)
                      and len(_descendants(p)) >= 2]
            time.sleep(0.02)
        assert server and run.poll() is None, "no fork server with workers seen"
        watched = server + _descendants(server[0])
    finally:
        run.kill()
        run.wait()
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline and any(_alive(p) for p in watched):
        time.sleep(0.02)
    left = [p for p in watched if _alive(p)]
    for p in left:  # not to leave them to the next test
        os.kill(p, signal.SIGKILL)
    assert not left, "the fork server or its workers outlived the sweep"

"""Output paths and result sets (`vsj.output.ResultSet`, issue 18): every command that
writes checks its output before the work, a set is replaced as a unit, a second writer is
refused, and neither a kill nor a failing disk leaves a mixed set, a damaged old set or
hidden files behind."""

import json
import os
import random
import resource
import shutil
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import SHORT_SCENARIO

from vsj.cli import main
from vsj.output import (MANIFEST, OutputError, ResultSet, clear_staging, read_manifest,
                        signals_bound, trajectory_bytes, verify)
from vsj.output import files as files_module


def _short(duration: str, output_step: str = "10 ms") -> str:
    return SHORT_SCENARIO.replace('duration = "0.3 s"', f'duration = "{duration}"').replace(
        'output_step = "10 ms"', f'output_step = "{output_step}"')


#: How long a killed run's watchdog may take to clear what the run left (it needs a few
#: tens of milliseconds; the margin is for a loaded machine).
SETTLE_TIMEOUT = 20.0
#: Kills aimed at the writing of a run (its last 0.1 s to 0.25 s; the test takes about
#: 0.6 s a kill). Each is delayed uniformly over 1.5 times the longest writing of three
#: whole runs, so it lands while the run writes with probability about 2/3 where runs
#: write alike. At least a third of them must: up to twice as many more are aimed when fewer
#: landed (at 2/3, fewer than 5 of 16 happen with probability 8e-4; where a loaded
#: machine drops the rate to 1/3, fewer than 5 of 48 with probability 5e-5).
WRITING_KILLS = 16


def scenario(tmp_path, duration="0.3 s", name="scen.toml", output_step="10 ms"):
    path = tmp_path / name
    path.write_text(_short(duration, output_step))
    return path


def contents(directory: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir())}


def hidden(directory: Path) -> list[str]:
    return sorted(p.name for p in directory.iterdir() if p.name.startswith("."))


def flock_pids() -> set[int]:
    """Processes that hold a ``flock`` (from /proc/locks)."""
    pids = set()
    with open("/proc/locks", encoding="ascii") as handle:
        for line in handle:
            fields = line.split()
            if len(fields) > 4 and fields[1] == "FLOCK":
                pids.add(int(fields[4]))
    return pids


def settle(parent: Path, out: Path, pid: int) -> None:
    """Wait until a killed run ``pid`` has no lock left and what it left is cleared (its
    watchdog has finished), or `SETTLE_TIMEOUT` has passed."""
    deadline = time.monotonic() + SETTLE_TIMEOUT
    while time.monotonic() < deadline:
        if pid not in flock_pids() and not hidden(parent) and not (
                out.is_dir() and (hidden(out) or not any(out.iterdir()))):
            return
        time.sleep(0.01)


def staging(parent: Path, out: Path) -> bool:
    """Whether a run is writing a set for ``out``: its hidden staging directory exists
    (the probes of its checks end in ``p`` or ``q``)."""
    return any(n.startswith(".") and n[-1] not in "pq" for n in os.listdir(parent)) or (
        out.is_dir() and bool(hidden(out)))


def finished(pid: int) -> bool:
    """Whether the child ``pid`` has ended (a zombie, not yet reaped)."""
    with open(f"/proc/{pid}/stat", encoding="ascii") as handle:
        return handle.read().rsplit(")", 1)[1].split()[0] == "Z"


def wait_until(condition, pid: int) -> float:
    """Poll until ``condition()`` holds or the child ``pid`` has ended; the time taken."""
    began = time.monotonic()
    while not condition() and not finished(pid):
        time.sleep(0.0005)
    return time.monotonic() - began


# ------------------------------------------------------------------ killed while writing

#: A vsj process with its modules imported that runs one ``vsj`` command per line of
#: standard input in a forked child, so that kills land in the run rather than in the
#: interpreter's start-up. It prints the child's pid, waits for a line (the test has
#: killed the child, or lets it finish), then reaps it and prints its wait status.
RUNNER = """
import json, os, sys
import scipy.interpolate, xarray  # imported by a run on first use
from vsj.cli import main
for line in sys.stdin:
    pid = os.fork()
    if pid == 0:
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(null, 2)
        os._exit(main(json.loads(line)))
    print(pid, flush=True)
    sys.stdin.readline()
    print(os.waitpid(pid, 0)[1], flush=True)
"""


class Runner:
    def __init__(self):
        self.process = subprocess.Popen([sys.executable, "-c", RUNNER], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, text=True, bufsize=1)

    def start(self, argv) -> int:
        self.process.stdin.write(json.dumps([str(a) for a in argv]) + "\n")
        return int(self.process.stdout.readline())

    def reap(self) -> int:
        """The wait status of the child after it was killed or has finished."""
        self.process.stdin.write("\n")
        return int(self.process.stdout.readline())

    def close(self):
        self.process.stdin.close()
        self.process.wait(timeout=30)


def classify(out: Path, old: dict[str, bytes] | None, new: dict[str, bytes]) -> str:
    """'old', 'new' or 'none' (no directory, when there was no old set); anything else
    fails the test."""
    if not out.exists():
        assert old is None, "the old set vanished"
        return "none"
    assert not hidden(out), f"hidden files left in {out}: {hidden(out)}"
    now = contents(out)
    if old is not None and now == old:
        return "old"
    assert set(now) == set(new), f"a mixed set: {sorted(now)}"
    assert verify(out) == []
    for name in ("trajectory.nc", "trajectory.csv"):  # meta.json has wall times
        assert now[name] == new[name], f"{name} is not the new set's"
    meta = json.loads(now["meta.json"])
    assert meta["scenario"]["definition"]["duration"] == "0.5 s"
    return "new"


def test_a_killed_run_leaves_the_complete_old_or_new_set(tmp_path):
    """`vsj simulate` killed (SIGKILL) at random moments of its run, most of them while
    it writes (timed from when it starts writing, so that a loaded machine does not move
    them), against a complete old set and against no directory at all: afterwards the
    directory holds exactly the old set or exactly the new one (every byte of the old; the
    new one's data and hashes), and nothing hidden is left beside or in it."""
    # the new set is sampled finely, so that its writing lasts tens of milliseconds
    # however fast the build: a kill aimed at it cannot all but miss a writing of a few
    old_scenario, new_scenario = scenario(tmp_path, "0.3 s", "old.toml"), \
        scenario(tmp_path, "0.5 s", "new.toml", output_step="1 ms")
    parent = tmp_path / "work"
    parent.mkdir()
    out = parent / "out"
    assert main(["simulate", str(old_scenario), "--out", str(out), "--csv", "--no-plot"]) == 0
    old = contents(out)
    reference = tmp_path / "reference"
    assert main(["simulate", str(new_scenario), "--out", str(reference), "--csv",
                 "--no-plot"]) == 0
    new = contents(reference)
    argv = ["simulate", new_scenario, "--out", out, "--csv", "--no-plot"]

    def restore(with_old: bool):
        shutil.rmtree(out, ignore_errors=True)
        if with_old:
            out.mkdir()
            for name, data in old.items():
                (out / name).write_bytes(data)

    def writes() -> bool:
        return staging(parent, out)

    rng = random.Random(18)
    runner = Runner()
    try:
        # whole runs: how long one takes to start writing, and how long its staging
        # directory is there (the writing, not the process's exit after it); kills
        # aim within the writings' median, which one slow writing (a cold cache, a
        # busy core) does not stretch past the others
        before, writings = 0.0, []
        for _ in range(3):
            restore(True)
            pid = runner.start(argv)
            before = max(before, wait_until(writes, pid))
            writings.append(wait_until(lambda: not writes(), pid))
            wait_until(lambda: False, pid)
            assert runner.reap() == 0 and classify(out, old, new) == "new"
        writing = statistics.median(writings)
        # (kind, with an old set): kills at random before the writing, while it writes,
        # after the end; on a loaded machine, where writings last unlike the three
        # measured, more kills aimed at the writing (within the shortest one measured),
        # until enough landed there
        plan = [("before", True)] * 3 + [("writing", True)] * WRITING_KILLS + \
            [("after", True)] * 2 + [("writing", False)] * 4
        plan += [("again", True)] * (2 * WRITING_KILLS)
        outcomes, while_writing = [], 0
        for kind, with_old in plan:
            span = 1.5 * writing
            if kind == "again":
                if while_writing >= WRITING_KILLS // 3:
                    break
                kind, span = "writing", min(writings)
            restore(with_old)
            pid = runner.start(argv)
            if kind == "before":
                time.sleep(rng.uniform(0, before))
            elif kind == "writing":
                wait_until(writes, pid)
                time.sleep(rng.uniform(0, span))
            else:
                wait_until(lambda: False, pid)
            while_writing += writes()
            os.kill(pid, signal.SIGKILL)  # a zombie until reaped, so the pid is still its
            runner.reap()
            settle(parent, out, pid)
            assert not hidden(parent), f"left beside the directory: {hidden(parent)}"
            outcomes.append((kind, with_old, classify(out, old if with_old else None, new)))
    finally:
        runner.close()
    counts = {o: sum(1 for _, _, c in outcomes if c == o) for o in ("old", "new", "none")}
    print(f"a run: {before:.3f} s to start writing, {writing:.3f} s writing; {len(outcomes)} "
          f"kills, {while_writing} while writing: {counts}")
    assert while_writing >= WRITING_KILLS // 3, "too few kills landed while the run wrote"
    assert {"old", "new"} <= {c for _, with_old, c in outcomes if with_old}
    assert "none" in {c for _, with_old, c in outcomes if not with_old}


def forked_children(pid: int) -> list[int]:
    """The children of ``pid`` that run its own command line (processes it forked, not
    ones it started, such as its watchdog)."""
    def read(p, name):
        with open(f"/proc/{p}/{name}", "rb") as handle:
            return handle.read()

    own = read(pid, "cmdline")
    found = []
    for entry in os.listdir("/proc"):
        try:
            status = read(entry, "status").decode()
            if f"\nPPid:\t{pid}\n" in status and read(entry, "cmdline") == own:
                found.append(int(entry))
        except (OSError, ValueError):
            continue
    return found


def test_a_killed_reproduction_leaves_no_worker_behind(tmp_path):
    """`vsj reproduce` makes its figures in processes forked from it (`vsj.reproduce.run`):
    killed outright (SIGKILL) while they work, it takes them with it, so that nothing
    holds the directory's lock or the watchdog's pipe, and the watchdog clears what the
    run left: no directory (there was none before) and nothing hidden beside it."""
    parent = tmp_path / "work"
    parent.mkdir()
    out = parent / "out"
    run = subprocess.Popen([sys.executable, "-m", "vsj", "reproduce", "--reduced", "--out",
                            str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + SETTLE_TIMEOUT
        workers = []
        while run.poll() is None and time.monotonic() < deadline and not (
                workers and staging(parent, out)):
            workers = forked_children(run.pid)
            time.sleep(0.01)
        assert workers and run.poll() is None, "no worker process seen while the run went on"
    finally:
        run.kill()
        run.wait()
    deadline = time.monotonic() + SETTLE_TIMEOUT
    while time.monotonic() < deadline and (
            any(os.path.exists(f"/proc/{w}") for w in workers) or hidden(parent)
            or out.exists()):
        time.sleep(0.01)
    assert not [w for w in workers if os.path.exists(f"/proc/{w}")], "workers outlived the run"
    assert not hidden(parent) and not out.exists()


# ------------------------------------------------------------------ concurrent writers

def test_a_second_writer_is_refused_while_the_first_holds_the_directory(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 0
    first = subprocess.Popen([sys.executable, "-m", "vsj", "simulate",
                              str(scenario(tmp_path, "0.5 s", "first.toml")), "--out", str(out),
                              "--no-plot"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while first.pid not in flock_pids():
        assert first.poll() is None and time.monotonic() < deadline
        time.sleep(0.005)
    os.kill(first.pid, signal.SIGSTOP)  # holds the directory for as long as the test needs
    try:
        before = contents(out)
        capsys.readouterr()
        assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 2
        err = capsys.readouterr().err
        assert f"--out {out}: another vsj command (process {first.pid}) is writing" in err
        assert contents(out) == before
    finally:
        os.kill(first.pid, signal.SIGCONT)
    assert first.wait(timeout=60) == 0, first.stderr.read()
    assert verify(out) == []
    assert json.loads((out / "meta.json").read_text())["scenario"]["definition"][
        "duration"] == "0.5 s"


# ------------------------------------------------------------------ checks before the work

@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """Measurement files for the fit commands."""
    d = tmp_path_factory.mktemp("data")
    for fixed in ("sun", "ring"):
        assert main(["synth", "friction", "--fixed", fixed, "--report", "second", "--form",
                     "points", "--out", str(d / f"{fixed}.csv")]) == 0
    assert main(["synth", "stiffness", "--q", "1.4", "--out", str(d / "k.csv")]) == 0
    (d / "scen.toml").write_text(_short("0.3 s"))
    return d


#: Each writing command: its arguments with the output path as OUT, and the function that
#: does its work (which must not be reached when the output is refused).
DIRECTORY_COMMANDS = {
    "simulate": (["simulate", "{data}/scen.toml", "--out", "OUT"], "vsj.simulate.simulate"),
    "reproduce": (["reproduce", "--reduced", "--out", "OUT"], "vsj.reproduce.Context"),
    "datasheet": (["datasheet", "--out", "OUT"], "vsj.datasheet.compute"),
    "fit friction": (["fit", "friction", "{data}/sun.csv", "--out", "OUT"],
                     "vsj.identification.friction.fit_curve"),
    "fit planetary": (["fit", "planetary", "--fixed-sun", "{data}/sun.csv", "--fixed-ring",
                       "{data}/ring.csv", "--out", "OUT"], "vsj.identification.friction.fit_curve"),
    "fit stiffness": (["fit", "stiffness", "{data}/k.csv", "--out", "OUT"],
                      "vsj.identification.stiffness.fit_stiffness"),
    "synth stiffness": (["synth", "stiffness", "--q", "1.4", "--q", "0.2", "--out", "OUT"],
                        "vsj.synth.stiffness"),
}
FILE_COMMANDS = {
    "synth friction": (["synth", "friction", "--fixed", "sun", "--report", "second", "--out",
                        "OUT"], "vsj.synth.friction", "--out"),
    "synth stiffness": (["synth", "stiffness", "--q", "1.4", "--out", "OUT.csv"],
                        "vsj.synth.stiffness", "--out"),
    "linearize": (["linearize", "--out", "OUT.json"], "vsj.linear.linearize", "--out"),
    "export-model": (["export-model", "--out", "OUT"], "vsj.export.wrist_stepper", "--out"),
    "fit planetary": (["fit", "planetary", "--fixed-sun", "{data}/sun.csv", "--fixed-ring",
                       "{data}/ring.csv", "--write-params", "OUT"],
                      "vsj.identification.friction.fit_curve", "--write-params"),
    "fit stiffness": (["fit", "stiffness", "{data}/k.csv", "--calibrate-geometry",
                       "--write-params", "OUT"], "vsj.identification.stiffness.fit_stiffness",
                      "--write-params"),
}


def refuse_work(monkeypatch, target: str):
    import importlib

    module, name = target.rsplit(".", 1)

    def work(*args, **kwargs):
        raise AssertionError(f"{target} ran before the output was checked")

    monkeypatch.setattr(importlib.import_module(module), name, work)


def run_refused(argv, data, out, option, capsys) -> str:
    args = [a.replace("{data}", str(data)).replace("OUT", str(out)) for a in argv]
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"{option} {args[args.index(option) + 1]}:" in err
    return err


@pytest.mark.parametrize("command", list(DIRECTORY_COMMANDS))
def test_directory_outputs_are_checked_before_the_work(command, data, tmp_path, capsys,
                                                       monkeypatch):
    argv, work = DIRECTORY_COMMANDS[command]
    refuse_work(monkeypatch, work)
    a_file = tmp_path / "a-file"
    a_file.write_text("mine\n")
    err = run_refused(argv, data, a_file, "--out", capsys)  # a file where a directory goes
    assert "exists and is not a directory" in err
    err = run_refused(argv, data, a_file / "out", "--out", capsys)  # under a file
    assert f"{a_file} is not a directory" in err
    foreign = tmp_path / "foreign"  # a directory holding files vsj did not write
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine\n")
    (foreign / "meta.json").write_text("{}\n")  # a name vsj writes does not make it vsj's
    err = run_refused(argv, data, foreign, "--out", capsys)
    assert "files that vsj did not write (meta.json, notes.txt" in err
    assert (foreign / "notes.txt").read_text() == "mine\n" and a_file.read_text() == "mine\n"
    assert sorted(os.listdir(tmp_path)) == ["a-file", "foreign"]


@pytest.mark.parametrize("command", list(FILE_COMMANDS))
def test_file_outputs_are_checked_before_the_work(command, data, tmp_path, capsys,
                                                  monkeypatch):
    argv, work, option = FILE_COMMANDS[command]
    refuse_work(monkeypatch, work)
    directory = tmp_path / ("a-directory" + (".csv" if "OUT.csv" in argv else
                                             ".json" if "OUT.json" in argv else ""))
    directory.mkdir()
    argv = [a.replace("OUT.csv", "OUT").replace("OUT.json", "OUT") for a in argv]
    err = run_refused(argv, data, directory, option, capsys)  # a directory where a file goes
    assert "is a directory" in err
    a_file = tmp_path / "a-file"
    a_file.write_text("mine\n")
    err = run_refused(argv, data, a_file / directory.name, option, capsys)  # under a file
    assert f"{a_file} is not a directory" in err
    assert a_file.read_text() == "mine\n" and sorted(os.listdir(directory)) == []


def test_too_little_free_space_is_refused_before_the_work(tmp_path):
    info = os.statvfs(tmp_path)
    free = info.f_bavail * info.f_frsize
    with pytest.raises(OutputError, match=r"--out .*: the results need up to .* free"), \
            ResultSet(tmp_path / "out", "simulate", size=2 * free + 10 ** 9):
        raise AssertionError("the work started")
    assert not (tmp_path / "out").exists()  # and the directory it made is gone


def test_size_estimates_bound_what_is_written(tmp_path):
    """The estimate behind the free-space check covers what a run writes."""
    from vsj import params as params_module
    from vsj import scenario as scenarios

    params = params_module.default()
    for name in scenarios.builtin_names():
        scen = scenarios.load(name)
        for case in scen.cases:
            prep = scenarios.prepare_case(scen, case, params)
            result = prep.run(duration=20 * case.options.output_step)
            assert len(result.signals) <= signals_bound(prep.structure), (name, case.label)
    out = tmp_path / "out"
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--csv"]) == 0
    written = sum(p.stat().st_size for p in out.iterdir())
    with open(out / "trajectory.csv") as handle:
        signals = len(handle.readline().split(",")) - 1
    assert written <= trajectory_bytes(31, signals, 1, csv=True, plot=True)


# ------------------------------------------------------------------ failing while writing

def limited_to(size: int):
    """Run a command with files limited to ``size`` bytes: a write beyond fails with EFBIG
    (Python ignores SIGXFSZ), a real failure of the disk as a process sees it."""
    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (size, size))
    return limit


def test_a_failing_write_leaves_the_old_set_byte_identical(tmp_path):
    out = tmp_path / "out"
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--csv"]) == 0
    before = contents(out)
    done = subprocess.run([sys.executable, "-m", "vsj", "simulate",
                           str(scenario(tmp_path, "0.5 s", "new.toml")), "--out", str(out)],
                          preexec_fn=limited_to(20_000), capture_output=True, text=True,
                          check=False)
    assert done.returncode == 2
    assert f"--out {out}: writing trajectory.nc failed (File too large); the directory is " \
           "unchanged" in done.stderr
    assert contents(out) == before and hidden(tmp_path) == []


def test_a_failing_write_leaves_the_old_file(tmp_path):
    path = tmp_path / "model.json"
    assert main(["linearize", "--out", str(path)]) == 0
    before = path.read_bytes()
    done = subprocess.run([sys.executable, "-m", "vsj", "linearize", "--q=-1cm", "--out",
                           str(path)], preexec_fn=limited_to(len(before) // 2),
                          capture_output=True, text=True, check=False)
    assert done.returncode == 2
    assert f"--out {path}: writing failed (File too large)" in done.stderr
    assert path.read_bytes() == before and os.listdir(tmp_path) == ["model.json"]


# ------------------------------------------------------------------ sets, manifests, leftovers

def test_a_set_is_replaced_whole_and_verified(tmp_path):
    out = tmp_path / "out"
    scen = scenario(tmp_path)
    assert main(["simulate", str(scen), "--out", str(out), "--csv", "--no-plot"]) == 0
    manifest = read_manifest(out)["sets"]["simulate"]
    meta = json.loads((out / "meta.json").read_text())
    assert set(manifest["files"]) == {"trajectory.nc", "trajectory.csv", "meta.json"}
    assert meta["files"] == {k: v for k, v in manifest["files"].items() if k != "meta.json"}
    assert verify(out) == []
    assert main(["simulate", str(scen), "--out", str(out), "--no-plot"]) == 0
    assert sorted(os.listdir(out)) == sorted(["meta.json", MANIFEST, "trajectory.nc"])  # no CSV
    (out / "trajectory.nc").write_bytes(b"not the set's")
    (out / "meta.json").unlink()
    assert verify(out) == ["set 'simulate': meta.json is missing",
                           "set 'simulate': trajectory.nc has changed (its SHA-256 differs)"]


def test_a_file_put_into_the_directory_while_a_set_is_committed_is_kept(tmp_path,
                                                                         monkeypatch):
    """A file that appears in the directory after the other sets' files are carried over
    and before the exchange ends up among the old set's files, which are removed: it is
    moved back, even under the name of another command's result (the old set's own
    files and manifest are what goes)."""
    out = tmp_path / "out"
    for text in ("first", "second"):
        with ResultSet(out, "datasheet") as results, results.write("datasheet.json", "w") as f:
            f.write(json.dumps({"vsj": text}))
    exchange = files_module._exchange

    def meanwhile(staging, target):
        (target / "results.json").write_text("the user's")  # a name of vsj reproduce's
        exchange(staging, target)

    monkeypatch.setattr(files_module, "_exchange", meanwhile)
    with ResultSet(out, "datasheet") as results, results.write("datasheet.json", "w") as f:
        f.write(json.dumps({"vsj": "third"}))
    assert (out / "results.json").read_text() == "the user's"
    assert json.loads((out / "datasheet.json").read_text()) == {"vsj": "third"}
    assert sorted(os.listdir(out)) == sorted(["datasheet.json", MANIFEST, "results.json"])


def test_sets_of_several_commands_share_a_directory(tmp_path, capsys):
    """`vsj simulate` and `vsj fit friction` into one directory (the README's
    `--out fit` of two fits, the `out` default of simulate and datasheet): each replaces
    its own set; the other's files stay, the very same files."""
    out = tmp_path / "out"
    for fixed in ("sun", "ring"):
        main(["synth", "friction", "--fixed", fixed, "--constants", "0.002,0.006,8", "--out",
              str(tmp_path / f"{fixed}.csv")])
        assert main(["fit", "friction", str(tmp_path / f"{fixed}.csv"), "--out", str(out)]) == 0
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 0
    inode = (out / "sun-friction.png").stat().st_ino
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 0
    assert (out / "sun-friction.png").stat().st_ino == inode
    assert sorted(read_manifest(out)["sets"]) == ["fit friction ring", "fit friction sun",
                                                   "simulate"]
    assert sorted(os.listdir(out)) == [
        "meta.json", "ring-friction.json", "ring-friction.png", "sun-friction.json",
        "sun-friction.png", "trajectory.nc", MANIFEST]
    assert verify(out) == []


def test_files_in_a_directory_without_a_manifest_are_never_taken(tmp_path, capsys):
    """Without a manifest nothing in a directory is vsj's, whatever its name (an earlier
    vsj that kept none, or a user's own trajectory.nc): the directory is refused and
    every file stays as it was."""
    out = tmp_path / "out"
    out.mkdir()
    for name in ("trajectory.nc", "trajectory.csv", "meta.json", "datasheet.html"):
        (out / name).write_text("written by someone else\n")
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 2
    assert "did not write (datasheet.html, meta.json, trajectory.csv, trajectory.nc" in \
        capsys.readouterr().err
    for name in ("trajectory.nc", "trajectory.csv", "meta.json", "datasheet.html"):
        assert (out / name).read_text() == "written by someone else\n"


def test_synthetic_curves_at_other_positions_are_kept(tmp_path, capsys):
    """A second run of synth stiffness into the same directory adds its positions; a
    position written again replaces its curve only; one position named twice is refused
    before anything is written."""
    out = tmp_path / "curves"
    assert main(["synth", "stiffness", "--q", "1.4", "--q=-0.4", "--out", str(out)]) == 0
    first = (out / "stiffness_q-0.4cm.csv").read_bytes()
    replaced = (out / "stiffness_q+1.4cm.csv").read_bytes()
    assert main(["synth", "stiffness", "--q", "1.4", "--q=-2.2", "--seed", "9",
                 "--out", str(out)]) == 0
    assert sorted(p.name for p in out.glob("*.csv")) == [
        "stiffness_q+1.4cm.csv", "stiffness_q-0.4cm.csv", "stiffness_q-2.2cm.csv"]
    assert (out / "stiffness_q-0.4cm.csv").read_bytes() == first
    assert (out / "stiffness_q+1.4cm.csv").read_bytes() != replaced  # another seed
    assert verify(out) == []
    capsys.readouterr()
    assert main(["synth", "stiffness", "--q", "0.5", "--q", "0.52", "--out", str(out)]) == 2
    assert "two positions give the same curve (stiffness_q+0.5cm.csv" in capsys.readouterr().err
    assert not (out / "stiffness_q+0.5cm.csv").exists()
    # another position with the file name of a curve written before (1.44 cm against
    # 1.4 cm, both stiffness_q+1.4cm.csv): refused, the earlier curve kept
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert main(["synth", "stiffness", "--q", "1.44", "--out", str(out)]) == 2
    assert "holds the curve at q = 1.4 cm" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_what_a_killed_run_left_is_cleared_by_the_next(tmp_path, capsys):
    """Leftovers of a run whose watchdog died with it (as a killed process group would):
    the next writer removes vsj's files, and moves anything else back into the directory,
    never deleting it (and then refuses to replace a directory with a user's file in it)."""
    out = tmp_path / "out"
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 0
    staging = tmp_path / ".out.vsj-0123456789abcdef"
    staging.mkdir()
    (staging / "meta.json").write_text("partial")
    (staging / "notes.txt").write_text("a user's file that ended up here\n")
    in_place = out / ".vsj-fedcba9876543210"
    in_place.mkdir()
    (in_place / "trajectory.nc").write_text("partial")
    (out / ".meta.json.vsj-tmp-1234abcd").write_text("partial")
    (out / ".probe.vsj-tmp-044bc52e").write_text("")  # killed while probing the directory
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 2
    assert "files that vsj did not write (notes.txt" in capsys.readouterr().err
    assert hidden(tmp_path) == [] and hidden(out) == []
    assert (out / "notes.txt").read_text() == "a user's file that ended up here\n"
    (out / "notes.txt").unlink()
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 0
    assert verify(out) == []


def test_clearing_a_staging_directory_deletes_only_vsj_files(tmp_path):
    staging, target = tmp_path / ".t.vsj-0123456789abcdef", tmp_path / "t"
    staging.mkdir()
    target.mkdir()
    (staging / "trajectory.nc").write_text("vsj's")
    (staging / ".meta.json.vsj-tmp-ab12").write_text("vsj's temporary")
    (target / "kept.txt").write_text("linked")
    os.link(target / "kept.txt", staging / "kept.txt")  # carried over: the original stays
    (staging / "own.txt").write_text("a user's")
    (target / "taken.txt").write_text("in the way")
    (staging / "taken.txt").write_text("a user's, name taken")
    from vsj.output.files import _DISPOSABLE

    assert clear_staging(str(staging), str(target), _DISPOSABLE) is False
    assert sorted(os.listdir(staging)) == ["taken.txt"]  # kept rather than deleted
    assert (target / "own.txt").read_text() == "a user's"
    assert (target / "kept.txt").read_text() == "linked"


def test_the_current_directory_is_replaced_in_place(tmp_path, monkeypatch):
    """`--out .` (or a directory a shell stands in) is not swapped away under its users:
    the files are replaced in place, the manifest records them."""
    out = tmp_path / "out"
    scen = scenario(tmp_path)
    assert main(["simulate", str(scen), "--out", str(out), "--csv", "--no-plot"]) == 0
    inode = out.stat().st_ino
    monkeypatch.chdir(out)
    assert main(["simulate", str(scen), "--out", ".", "--no-plot"]) == 0
    assert out.stat().st_ino == inode
    assert sorted(os.listdir(out)) == sorted(["meta.json", MANIFEST, "trajectory.nc"])
    assert verify(out) == []
    assert read_manifest(out)["sets"]["simulate"]["complete"] is True


def test_a_failed_command_leaves_no_new_directory(tmp_path, capsys):
    """A command that fails during its work (here: a stiffness file without its pivot
    position, found by the fit) removes the directories it made for its results."""
    path = tmp_path / "nopivot.csv"
    path.write_text("time [s],deflection [rad],torque [N m]\n" +
                    "".join(f"{i * 0.01},{i / 50},{i / 40}\n" for i in range(50)))
    out = tmp_path / "new" / "out"
    assert main(["fit", "stiffness", str(path), "--out", str(out)]) == 2
    assert "no pivot position" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


def test_verify_command(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot"]) == 0
    capsys.readouterr()
    assert main(["verify", str(out)]) == 0
    assert "1 result set(s), 2 files" in capsys.readouterr().out
    (out / "trajectory.nc").write_bytes(b"changed")
    assert main(["verify", str(out)]) == 1
    assert "trajectory.nc has changed" in capsys.readouterr().err
    assert main(["verify", str(tmp_path / "nothing")]) == 2


def test_verify_names_a_file_meta_json_records_and_the_manifest_dropped(tmp_path, capsys):
    """A data file deleted together with its manifest entry: meta.json, whose own hash
    the manifest keeps, still records it, and verify names it (it passed)."""
    out = tmp_path / "out"
    assert main(["simulate", str(scenario(tmp_path)), "--out", str(out), "--no-plot",
                 "--csv"]) == 0
    (out / "trajectory.csv").unlink()
    manifest = json.loads((out / "vsj-manifest.json").read_text())
    for entry in manifest["sets"].values():
        entry["files"].pop("trajectory.csv", None)
    (out / "vsj-manifest.json").write_text(json.dumps(manifest))
    capsys.readouterr()
    assert main(["verify", str(out)]) == 1
    assert "trajectory.csv: meta.json records it, vsj-manifest.json does not" in \
        capsys.readouterr().err

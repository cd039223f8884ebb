"""Shared fixtures. Tolerances are named where they are used and say where they come from."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pytest

from vsj import params as params_module

try:
    import fcntl
except ImportError:  # not POSIX: each worker reproduces on its own
    fcntl = None

#: A short wrist scenario (0.3 s, arctan friction, one motor) that the command-line,
#: bad-input and result-set tests run and edit.
SHORT_SCENARIO = """name = "short"
description = "a short wrist run"
network = "wrist"
duration = "0.3 s"
[solver]
friction = "arctan"
output_step = "10 ms"
[initial]
q = "-0.4 cm"
[inputs.motor_1]
kind = "sine"
amplitude = "2 rad/s"
frequency = "2 Hz"
"""


@pytest.fixture(scope="session")
def params():
    """The bundled parameter set (report table 4.1 plus estimates)."""
    return params_module.default()


#: What `_once` made in this process: key -> (value, directory).
_MADE: dict = {}


def _once(tmp_path_factory, key: str, make):
    """``make(directory)`` run once per test session for ``key``: ``(value, directory)``.

    ``make`` writes its files into ``directory`` (which it may have to create) and
    returns a JSON value. Under pytest-xdist each worker is a process of its own, so the
    first worker to ask makes it in this session's temporary directory (shared by its
    workers) while holding a lock; the others wait for it and read the same files and
    value. Tests must not change the files.
    """
    if key in _MADE:
        return _MADE[key]
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    if worker is None or fcntl is None:
        out = tmp_path_factory.mktemp(key)
        _MADE[key] = make(out), out
        return _MADE[key]
    shared = tmp_path_factory.getbasetemp().parent  # this session's, above the workers'
    out = shared / key
    value_file = shared / f"{key}.json"
    with open(shared / f"{key}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not value_file.exists():
                value_file.write_text(json.dumps(make(out)))
            _MADE[key] = json.loads(value_file.read_text()), out
            return _MADE[key]
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _reproduce(out) -> int:
    from vsj.cli import main

    return main(["reproduce", "--reduced", "--out", str(out)])


@pytest.fixture(scope="session", autouse=True)
def vsj_cache(tmp_path_factory):
    """vsj's cache of compiled FMU binaries (`vsj.fmu.cache_dir`) in this session's
    temporary directory: each session compiles afresh (nothing from the user's cache), and
    its workers share what one of them compiled."""
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    base = tmp_path_factory.getbasetemp()
    os.environ["VSJ_CACHE"] = str((base.parent if worker else base) / "vsj-cache")
    return Path(os.environ["VSJ_CACHE"])


@pytest.fixture(scope="session")
def reproduction(tmp_path_factory):
    """``vsj reproduce --reduced`` run once per test session: ``(exit code, output dir)``.

    It makes every report figure (about a minute of work), once per session: the tests
    of the figures read what it writes (made once for all workers, `_once`), and
    `reproduced` the figures themselves. Tests must not change them.
    """
    return _once(tmp_path_factory, "reproduction", _reproduce)


@pytest.fixture(scope="session")
def reproduced_figures(reproduction):
    """Every figure of the session's reproduction, read back from the ``.npz`` file it
    wrote (`vsj.reproduce.base.Figure.load`): the tests of the figures' numbers and
    drawings use these rather than computing the figures again."""
    from vsj.reproduce import figures
    from vsj.reproduce.base import Figure

    code, out = reproduction
    assert code == 0
    return {name: Figure.load(out / f"{name}.npz") for name in figures()}


@pytest.fixture(scope="session")
def wrist_fmu_file(tmp_path_factory):
    """A function ``(**options) -> (path, info)``: the wrist FMU that `vsj.fmu.build`
    writes for the bundled parameters with these keyword options, and what it returns.

    Compiling an FMU's binary takes seconds, and test_fmu.py and test_fmu_refusals.py
    import the same default FMU: it is built once per test session for each set of
    options (`_once`), so both files exercise the very file `fmu.build` wrote. Tests
    must not change it (extract a copy to modify).
    """
    from vsj import fmu

    def built(**options):
        key = "fmu-" + hashlib.sha1(json.dumps(options, sort_keys=True).encode()).hexdigest()[:12]

        def make(out):
            out.mkdir(parents=True, exist_ok=True)
            return fmu.build(out / "wrist.fmu", params_module.default(), **options)

        info, out = _once(tmp_path_factory, key, make)
        return out / "wrist.fmu", info

    return built


#: The test files that hold most of a session's work (the identification studies, the
#: FMUs, the reproduction, the streamed runs, the README's commands),
#: costliest first. They are collected first (`pytest_collection_modifyitems`), and
#: ``make test`` keeps that order when it hands files to its workers (xdist's
#: --no-loadscope-reorder; by default xdist starts with the files of most tests, which
#: leaves the long single studies to the end): the session ends on short files, with
#: every worker busy until then.
FIRST = ("test_identify_wrist.py", "test_identify_wrist_calibration.py",
         "test_fmu.py", "test_reproduce_honest.py", "test_streaming.py", "test_readme.py",
         "test_docs.py")


def pytest_collection_modifyitems(config, items):
    """The files of `FIRST` first, in its order; the others after them, as collected."""
    here = os.path.dirname(__file__)
    missing = [name for name in FIRST if not os.path.exists(os.path.join(here, name))]
    if missing:
        raise pytest.UsageError(f"conftest.FIRST names test files that do not exist: "
                                f"{', '.join(missing)}")
    rank = {name: k for k, name in enumerate(FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(FIRST)))  # stable


def override(params, **values):
    """``params`` with ``section__key=value`` overrides (value texts with units)."""
    return params.with_overrides({k.replace("__", "."): v for k, v in values.items()},
                                 origin="test")


# The first call of a compiled kernel in a fresh environment compiles it (seconds);
# hypothesis must not count that as a slow example.
from hypothesis import settings  # noqa: E402

settings.register_profile("vsj", deadline=None)
settings.load_profile("vsj")

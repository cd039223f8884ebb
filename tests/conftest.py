"""Shared fixtures. Tolerances are named where they are used and say where they come from."""

from __future__ import annotations

import os

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


def _reproduce(out) -> int:
    from vsj.cli import main

    return main(["reproduce", "--reduced", "--out", str(out)])


@pytest.fixture(scope="session")
def reproduction(tmp_path_factory):
    """``vsj reproduce --reduced`` run once per test session: ``(exit code, output dir)``.

    It makes every report figure (about a minute of work), and three test files
    read what it writes. Under pytest-xdist each worker is a process of its
    own, so the first worker to ask makes the figures in this session's
    temporary directory (shared by its workers) while holding a lock; the
    others wait for it and read the same files. Tests must not change them.
    """
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    if worker is None or fcntl is None:
        out = tmp_path_factory.mktemp("reproduction")
        return _reproduce(out), out
    shared = tmp_path_factory.getbasetemp().parent  # this session's, above the workers'
    out = shared / "reproduction"
    code_file = shared / "reproduction.code"
    with open(shared / "reproduction.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            if not code_file.exists():
                code_file.write_text(str(_reproduce(out)))
            return int(code_file.read_text()), out
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def override(params, **values):
    """``params`` with ``section__key=value`` overrides (value texts with units)."""
    return params.with_overrides({k.replace("__", "."): v for k, v in values.items()},
                                 origin="test")


# The first call of a compiled kernel in a fresh environment compiles it (seconds);
# hypothesis must not count that as a slow example.
from hypothesis import settings  # noqa: E402

settings.register_profile("vsj", deadline=None)
settings.load_profile("vsj")

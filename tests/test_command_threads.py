"""The vsj command sends OpenBLAS's idle threads to sleep at once, set before NumPy loads
(`vsj._the_command`): vsj runs its work side by side by runs, and OpenBLAS's threads
would otherwise spin beside them. A program that imports vsj keeps NumPy as it is, and a
value the environment sets wins."""

import os
import subprocess
import sys

import vsj

SETTING = "OPENBLAS_THREAD_TIMEOUT"

#: Imports vsj as a process whose first argument is ``argv0``, then prints the setting.
CODE = ("import sys; sys.argv[0] = {argv0!r}; import vsj, numpy, os; "
        f"print(os.environ.get({SETTING!r}))")


def setting(argv0: str, **env) -> str:
    clean = {k: v for k, v in os.environ.items() if k != SETTING}
    done = subprocess.run([sys.executable, "-c", CODE.format(argv0=argv0)],
                          env={**clean, **env}, capture_output=True, text=True, check=True)
    return done.stdout.strip()


def test_the_command_sends_idle_blas_threads_to_sleep():
    assert setting("/somewhere/bin/vsj") == "4"  # OpenBLAS's shortest wait
    assert setting("/somewhere/bin/vsj", **{SETTING: "20"}) == "20"
    assert setting("analysis.py") == "None"


def test_python_dash_m_vsj_is_the_command(monkeypatch):
    monkeypatch.setattr(sys, "argv", ["-m"])  # as while ``python -m`` finds the package
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-X", "importtime", "-m", "vsj",
                                           "simulate", "fig-4.15"])
    assert vsj._the_command()
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-m", "vsj_tools", "vsj"])
    assert not vsj._the_command()

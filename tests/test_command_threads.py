"""The vsj command caps OpenBLAS at one thread before NumPy loads (`vsj._the_command`):
vsj runs its work side by side by runs, and OpenBLAS's threads would only spin beside
them. A program that imports vsj keeps NumPy as it is, and a value the environment sets
wins."""

import os
import subprocess
import sys

import vsj

#: Imports vsj as a process whose first argument is ``argv0``, then prints the setting
#: and the threads of the process (Linux lists them in /proc/self/task).
CODE = ("import sys; sys.argv[0] = {argv0!r}; import vsj, numpy, os; "
        "print(os.environ.get('OPENBLAS_NUM_THREADS'), len(os.listdir('/proc/self/task')))")


def started(argv0: str, **env) -> tuple[str, int]:
    clean = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    done = subprocess.run([sys.executable, "-c", CODE.format(argv0=argv0)],
                          env={**clean, **env}, capture_output=True, text=True, check=True)
    setting, threads = done.stdout.split()
    return setting, int(threads)


def test_the_command_runs_numpy_on_one_thread():
    assert started("/somewhere/bin/vsj") == ("1", 1)
    assert started("/somewhere/bin/vsj", OPENBLAS_NUM_THREADS="2")[0] == "2"
    assert started("analysis.py")[0] == "None"


def test_python_dash_m_vsj_is_the_command(monkeypatch):
    monkeypatch.setattr(sys, "argv", ["-m"])  # as while ``python -m`` finds the package
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-X", "importtime", "-m", "vsj",
                                           "simulate", "fig-4.15"])
    assert vsj._the_command()
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-m", "vsj_tools", "vsj"])
    assert not vsj._the_command()

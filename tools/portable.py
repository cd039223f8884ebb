"""`make portable`: the test suite under other floating-point configurations.

A tolerance tuned to one CPU fails on the next machine. This builds the C engine
once per configuration (another compiler, optimisation level, fused multiply-add,
native instructions) or runs it with another BLAS kernel, each in a copy of the
package under ``build/portable/<name>``, and runs the whole suite against that copy
(``PYTHONPATH`` puts it ahead of the editable install). Every configuration must
pass. Run from the repository root with the project's environment::

    .venv/bin/python tools/portable.py [NAME ...]

Configurations (``NAME``): ``O0`` (-O0, no contraction), ``fma`` (-O2 with fused
multiply-add contracted wherever the compiler likes), ``native`` (-O3 -march=native),
``clang`` (CC=clang, its default flags) and ``blas`` (OpenBLAS's Prescott kernel on one
thread, the oldest x86-64 kernel; the engine built as usual).
"""

from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BUILD = ROOT / "build" / "portable"


def configurations() -> dict[str, dict[str, str]]:
    """Environment of each configuration: compiler, flags, BLAS kernel."""
    x86 = platform.machine().lower() in ("x86_64", "amd64")
    fma = "-O2 -mfma -ffp-contract=fast" if x86 else "-O2 -ffp-contract=fast"
    return {
        "O0": {"CFLAGS": "-O0 -ffp-contract=off"},
        "fma": {"CFLAGS": fma},
        "native": {"CFLAGS": "-O3 -march=native"},
        "clang": {"CC": "clang"},
        "blas": {"OPENBLAS_CORETYPE": "Prescott", "OPENBLAS_NUM_THREADS": "1"},
    }


def build(name: str, env: dict[str, str]) -> Path:
    """A copy of the package whose engine is compiled with ``env``; returns its src."""
    where = BUILD / name
    shutil.rmtree(where, ignore_errors=True)
    src = where / "src"
    shutil.copytree(ROOT / "src", src,
                    ignore=shutil.ignore_patterns("*.so", "__pycache__", "*.egg-info"))
    for name_ in ("setup.py", "pyproject.toml", "README.md"):
        shutil.copy(ROOT / name_, where / name_)
    build_env = {**os.environ, **{k: v for k, v in env.items() if k in ("CC", "CFLAGS")}}
    if "CC" in env and shutil.which(env["CC"]) is None:
        raise SystemExit(f"portable {name}: compiler {env['CC']!r} not found "
                         f"(Debian: apt-get install {env['CC']})")
    log = where / "build.log"
    with open(log, "w") as handle:
        done = subprocess.run([sys.executable, "setup.py", "build_ext", "--inplace", "--force"],
                              cwd=where, env=build_env, stdout=handle, stderr=subprocess.STDOUT)
    if done.returncode:
        raise SystemExit(f"portable {name}: the engine did not build; see {log}")
    return src


def run(name: str, env: dict[str, str]) -> tuple[bool, float]:
    """Build configuration ``name`` and run the suite against it."""
    started = time.perf_counter()
    src = build(name, env)
    test_env = {**os.environ, **env, "PYTHONPATH": str(src)}
    if "CFLAGS" in env:  # the tests' own C builds (the C example) take them too
        test_env["VSJ_TEST_CFLAGS"] = env["CFLAGS"]
    check = subprocess.run([sys.executable, "-c", "import vsj._core as c; print(c.__file__)"],
                           env=test_env, capture_output=True, text=True, cwd=ROOT)
    if str(src) not in check.stdout:
        raise SystemExit(f"portable {name}: the suite would not load the copy ({check.stdout}"
                         f"{check.stderr})")
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "auto", "--dist",
                           "loadfile", "-p", "no:cacheprovider"], cwd=ROOT, env=test_env)
    return done.returncode == 0, time.perf_counter() - started


def main(names: list[str]) -> int:
    every = configurations()
    unknown = sorted(set(names) - set(every))
    if unknown:
        print(f"portable: unknown configuration(s) {', '.join(unknown)}; choose from "
              f"{', '.join(every)}", file=sys.stderr)
        return 2
    results = {}
    for name in names or list(every):
        env = every[name]
        print(f"== portable {name}: {' '.join(f'{k}={v!r}' for k, v in env.items())}",
              flush=True)
        results[name] = run(name, env)
    print("\nportable configurations:")
    for name, (ok, seconds) in results.items():
        print(f"  {name:8s} {'passed' if ok else 'FAILED'} ({seconds:.0f} s)")
    return 0 if all(ok for ok, _ in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

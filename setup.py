"""The compiled part of vsj: its engine, a C99 library (src/vsj/engine/c, public
header vsj.h) and the Python binding around it, built by the system C compiler
when the package is installed. Everything else is in pyproject.toml."""

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ENGINE = Path("src/vsj/engine")
SOURCES = ["src/vsj/_core.c"] + sorted(str(p) for p in (ENGINE / "c").glob("*.c"))
#: Warnings on for gcc and clang (the engine and its binding build without any);
#: VSJ_WERROR=1 makes them errors. tests/test_c_source.py reads this line and builds the
#: binding with it, warnings as errors.
WARNINGS = ["-Wall", "-Wextra"] + (["-Werror"] if os.environ.get("VSJ_WERROR") == "1" else [])
#: ISO C99, the language of the engine: gcc then fuses no multiply and add unless told to
#: (-ffp-contract=fast), so that a build for a CPU with fused multiply-add (-march=native,
#: or any arm64) rounds as the FMU's binary and the C example do, and the time-stepper's
#: energy ledger books each step to round-off there too (in GNU C, gcc fuses them across
#: statements, and the step's sums and the ledger's then round apart).
STANDARD = ["-std=c99"]
#: The engine reads no errno after a math function, so none need be set: gcc and clang
#: then compile sqrt to the processor's instruction alone, not with a branch to the
#: library for a negative argument. The same bits, and a shorter step.
MATH = ["-fno-math-errno"]


class BuildOnEveryCore(build_ext):
    """Compiles the engine's source files in parallel, one per core (setuptools
    itself runs only separate extensions in parallel), the largest first: a large file
    started last would leave the other cores idle while it compiles."""

    def build_extension(self, ext):
        if self.compiler.compiler_type == "unix":
            ext.extra_compile_args = STANDARD + MATH + WARNINGS + list(ext.extra_compile_args or [])
        compile_all = self.compiler.compile

        def compile_each(sources, *args, **kwargs):
            largest_first = sorted(sources, key=lambda source: -os.path.getsize(source))
            with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
                parts = dict(zip(largest_first, pool.map(
                    lambda source: compile_all([source], *args, **kwargs), largest_first)))
            return [obj for source in sources for obj in parts[source]]  # the link's order

        self.compiler.compile = compile_each
        try:
            super().build_extension(ext)
        finally:
            self.compiler.compile = compile_all


setup(ext_modules=[Extension("vsj._core", sources=SOURCES,
                             depends=[str(p) for p in (ENGINE / "c").glob("*.h")])],
      cmdclass={"build_ext": BuildOnEveryCore})

"""The compiled part of vsj: its engine, a C99 library (src/vsj/engine/c, public
header vsj.h) and the Python binding around it, built by the system C compiler
when the package is installed. Everything else is in pyproject.toml."""

from pathlib import Path

from setuptools import Extension, setup

ENGINE = Path("src/vsj/engine")
SOURCES = [str(ENGINE / "_core.c")] + sorted(str(p) for p in (ENGINE / "c").glob("*.c"))

setup(ext_modules=[Extension("vsj.engine._core", sources=SOURCES,
                             depends=[str(p) for p in (ENGINE / "c").glob("*.h")])])

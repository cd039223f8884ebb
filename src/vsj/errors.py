"""Exceptions that the command line maps to exit codes, and the reading of user files.

`InputError` (exit code 2) is raised for anything a user supplied that vsj
cannot accept: a parameter file, a scenario, a measurement file, a command-line
value. Its message names the file, the key or line, the value and what is
allowed. `SimulationError` (exit code 1) is raised when a simulation or a fit
fails; it carries the time and state where that happened. `read_text` reads a
user's text file and says in an `InputError` why it cannot.

Every user file vsj reads goes through `read_bytes`, which takes only a regular
file and only up to a size given by the kind of file: a FIFO would make the read
wait for a writer that may never come, and a device such as ``/dev/zero``, or a
file far larger than its kind can be, would be read until memory runs out.
Both are refused before anything is read.
"""

from __future__ import annotations

import math
import numbers
import os
import stat
from pathlib import Path


class InputError(ValueError):
    """Bad input: the message says what is wrong and where."""


class SimulationError(RuntimeError):
    """A simulation or fit failed; never reported as success."""


def is_number(value) -> bool:
    """Whether ``value`` is a real number as an argument takes one: Python's or NumPy's
    (np.float32, np.int64), not a bool nor a string such as "1 ms"."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


#: Largest scenario, sweep, experiment, fit set-up, covariance or linear model file read
#: [bytes]. Most are a few kB; the largest hold lists of numbers (a scenario's table
#: input, a sweep's list of values, a model's matrices): 64 MiB is a table of a million
#: samples written to full precision.
TEXT_BYTES = 64 << 20

_KINDS = {stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFCHR: "a character device",
          stat.S_IFBLK: "a block device", stat.S_IFDIR: "a directory",
          stat.S_IFSOCK: "a socket"}


def byte_size(count: int) -> str:
    """``count`` bytes as text for messages (``"8.1 KiB"``, ``"1.0 MiB"``, ...)."""
    for unit, size in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if count >= size:
            return f"{count / size:.1f} {unit}"
    return f"{count} bytes"


def read_bytes(path: str | Path, what: str, limit: int) -> bytes:
    """The bytes of the regular file ``path``, which may hold at most ``limit`` bytes.

    ``what`` names the kind of file in messages ("parameter file"). A path that
    cannot be opened, is not a regular file (a FIFO, a device, a directory) or
    holds more than ``limit`` bytes raises `InputError` naming the path; nothing is
    read from a file that is refused.
    """
    try:
        # O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
                     | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_BINARY", 0))
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what} ({exc.strerror or exc})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            kind = _KINDS.get(stat.S_IFMT(info.st_mode), "not a regular file")
            raise InputError(f"{path}: cannot read {what}: {kind}, not a regular file")
        too_large = (f"{path}: cannot read {what}: {{}}; a {what} holds at most "
                     f"{byte_size(limit)} ({limit} bytes)")
        if info.st_size > limit:
            raise InputError(too_large.format(byte_size(info.st_size)))
        with os.fdopen(fd, "rb", closefd=False) as handle:
            data = handle.read(limit + 1)  # a file that grows, or reports no size (/proc)
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what} ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if len(data) > limit:
        raise InputError(too_large.format(f"more than {byte_size(limit)}"))
    return data


def read_text(path: str | Path, what: str, *, limit: int = TEXT_BYTES) -> str:
    """The text of the UTF-8 file ``path`` (a byte-order mark is dropped).

    ``what`` names the kind of file in messages ("parameter file"); ``limit`` is
    the most bytes such a file may hold (`read_bytes`). A file that cannot be
    read, is not a regular file, is too large, or is not UTF-8 raises `InputError`
    with the path and, for bad bytes, their line and byte offset.
    """
    data = read_bytes(path, what, limit)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{path}, line {line}: byte offset {exc.start} "
                         f"({data[exc.start]:#04x}) is not UTF-8; a {what} is UTF-8 text") \
            from None


def finite_number(name: str, value, *, low: float | None = None, strict: bool = False) -> float:
    """``value`` as a finite float, above ``low`` (``strict``) or at least it; else
    `InputError` naming ``name`` and what is allowed."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or (low is not None and (v <= low if strict else v < low)):
        bound = "" if low is None else f" {'>' if strict else '>='} {low:g}"
        raise InputError(f"{name} must be a finite number{bound}, got {value!r}")
    return v

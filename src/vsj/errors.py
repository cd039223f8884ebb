"""Exceptions that the command line maps to exit codes, and the reading of user files.

`InputError` (exit code 2) is raised for anything a user supplied that vsj
cannot accept: a parameter file, a scenario, a measurement file, a command-line
value. Its message names the file, the key or line, the value and what is
allowed. `SimulationError` (exit code 1) is raised when a simulation or a fit
fails; it carries the time and state where that happened. `read_text` reads a
user's text file and says in an `InputError` why it cannot.
"""

from __future__ import annotations

from pathlib import Path


class InputError(ValueError):
    """Bad input: the message says what is wrong and where."""


class SimulationError(RuntimeError):
    """A simulation or fit failed; never reported as success."""


def read_text(path: str | Path, what: str) -> str:
    """The text of the UTF-8 file ``path`` (a byte-order mark is dropped).

    ``what`` names the kind of file in messages ("parameter file"). A file
    that cannot be read, or is not UTF-8, raises `InputError` with the path
    and, for bad bytes, their line and byte offset.
    """
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise InputError(f"{path}: cannot read {what} ({exc.strerror or exc})") from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise InputError(f"{path}, line {line}: byte offset {exc.start} "
                         f"({data[exc.start]:#04x}) is not UTF-8; a {what} is UTF-8 text") \
            from None

"""Exceptions that the command line maps to exit codes.

`InputError` (exit code 2) is raised for anything a user supplied that vsj
cannot accept: a parameter file, a scenario, a measurement file, a command-line
value. Its message names the file, the key or line, the value and what is
allowed. `SimulationError` (exit code 1) is raised when a simulation or a fit
fails; it carries the time and state where that happened.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad input: the message says what is wrong and where."""


class SimulationError(RuntimeError):
    """A simulation or fit failed; never reported as success."""

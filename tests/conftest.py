"""Shared fixtures. Tolerances are named where they are used and say where they come from."""

from __future__ import annotations

import pytest

from vsj import params as params_module


@pytest.fixture(scope="session")
def params():
    """The bundled parameter set (report table 4.1 plus estimates)."""
    return params_module.default()


def override(params, **values):
    """``params`` with ``section__key=value`` overrides (value texts with units)."""
    return params.with_overrides({k.replace("__", "."): v for k, v in values.items()},
                                 origin="test")


# The first call of a compiled kernel in a fresh environment compiles it (seconds);
# hypothesis must not count that as a slow example.
from hypothesis import settings  # noqa: E402

settings.register_profile("vsj", deadline=None)
settings.load_profile("vsj")

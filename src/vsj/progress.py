"""Progress bars for long work, on standard error (tqdm; silent when not a terminal)."""

from __future__ import annotations

import sys


def progress(iterable, *, desc: str, unit: str = "it", total: int | None = None):
    """``iterable`` wrapped in a progress bar on standard error, labelled ``desc`` and
    counted in ``unit``; silent when standard error is not a terminal."""
    from tqdm import tqdm  # lazy: tqdm, only once a bar is made, so vsj.progress stays free

    return tqdm(iterable, desc=desc, unit=unit, total=total, file=sys.stderr,
                disable=not sys.stderr.isatty(), leave=False)

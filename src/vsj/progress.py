"""Progress bars for long work, on standard error (tqdm; silent when not a terminal)."""

from __future__ import annotations

import sys


class Silent:
    """What `progress` gives where no bar is shown: it iterates over the wrapped iterable
    and takes a bar's `update` and `close`, doing nothing else."""

    def __init__(self, iterable):
        self.iterable = iterable

    def __iter__(self):
        return iter(self.iterable)

    def update(self, n: int = 1) -> None:
        """Count ``n`` more units (nothing to show)."""

    def close(self) -> None:
        """End the bar (nothing to clear)."""


def progress(iterable, *, desc: str, unit: str = "it", total: int | None = None):
    """``iterable`` wrapped in a progress bar on standard error, labelled ``desc`` and
    counted in ``unit``; silent when standard error is not a terminal (`Silent`: then
    tqdm is not even imported, a measurable part of a short command's start)."""
    if not sys.stderr.isatty():
        return Silent(iterable)
    # lazy: tqdm's import is a measurable part of a short command's start; only a bar needs it
    from tqdm import tqdm

    return tqdm(iterable, desc=desc, unit=unit, total=total, file=sys.stderr, leave=False)

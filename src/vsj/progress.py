"""Progress bars for long work, on standard error (tqdm; silent when not a terminal)."""

from __future__ import annotations

import sys


def progress(iterable, *, desc: str, unit: str = "it", total: int | None = None):
    from tqdm import tqdm  # lazy: tqdm, only once a bar is made, so vsj.progress stays free

    return tqdm(iterable, desc=desc, unit=unit, total=total, file=sys.stderr,
                disable=not sys.stderr.isatty(), leave=False)

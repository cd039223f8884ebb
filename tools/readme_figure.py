"""Run README.md's Python snippet in a directory (``make figures``), so that the figure
the README shows is the one its snippet makes, drawn by today's code.

    python tools/readme_figure.py build/figures/readme
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def main(argv=None) -> int:
    """Execute every ``python`` block of the README, in order, in the directory given."""
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1:
        print(__doc__.strip().splitlines()[-1].strip())
        return 2
    out = Path(argv[0])
    out.mkdir(parents=True, exist_ok=True)
    blocks = re.findall(r"^```python\n(.*?)^```", README.read_text(), re.S | re.M)
    if not blocks:
        print(f"{README}: no Python block")
        return 1
    os.environ.setdefault("MPLBACKEND", "Agg")
    os.chdir(out)
    namespace = {"__name__": "__readme__"}
    for block in blocks:
        exec(compile(block, str(README), "exec"), namespace)
    print(f"ran {len(blocks)} Python block(s) of {README.name} in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""The screenshot of ``vsj explore`` that the README and the docs show.

Starts ``vsj explore`` and opens it in Debian's headless Chromium (tests/explore_browser.py,
what the browser test drives), puts the wall of the environment in the circle's way so
that every view has something to show, and saves the page with its first tab of views
(tracking and stiffness) as the PNG named, and with its last (energy and impact) beside it
as ``<name>-energy.png``:

    .venv/bin/python tools/explorer_screenshot.py build/figures/explorer.png

(``make figures`` runs it.)
"""

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from explore_browser import Explorer, available  # noqa: E402


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    why = available()
    if why is not None:
        print(f"explorer_screenshot: {why}", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as out, Explorer(Path(out)) as page:
        runs = page.runs()
        page.choose("environment", "wall")
        page.wait_runs(runs + 1)
        errors = page.console_errors()
        if errors:
            print(f"explorer_screenshot: the page logged errors: {errors}", file=sys.stderr)
            return 1
        first = Path(argv[0])
        page.screenshot(first)
        page.show_tab(3)
        last = first.with_name(f"{first.stem}-energy{first.suffix}")
        page.screenshot(last)
    print(f"wrote {first} and {last}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

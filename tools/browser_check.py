"""Open the built documentation in headless Chromium (``make docs-browser``).

    python tools/browser_check.py docs/_build/html [--screenshots DIR]

Serves the site on the loopback interface and drives Debian's Chromium through its
chromedriver with Selenium (both from ``apt-get install chromium chromium-driver``;
nothing is downloaded at run time: Selenium is given both paths, so its driver manager
never runs). On each page of `PAGES` the browser's console must hold no error; the page
of an equation must show it typeset by the MathJax shipped with the site; the search
page must find "stiction". With ``--screenshots`` it saves the home page and an executed
example as ``docs-home.png`` and ``docs-example.png``. Exits 1 naming each failure.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import os
import sys
import threading
from pathlib import Path

CHROMIUM = os.environ.get("VSJ_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("VSJ_CHROMEDRIVER", "/usr/bin/chromedriver")
#: Pages opened, each with what it must show (a CSS selector), and whether it is
#: a page with equations (MathJax must have typeset them).
PAGES = [
    ("index.html", "h1", False),
    ("getting-started/examples/2_first_plot.html", "img.sphx-glr-single-img", False),
    ("model-notes/planetary.html", "mjx-container", True),
    ("user-guide/friction.html", "mjx-container", True),
    ("reference/generated/vsj.simulate.driver.html", "dl.py.function", False),
    ("reference/cli.html", "#vsj-fit-wrist", False),
]
#: The search and what it must find.
QUERY = "stiction"
#: Seconds to wait for a page's scripts (search index, MathJax) to finish.
WAIT = 30


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):  # the check prints its own findings
        pass


def serve(site: Path) -> tuple[http.server.ThreadingHTTPServer, str]:
    """An HTTP server of ``site`` on 127.0.0.1 (a free port), running in a thread."""
    handler = functools.partial(_Quiet, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}/"


def browser():
    """Headless Chromium through Debian's chromedriver, with the console log kept."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--window-size=1280,1000"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(options=options, service=Service(executable_path=CHROMEDRIVER))


def console_errors(driver) -> list[str]:
    """The console's errors since the last call."""
    return [entry["message"] for entry in driver.get_log("browser")
            if entry["level"] == "SEVERE"]


def check(site: Path, screenshots: Path | None) -> list[str]:
    """Every finding, as a line naming the page."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.support.ui import WebDriverWait

    problems = []
    server, base = serve(site)
    driver = browser()
    try:
        wait = WebDriverWait(driver, WAIT)
        for page, selector, math in PAGES:
            driver.get(base + page)
            try:
                wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, selector))
            except Exception:  # noqa: BLE001 - a time-out is the finding
                problems.append(f"{page}: nothing matches {selector!r} after {WAIT} s"
                                + (" (MathJax did not typeset the equations)" if math else ""))
            problems += [f"{page}: console error: {e}" for e in console_errors(driver)]
            if screenshots is not None and page == "index.html":
                driver.save_screenshot(str(screenshots / "docs-home.png"))
            if screenshots is not None and page.startswith("getting-started/examples/"):
                figures = driver.find_elements(By.CSS_SELECTOR, selector)
                if figures:  # the executed example's figure, whole, once it has loaded
                    wait.until(lambda d: d.execute_script(
                        "return arguments[0].complete && arguments[0].naturalHeight > 0",
                        figures[0]))
                    driver.execute_script("arguments[0].scrollIntoView({block: 'center', behavior: 'instant'})",
                                          figures[0])
                driver.save_screenshot(str(screenshots / "docs-example.png"))
        driver.get(base + f"search.html?q={QUERY}")
        try:
            wait.until(lambda d: d.find_elements(By.CSS_SELECTOR, "ul.search li"))
            hits = [li.text.splitlines()[0] for li in
                    driver.find_elements(By.CSS_SELECTOR, "ul.search li")]
            print(f"search for {QUERY!r}: {len(hits)} pages, first: {'; '.join(hits[:3])}")
        except Exception:  # noqa: BLE001 - as above
            problems.append(f"search.html: no result for {QUERY!r} after {WAIT} s")
        problems += [f"search.html: console error: {e}" for e in console_errors(driver)]
    finally:
        driver.quit()
        server.shutdown()
    return problems


def main(argv=None) -> int:
    """Run the check; 0 if the site passes, 1 otherwise."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("site", type=Path, help="the built HTML (docs/_build/html)")
    parser.add_argument("--screenshots", type=Path, metavar="DIR",
                        help="save docs-home.png and docs-example.png here")
    args = parser.parse_args(argv)
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not Path(p).exists()]
    if missing:
        print(f"no {' or '.join(missing)}: apt-get install chromium chromium-driver")
        return 1
    if args.screenshots is not None:
        args.screenshots.mkdir(parents=True, exist_ok=True)
    problems = check(args.site.resolve(), args.screenshots)
    for problem in problems:
        print(problem)
    print(f"{len(PAGES) + 1} pages opened in headless Chromium: {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())

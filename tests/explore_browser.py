"""Driving ``vsj explore`` in a real browser: Debian's headless Chromium through its
chromedriver and Selenium, nothing downloaded. Shared by tests/browser_explorer.py (run by
make explore-browser) and benchmarks/explore.py.

`Explorer` starts ``vsj explore`` as the user would (a process of its own, on a free
port) and a headless Chromium on it; its methods move the page's sliders with the mouse,
type into its fields and read what the page plots (the Bokeh document's data sources).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

#: Debian's Chromium and its driver (packages chromium, chromium-driver).
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
#: How long [s] to wait for the server to listen and for the page to finish a run: a
#: run takes tens of milliseconds, starting Python with Bokeh a few seconds on a busy
#: machine; these are limits for a hung page, not measurements.
START_TIMEOUT = 60.0
RUN_TIMEOUT = 30.0


def available() -> str | None:
    """Why the browser cannot run here (None if it can)."""
    for path in (CHROMIUM, CHROMEDRIVER):
        if not os.access(path, os.X_OK):
            return f"{path} is not installed (Debian packages chromium, chromium-driver)"
    try:
        import bokeh  # noqa: F401
        import selenium  # noqa: F401
    except ImportError as exc:
        return f"{exc.name} is not installed (pip install 'vsj[explore,test]')"
    return None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Explorer:
    """``vsj explore`` served on a free port and opened in headless Chromium."""

    def __init__(self, out: Path, *, width: int = 1250, height: int = 1000):
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service

        self.out = Path(out)
        self.port = _free_port()
        vsj = Path(sys.executable).with_name("vsj")
        command = [str(vsj)] if vsj.exists() else [sys.executable, "-m", "vsj"]
        self.server = subprocess.Popen(
            command + ["explore", "--no-browser", "--port", str(self.port),
                       "--out", str(self.out)],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.driver = None
        try:
            self._wait_listening()
            options = webdriver.ChromeOptions()
            options.binary_location = CHROMIUM
            for flag in ("--headless=new", "--no-sandbox", "--disable-gpu",
                         "--disable-dev-shm-usage", f"--window-size={width},{height}"):
                options.add_argument(flag)
            options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
            self.driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
            self.driver.get(f"http://localhost:{self.port}/")
            self.wait_runs(1)
        except BaseException:
            self.close()
            raise

    def _wait_listening(self) -> None:
        deadline = time.monotonic() + START_TIMEOUT
        while time.monotonic() < deadline:
            if self.server.poll() is not None:
                raise RuntimeError(f"vsj explore exited: {self.server.stdout.read()}")
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    return
            time.sleep(0.05)
        raise RuntimeError(f"vsj explore did not listen on port {self.port}")

    def close(self) -> None:
        """Quit the browser and stop the server (the process this object started)."""
        if self.driver is not None:
            self.driver.quit()
            self.driver = None
        if self.server.poll() is None:
            self.server.terminate()
            try:
                self.server.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.server.kill()
                self.server.wait()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # -- reading the page ---------------------------------------------------------------

    def script(self, code: str, *args):
        return self.driver.execute_script(code, *args)

    def runs(self) -> int:
        """The number of the last run the page has drawn (``window.vsjDrawn``; the
        server numbers its runs from 1)."""
        return int(self.script("return window.vsjDrawn || 0;"))

    def wait_runs(self, count: int) -> None:
        """Wait until the page has drawn run ``count`` (told by the page itself, so that
        no polling competes with it for the browser's thread)."""
        from selenium.common.exceptions import TimeoutException

        self.driver.set_script_timeout(RUN_TIMEOUT)
        try:
            self.driver.execute_async_script("""
                const done = arguments[arguments.length - 1], count = arguments[0];
                if ((window.vsjDrawn || 0) >= count) { done(); return; }
                window.vsjOnDrawn = () => {
                    if (window.vsjDrawn >= count) { window.vsjOnDrawn = null; done(); }
                };""", count)
        except TimeoutException:
            raise TimeoutError(f"the page drew {self.runs()} runs, expected {count}") from None

    def source(self, name: str) -> dict:
        """The columns of the page's data source ``name`` (what a view plots)."""
        return self.script("""
            const doc = Bokeh.documents[0];
            const data = doc.get_model_by_name(arguments[0]).data;
            const out = {};
            for (const [k, v] of Object.entries(data)) out[k] = Array.from(v);
            return out;""", name)

    def text(self, name: str) -> str:
        """The text of the page's Div ``name``."""
        return self.script("return Bokeh.documents[0].get_model_by_name(arguments[0]).text;",
                           name)

    def note(self, key: str) -> str:
        """The line ``key`` of the numbers the page writes over its views."""
        return self.source("notes")[key][0]

    def console_errors(self) -> list[str]:
        """The browser console's errors since the last call."""
        return [e["message"] for e in self.driver.get_log("browser")
                if e["level"] in ("SEVERE", "ERROR")]

    def latencies(self) -> list[float]:
        """Release-to-redraw times [ms] the page measured, to the new curves painted
        (``window.vsjLatencies``)."""
        return [float(x) for x in self.script("return window.vsjLatencies || [];")]

    def number_latencies(self) -> list[float]:
        """Release-to-redraw times [ms] to the numbers over the curves painted too, a frame
        later (``window.vsjNumberLatencies``)."""
        return [float(x) for x in self.script("return window.vsjNumberLatencies || [];")]

    # -- acting on it -------------------------------------------------------------------

    def _element(self, name: str):
        """The DOM element of the Bokeh model ``name`` (inside its view's shadow root)."""
        return self.script("""
            const doc = Bokeh.documents[0];
            const model = doc.get_model_by_name(arguments[0]);
            const view = Bokeh.index[doc.roots()[0].id].owner.get_one(model);
            return view.el;""", name)

    def drag_slider(self, key: str, to: str) -> None:
        """Drag the slider of control ``key`` with the mouse to its ``start`` or ``end`` and
        release it there; waits for the run it causes to be drawn."""
        from selenium.webdriver.common.action_chains import ActionChains

        before = self.runs()
        host = self._element(f"slider:{key}")
        self.script("arguments[0].scrollIntoView({block: 'center'});", host)
        handle, track = self.script("""
            const root = arguments[0].shadowRoot;
            return [root.querySelector('.noUi-handle'), root.querySelector('.noUi-base')];""",
                                    host)
        width = track.size["width"]
        # past the track's end by a few pixels: the slider stops at its start or end
        beyond = (width / 2 + 4) * (-1 if to == "start" else 1)
        ActionChains(self.driver).click_and_hold(handle) \
            .move_to_element_with_offset(track, int(beyond / 2), 0) \
            .move_to_element_with_offset(track, int(beyond), 0).release().perform()
        self.wait_runs(before + 1)

    def type_into(self, key: str, text: str) -> None:
        """Type ``text`` into the field of control ``key`` and press Enter."""
        from selenium.webdriver.common.keys import Keys

        host = self._element(f"field:{key}")
        box = self.script("return arguments[0].shadowRoot.querySelector('input');", host)
        # emptied as a user's select-all would (no change event), then typed
        self.script("arguments[0].value = '';", box)
        box.send_keys(text + Keys.ENTER)

    def show_tab(self, index: int) -> None:
        """Click the header of the tab of views ``index`` (from 0) and wait until it shows
        the latest run's data."""
        host = self._element("views")
        headers = self.script("return arguments[0].shadowRoot.querySelectorAll('.bk-tab');",
                              host)
        headers[index].click()
        want = f"{self.runs()}:{index}"
        deadline = time.monotonic() + RUN_TIMEOUT
        while self.script("return window.vsjShown;") != want:
            if time.monotonic() > deadline:
                raise TimeoutError(f"tab {index}: {self.script('return window.vsjShown;')}")
            time.sleep(0.01)

    def choose(self, key: str, option: str) -> None:
        """Choose ``option`` in the drop-down of ``key`` (as a user picks it)."""
        from selenium.webdriver.support.select import Select

        host = self._element(f"select:{key}")
        Select(self.script("return arguments[0].shadowRoot.querySelector('select');", host)) \
            .select_by_value(option)

    def upload(self, name: str, path: Path) -> None:
        """Choose the file ``path`` in the file input ``name`` (as a user picks it)."""
        host = self._element(name)
        box = self.script("return arguments[0].shadowRoot.querySelector('input');", host)
        box.send_keys(str(Path(path).resolve()))

    def click(self, name: str) -> None:
        """Click the button ``name``."""
        host = self._element(name)
        button = self.script("return arguments[0].shadowRoot.querySelector('button');", host)
        button.click()

    def field(self, key: str) -> str:
        """The text in the field of control ``key``."""
        return self.script("return Bokeh.documents[0].get_model_by_name(arguments[0]).value;",
                           f"field:{key}")

    def wait_for(self, condition, what: str, timeout: float = RUN_TIMEOUT) -> None:
        """Wait until ``condition()`` holds; `TimeoutError` naming ``what`` if it does not."""
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise TimeoutError(f"waited for: {what}")
            time.sleep(0.01)

    def wait_text(self, name: str, predicate, timeout: float = RUN_TIMEOUT) -> str:
        """Wait until the Div ``name``'s text satisfies ``predicate``; returns it."""
        deadline = time.monotonic() + timeout
        while True:
            text = self.text(name)
            if predicate(text):
                return text
            if time.monotonic() > deadline:
                raise TimeoutError(f"{name}: {text!r}")
            time.sleep(0.01)

    def screenshot(self, path: Path) -> None:
        """Save the whole page as a PNG."""
        import base64

        Path(path).parent.mkdir(parents=True, exist_ok=True)
        size = self.driver.execute_cdp_cmd("Page.getLayoutMetrics", {})["cssContentSize"]
        shot = self.driver.execute_cdp_cmd("Page.captureScreenshot", {
            "format": "png", "captureBeyondViewport": True,
            "clip": {"x": 0, "y": 0, "width": size["width"], "height": size["height"],
                     "scale": 1}})
        Path(path).write_bytes(base64.b64decode(shot["data"]))


__all__ = ["CHROMEDRIVER", "CHROMIUM", "Explorer", "available"]
